"""Read a flight back from a ``.tlog``: the vehicle's track and the setpoints the ground station sent.

A tlog is the one record every vehicle leaves the same way (bundled sim, ArduCopter, PX4), so the
plot, the end-to-end tests and the latency benchmark all read flights through this module.
Messages from the ground station are told apart by their source system id (255 unless changed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from gcs_voice.errors import GcsVoiceError

__all__ = ["Flight", "Setpoint", "Track", "read_flight", "setpoint_action", "GCS_SYSTEM_ID"]

#: Ground stations conventionally use system id 255 (ArduPilot's MAV_GCS_SYSID default, PX4's too).
GCS_SYSTEM_ID = 255
BODY_FRAMES = (8, 9, 12)  # MAV_FRAME_BODY_NED, BODY_OFFSET_NED, BODY_FRD
#: type_mask bit 10 (value 1024): yaw ignored.
YAW_IGNORE_BIT = 1024


class FlightLogError(GcsVoiceError):
    """A tlog cannot be read or holds no flight."""


@dataclass
class Track:
    """Vehicle state over time; ``t_s`` are UNIX seconds from the tlog record headers."""

    t_s: list[float] = field(default_factory=list)
    north_m: list[float] = field(default_factory=list)
    east_m: list[float] = field(default_factory=list)
    alt_m: list[float] = field(default_factory=list)  # up positive (-z of LOCAL_POSITION_NED)
    vn_m_s: list[float] = field(default_factory=list)
    ve_m_s: list[float] = field(default_factory=list)
    vup_m_s: list[float] = field(default_factory=list)
    boot_s: list[float] = field(default_factory=list)  # the vehicle's own clock (time_boot_ms), simulated time


@dataclass(frozen=True)
class Setpoint:
    """One SET_POSITION_TARGET_LOCAL_NED sent by the ground station (fields as on the wire, NED)."""

    t_s: float
    frame: int
    type_mask: int
    vx_m_s: float
    vy_m_s: float
    vz_m_s: float
    yaw_rad: float

    @property
    def yaw_used(self) -> bool:
        return not (self.type_mask & YAW_IGNORE_BIT)

    def key(self) -> tuple:
        """What makes two setpoints 'the same command' (for segmenting a 10 Hz stream)."""
        yaw = round(self.yaw_rad, 2) if self.yaw_used else None
        return (self.frame, round(self.vx_m_s, 2), round(self.vy_m_s, 2), round(self.vz_m_s, 2), yaw)


@dataclass
class Flight:
    """Everything a plot or a test needs from one tlog."""

    path: Path
    track: Track
    heading_t_s: list[float]
    heading_deg: list[float]  # 0..360, clockwise from north
    setpoints: list[Setpoint]
    statustexts: list[tuple[float, str]]
    modes: list[tuple[float, int, bool]]  # (t, custom_mode, armed) at each vehicle HEARTBEAT
    autopilot: int | None = None

    @property
    def t0_s(self) -> float:
        starts = [s[0] for s in (self.track.t_s, self.heading_t_s, [p.t_s for p in self.setpoints]) if s]
        return min(starts) if starts else 0.0

    def heading_at(self, t_s: float) -> float | None:
        """Heading (deg) of the last ATTITUDE at or before ``t_s``."""
        return _value_at(self.heading_t_s, self.heading_deg, t_s)

    def position_at(self, t_s: float) -> tuple[float, float, float] | None:
        """(north, east, alt) in metres at the last LOCAL_POSITION_NED at or before ``t_s``."""
        i = _index_at(self.track.t_s, t_s)
        if i is None:
            return None
        tr = self.track
        return tr.north_m[i], tr.east_m[i], tr.alt_m[i]

    def vehicle_time_at(self, t_s: float) -> float | None:
        """The vehicle's clock (s since boot) at UNIX time ``t_s``: simulated time for a simulator."""
        return _value_at(self.track.t_s, self.track.boot_s, t_s)

    def segments(self) -> list[tuple[float, float, Setpoint]]:
        """Runs of identical setpoints: (start, end, first setpoint of the run)."""
        runs: list[tuple[float, float, Setpoint]] = []
        for sp in self.setpoints:
            if runs and runs[-1][2].key() == sp.key() and sp.t_s - runs[-1][1] < 1.0:
                start, _, first = runs[-1]
                runs[-1] = (start, sp.t_s, first)
            else:
                runs.append((sp.t_s, sp.t_s, sp))
        return runs


def _index_at(ts: list[float], t_s: float) -> int | None:
    import bisect

    i = bisect.bisect_right(ts, t_s) - 1
    return i if i >= 0 else None


def _value_at(ts: list[float], values: list[float], t_s: float) -> float | None:
    i = _index_at(ts, t_s)
    return None if i is None else values[i]


def read_flight(path: str | Path, gcs_system_id: int = GCS_SYSTEM_ID) -> Flight:
    """Parse a tlog; raise FlightLogError (one line) when it is missing or not a tlog."""
    from pymavlink import mavutil

    path = Path(path)
    if not path.is_file():
        raise FlightLogError(f"{path}: no such file")
    try:
        log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    except Exception as exc:  # pymavlink raises assorted errors on bad files
        raise FlightLogError(f"{path}: cannot open as a tlog: {exc}") from None
    track = Track()
    heading_t: list[float] = []
    heading: list[float] = []
    setpoints: list[Setpoint] = []
    texts: list[tuple[float, str]] = []
    modes: list[tuple[float, int, bool]] = []
    autopilot: int | None = None
    try:
        while True:
            msg = log.recv_match(
                type=["LOCAL_POSITION_NED", "ATTITUDE", "SET_POSITION_TARGET_LOCAL_NED", "STATUSTEXT", "HEARTBEAT"]
            )
            if msg is None:
                break
            kind = msg.get_type()
            t = float(getattr(msg, "_timestamp", 0.0))
            from_gcs = msg.get_srcSystem() == gcs_system_id
            if kind == "SET_POSITION_TARGET_LOCAL_NED":
                if from_gcs:
                    setpoints.append(
                        Setpoint(t, int(msg.coordinate_frame), int(msg.type_mask), float(msg.vx), float(msg.vy),
                                 float(msg.vz), float(msg.yaw))
                    )
            elif from_gcs:
                continue
            elif kind == "LOCAL_POSITION_NED":
                track.t_s.append(t)
                track.north_m.append(float(msg.x))
                track.east_m.append(float(msg.y))
                track.alt_m.append(-float(msg.z))
                track.vn_m_s.append(float(msg.vx))
                track.ve_m_s.append(float(msg.vy))
                track.vup_m_s.append(-float(msg.vz))
                track.boot_s.append(float(msg.time_boot_ms) / 1000.0)
            elif kind == "ATTITUDE":
                heading_t.append(t)
                heading.append(math.degrees(float(msg.yaw)) % 360.0)
            elif kind == "STATUSTEXT":
                texts.append((t, str(msg.text).strip()))
            elif kind == "HEARTBEAT" and msg.type != 6:  # 6 = MAV_TYPE_GCS
                autopilot = int(msg.autopilot)
                modes.append((t, int(msg.custom_mode), bool(msg.base_mode & 128)))
    except Exception as exc:
        raise FlightLogError(f"{path}: unreadable record: {exc}") from None
    if not track.t_s and not heading_t and not setpoints:
        raise FlightLogError(f"{path}: no position, attitude or setpoint messages (is it a MAVLink tlog?)")
    return Flight(path, track, heading_t, heading, setpoints, texts, modes, autopilot)


def setpoint_action(sp: Setpoint, heading_deg: float | None) -> str:
    """Name the action a setpoint expresses (for plots of tlogs without a session log).

    Velocities in a local frame are turned into the body frame with the vehicle's heading at that time;
    a zero-velocity setpoint whose absolute yaw target is far (> 45 deg) from the heading is a turn.
    """
    vx, vy, vz = sp.vx_m_s, sp.vy_m_s, sp.vz_m_s
    if sp.frame not in BODY_FRAMES and heading_deg is not None:
        h = math.radians(heading_deg)
        vx, vy = vx * math.cos(h) + vy * math.sin(h), -vx * math.sin(h) + vy * math.cos(h)
    horizontal = max(abs(vx), abs(vy))
    if max(horizontal, abs(vz)) < 0.05:
        if sp.yaw_used and heading_deg is not None:
            target = math.degrees(sp.yaw_rad) + (heading_deg if sp.frame in BODY_FRAMES else 0.0)
            turn = (target - heading_deg + 180.0) % 360.0 - 180.0
            if turn > 45:
                return "turn_right"
            if turn < -45:
                return "turn_left"
        return "stop"
    if abs(vz) > horizontal:
        return "up" if vz < 0 else "down"
    if abs(vx) >= abs(vy):
        return "go_forward" if vx > 0 else "go_back"
    return "go_right" if vy > 0 else "go_left"
