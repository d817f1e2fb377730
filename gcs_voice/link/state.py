"""Vehicle state from MAVLink, fed one message at a time (live, or from a .tlog for replay tests).

The tracker locks onto the first flight controller whose HEARTBEAT it hears and ignores other system
ids and ground stations. Every field keeps its last finite value: NaN, infinities and malformed
messages are dropped, never stored. STATUSTEXT chunks are reassembled by (sender, id, chunk_seq) and
PX4's trailing TAB (its "also sent as EVENT" marker) is stripped.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.autopilots import AutopilotProfile, profile_for
from gcs_voice.link.setpoints import wrap_deg

__all__ = ["VehicleState", "VehicleStateTracker", "StatusText", "CommandAck", "enum_name", "result_name", "landed_state_name"]

STATUSTEXT_CHUNK_CHARS = 50
#: how autopilots begin the texts that say why they cannot arm yet (ArduPilot, PX4)
PREARM_PREFIXES = ("PreArm:", "Arm:", "Preflight Fail:")  # PX4's "Arming denied: ..." is generic
_CHUNK_STALE_S = 2.0


def enum_name(enum: str, value: int, unknown: str | None = None) -> str:
    """A MAVLink enum value's name without the enum's prefix ("ACCEPTED" for MAV_RESULT 0); an unknown value
    is ``<unknown>_<value>`` ("RESULT_42"; ``unknown`` defaults to the enum's name less "MAV_")."""
    entry = mavlink.enums[enum].get(value)
    return entry.name.removeprefix(enum + "_") if entry else f"{unknown or enum.removeprefix('MAV_')}_{value}"


def result_name(result: int) -> str:
    """MAV_RESULT name without its prefix ("ACCEPTED", "FAILED", ...)."""
    return enum_name("MAV_RESULT", result)


def landed_state_name(value: int) -> str:
    return enum_name("MAV_LANDED_STATE", value)


@dataclass(frozen=True)
class StatusText:
    time_s: float
    severity: int
    text: str


@dataclass(frozen=True)
class CommandAck:
    time_s: float
    command: int
    result: int

    @property
    def result_name(self) -> str:
        return result_name(self.result)

    @property
    def accepted(self) -> bool:
        return self.result == mavlink.MAV_RESULT_ACCEPTED


@dataclass(frozen=True)
class VehicleState:
    """A snapshot. None = not heard yet. Positions are local NED metres; heading clockwise from north."""

    system_id: int | None = None
    component_id: int | None = None
    profile: AutopilotProfile | None = None
    mav_type: int | None = None
    base_mode: int | None = None
    custom_mode: int | None = None
    mode: str | None = None
    armed: bool | None = None
    system_status: int | None = None
    landed_state: str | None = None
    north_m: float | None = None
    east_m: float | None = None
    down_m: float | None = None
    north_m_s: float | None = None
    east_m_s: float | None = None
    down_m_s: float | None = None
    heading_deg: float | None = None
    home_north_m: float | None = None
    home_east_m: float | None = None
    home_down_m: float | None = None
    home_alt_amsl_m: float | None = None
    alt_amsl_m: float | None = None
    relative_alt_m: float | None = None
    #: downward rangefinder distance (DISTANCE_SENSOR, PITCH_270), None when absent or stale
    ground_clearance_m: float | None = None
    last_heard_s: float | None = None
    link_ok: bool = False
    heartbeats: int = 0
    #: when the last HEARTBEAT came, and since when it has shown the current custom_mode (tracker clock)
    heartbeat_s: float | None = None
    mode_since_s: float | None = None
    #: SYS_STATUS onboard_control_sensors_present / _enabled / _health bit fields (None: not heard)
    sensors_present: int | None = None
    sensors_enabled: int | None = None
    sensors_health: int | None = None
    #: battery charge left, percent, as SYS_STATUS / BATTERY_STATUS say it (None: not heard or the vehicle does not
    #: know: -1 on the wire)
    battery_pct: int | None = None
    #: EKF_STATUS_REPORT.flags (ArduPilot; None: not heard)
    ekf_flags: int | None = None
    #: the last pre-arm complaint the vehicle made ("PreArm: Need Position Estimate", "Arm: ...",
    #: "Preflight Fail: ..."), cleared when it arms
    prearm_text: str | None = None
    #: another ground station on this vehicle, seen by the COMMAND_ACKs addressed to it: its (system,
    #: component), and when (tracker clock) it last had a mode change acknowledged (DO_SET_MODE)
    other_station: tuple[int, int] | None = None
    other_station_mode_s: float | None = None

    @property
    def autopilot(self) -> str | None:
        return self.profile.name if self.profile else None

    @property
    def height_m(self) -> float | None:
        """Height above home from the local z (smoother than GLOBAL_POSITION_INT on PX4), else relative_alt."""
        if self.down_m is not None:
            return -(self.down_m - (self.home_down_m or 0.0))
        return self.relative_alt_m

    @property
    def home_distance_m(self) -> float | None:
        """Horizontal distance from home (local origin when home is unknown)."""
        if self.north_m is None or self.east_m is None:
            return None
        return math.hypot(self.north_m - (self.home_north_m or 0.0), self.east_m - (self.home_east_m or 0.0))

    @property
    def home_amsl_m(self) -> float | None:
        """Home altitude AMSL: HOME_POSITION, else GLOBAL_POSITION_INT alt - relative_alt."""
        if self.home_alt_amsl_m is not None:
            return self.home_alt_amsl_m
        if self.alt_amsl_m is not None and self.relative_alt_m is not None:
            return self.alt_amsl_m - self.relative_alt_m
        return None


def _finite(*values: Any) -> bool:
    try:
        return all(math.isfinite(float(v)) for v in values)
    except (TypeError, ValueError):
        return False


def _battery_pct(remaining: Any, before: int | None) -> int | None:
    """A battery_remaining field as a percent: -1 (the vehicle does not know) is None, nonsense keeps what was known."""
    value = int(remaining)
    if value == -1:
        return None
    return value if 0 <= value <= 100 else before


@dataclass
class _Pending:
    severity: int
    chunks: list[str]
    started_s: float


@dataclass
class VehicleStateTracker:
    """Feed ``update(msg, now_s)``; read ``state``; new ACKs and texts come back from ``update``."""

    gcs_system_id: int = 255
    link_lost_s: float = 2.0
    #: our component: a COMMAND_ACK addressed to (gcs_system_id, another component) is another station's
    #: (QGroundControl is 255/190); 0 takes every ACK addressed to our system
    gcs_component_id: int = 0
    state: VehicleState = field(default_factory=VehicleState)
    acks: deque = field(default_factory=lambda: deque(maxlen=256))
    texts: deque = field(default_factory=lambda: deque(maxlen=256))
    #: a rangefinder reading older than this is not used (PX4 sends DISTANCE_SENSOR at 0.5 Hz unless asked)
    rangefinder_max_age_s: float = 1.0
    ignored: int = 0
    _pending: dict = field(default_factory=dict)
    _clearance: tuple[float, float] | None = None  # (metres, time)

    def snapshot(self, now_s: float) -> VehicleState:
        """The state with ``link_ok`` and the rangefinder's freshness evaluated at ``now_s``."""
        heard = self.state.last_heard_s
        ok = heard is not None and now_s - heard < self.link_lost_s
        clearance = None
        if self._clearance is not None and now_s - self._clearance[1] <= self.rangefinder_max_age_s:
            clearance = self._clearance[0]
        if ok == self.state.link_ok and clearance == self.state.ground_clearance_m:
            return self.state
        return replace(self.state, link_ok=ok, ground_clearance_m=clearance)

    def update(self, msg: mavlink.MAVLink_message, now_s: float) -> list[CommandAck | StatusText]:
        """Take one message; return the ACKs and complete STATUSTEXTs it produced. Never raises on bad input."""
        try:
            return self._update(msg, now_s)
        except (AttributeError, TypeError, ValueError, KeyError, OverflowError):
            self.ignored += 1
            return []

    def _update(self, msg: mavlink.MAVLink_message, now_s: float) -> list[CommandAck | StatusText]:
        kind = msg.get_type()
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "BAD_DATA" or sysid == self.gcs_system_id:
            return []
        if self.state.system_id is None:
            if kind == "HEARTBEAT" and self._is_flight_controller(msg):
                self.state = replace(self.state, system_id=sysid, component_id=compid)
            elif kind == "STATUSTEXT":  # boot messages come before the first HEARTBEAT
                return self._statustext(msg, now_s)
            else:
                return []
        if sysid != self.state.system_id:
            self.ignored += 1
            return []
        if compid == self.state.component_id or kind in ("STATUSTEXT", "COMMAND_ACK"):
            self.state = replace(self.state, last_heard_s=now_s, link_ok=True)
        handler = getattr(self, "_" + kind.lower(), None)
        if handler is None or (compid != self.state.component_id and kind not in ("STATUSTEXT", "COMMAND_ACK")):
            return []
        return handler(msg, now_s) or []

    @staticmethod
    def _is_flight_controller(msg: mavlink.MAVLink_message) -> bool:
        return msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID and msg.type not in (
            mavlink.MAV_TYPE_GCS, mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_TYPE_GIMBAL,
            mavlink.MAV_TYPE_CAMERA, mavlink.MAV_TYPE_ADSB)

    def _heartbeat(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if not self._is_flight_controller(msg):
            return
        profile = profile_for(msg.autopilot)
        mode = profile.mode_name(msg.base_mode, msg.custom_mode) if profile else f"MODE({msg.custom_mode})"
        armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        since = self.state.mode_since_s if self.state.custom_mode == msg.custom_mode else now_s
        self.state = replace(
            self.state, profile=profile, mav_type=msg.type, base_mode=msg.base_mode, custom_mode=msg.custom_mode,
            mode=mode, armed=armed, system_status=msg.system_status, heartbeats=self.state.heartbeats + 1,
            heartbeat_s=now_s, mode_since_s=since if since is not None else now_s,
            # a complaint made while booting ("Arm: System not initialised") is stale once the boot is over
            prearm_text=None if armed or (self.state.system_status == mavlink.MAV_STATE_BOOT
                                          and msg.system_status != mavlink.MAV_STATE_BOOT) else self.state.prearm_text,
        )

    def _sys_status(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        self.state = replace(self.state, sensors_present=int(msg.onboard_control_sensors_present),
                             sensors_enabled=int(msg.onboard_control_sensors_enabled),
                             sensors_health=int(msg.onboard_control_sensors_health),
                             battery_pct=_battery_pct(msg.battery_remaining, self.state.battery_pct))

    def _battery_status(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if int(getattr(msg, "id", 0)) == 0:  # the first battery is the flight battery (both autopilots)
            self.state = replace(self.state, battery_pct=_battery_pct(msg.battery_remaining, self.state.battery_pct))

    def _ekf_status_report(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        self.state = replace(self.state, ekf_flags=int(msg.flags))

    def _extended_sys_state(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        self.state = replace(self.state, landed_state=landed_state_name(int(msg.landed_state)))

    def _local_position_ned(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if _finite(msg.x, msg.y, msg.z):
            self.state = replace(self.state, north_m=float(msg.x), east_m=float(msg.y), down_m=float(msg.z))
        if _finite(msg.vx, msg.vy, msg.vz):
            self.state = replace(self.state, north_m_s=float(msg.vx), east_m_s=float(msg.vy), down_m_s=float(msg.vz))

    def _attitude(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if _finite(msg.yaw):
            self.state = replace(self.state, heading_deg=wrap_deg(math.degrees(float(msg.yaw))))

    def _global_position_int(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        self.state = replace(self.state, alt_amsl_m=msg.alt / 1000.0, relative_alt_m=msg.relative_alt / 1000.0)

    def _distance_sensor(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if msg.orientation != mavlink.MAV_SENSOR_ROTATION_PITCH_270:
            return
        distance_cm = int(msg.current_distance)
        if msg.min_distance <= distance_cm <= msg.max_distance and msg.max_distance > 0:
            self._clearance = (distance_cm / 100.0, now_s)
            self.state = replace(self.state, ground_clearance_m=distance_cm / 100.0)

    def _home_position(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        if _finite(msg.x, msg.y, msg.z):
            self.state = replace(self.state, home_north_m=float(msg.x), home_east_m=float(msg.y),
                                 home_down_m=float(msg.z))
        self.state = replace(self.state, home_alt_amsl_m=msg.altitude / 1000.0)

    def _command_ack(self, msg: mavlink.MAVLink_message, now_s: float) -> list[CommandAck]:
        """Ours when addressed to our system and component (0 = broadcast, as MAVLink 1 ACKs are).

        Behind a router (MAVProxy, mavlink-router) or on PX4's second link we also hear the ACKs meant for
        the other ground stations: those are not answers to our commands, only a sign that someone else
        commands this vehicle (kept in ``other_station``)."""
        target = int(getattr(msg, "target_system", 0) or 0)
        component = int(getattr(msg, "target_component", 0) or 0)
        ours = target in (0, self.gcs_system_id) and (
            target == 0 or component == 0 or not self.gcs_component_id or component == self.gcs_component_id)
        if not ours:
            mode = self.state.other_station_mode_s
            if int(msg.command) == mavlink.MAV_CMD_DO_SET_MODE and int(msg.result) == mavlink.MAV_RESULT_ACCEPTED:
                mode = now_s
            self.state = replace(self.state, other_station=(target, component), other_station_mode_s=mode)
            return []
        ack = CommandAck(now_s, int(msg.command), int(msg.result))
        self.acks.append(ack)
        return [ack]

    def _statustext(self, msg: mavlink.MAVLink_message, now_s: float) -> list[StatusText]:
        text = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode("utf-8", "replace")
        text = text.split("\0", 1)[0]
        text_id, chunk_seq = int(getattr(msg, "id", 0) or 0), int(getattr(msg, "chunk_seq", 0) or 0)
        done: list[StatusText] = self._flush_stale(now_s)
        if text_id == 0:
            done.append(self._emit(now_s, int(msg.severity), text))
            return done
        key = (msg.get_srcSystem(), msg.get_srcComponent(), text_id)
        pending = self._pending.get(key)
        if chunk_seq == 0 or pending is None or len(pending.chunks) != chunk_seq:
            if pending is not None:  # a chunk went missing: say what we have
                done.append(self._emit(now_s, pending.severity, "".join(pending.chunks)))
            pending = _Pending(int(msg.severity), [], now_s)
            if chunk_seq != 0:
                pending.chunks.append("...")
        pending.chunks.append(text)
        self._pending[key] = pending
        if len(text) < STATUSTEXT_CHUNK_CHARS:
            del self._pending[key]
            done.append(self._emit(now_s, pending.severity, "".join(pending.chunks)))
        return done

    def _flush_stale(self, now_s: float) -> list[StatusText]:
        stale = [k for k, p in self._pending.items() if now_s - p.started_s > _CHUNK_STALE_S]
        return [self._emit(now_s, p.severity, "".join(p.chunks)) for p in (self._pending.pop(k) for k in stale)]

    def _emit(self, now_s: float, severity: int, text: str) -> StatusText:
        status = StatusText(now_s, severity, text.rstrip("\t\r\n "))
        self.texts.append(status)
        if status.text.startswith(PREARM_PREFIXES) and not self.state.armed:
            self.state = replace(self.state, prearm_text=status.text)
        return status
