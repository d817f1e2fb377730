"""Replays: the committed sim fixture, and the real ArduCopter / PX4 captures driven into the sim.

The real captures (../shared/tlogs) hold every message a ground station sent to real SITL. We send the
same messages at the same times to gcs-sim and compare what comes back: COMMAND_ACK results for
commands given in the same situation, HEARTBEAT fields, the message set, stream rates and a few flight
facts (auto-yaw, guided timeout, offboard-loss failsafe). These tests fail when the sim drifts away
from the real autopilots.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import pytest
from tools.flight.lockstep_gcs import LockstepGcs

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "sim_ardupilot_guided_flight.tlog"
GCS_SYSTEM = 255
ARDU_HOME = (-33.45, -70.66, 500.0)
PX4_HOME = (47.3977, 8.5456, 489.643)
#: COMMAND_ACKs count for the request they follow if they come within this time.
ACK_WINDOW_S = 0.3


def read_tlog(path: Path) -> list[tuple[float, object]]:
    """(seconds from the first record, message) for every decodable record."""
    log = mavutil.mavlink_connection(str(path))
    records, first = [], None
    while (msg := log.recv_match()) is not None:
        if msg.get_type() == "BAD_DATA" or msg.get_type().startswith("UNKNOWN"):
            continue
        first = msg._timestamp if first is None else first
        records.append((msg._timestamp - first, msg))
    return records


def replay_into_sim(records: list[tuple[float, object]], autopilot: str, home: tuple) -> list[tuple[float, object]]:
    """Send the ground station's messages to a lockstep sim at their times; return the sim's timeline."""
    g = LockstepGcs(autopilot, room="open_field", home=home)
    timeline: list[tuple[float, object]] = []
    try:
        for t, msg in records:
            if msg.get_srcSystem() != GCS_SYSTEM:
                continue
            if t > g.t_s:
                g.run(t - g.t_s)
            timeline.extend(g.received)
            g.received.clear()
            timeline.append((g.t_s, msg))
            g.send(msg)
            if msg.get_type() in ("COMMAND_LONG", "SET_MODE"):
                g.run(g.server.dt_s)    # the real GCS waited for each ACK before its next request
        g.run(records[-1][0] - g.t_s + 0.5)
        timeline.extend(g.received)
    finally:
        g.close()
    return timeline


class Situation:
    """What the ground station knew when it sent a request: the latest HEARTBEAT, EKF flags, setpoints."""

    def __init__(self) -> None:
        self.heartbeat = None
        self.ekf_flags = None
        self.last_setpoint_s = -math.inf
        self.home_seen = False
        self.arm_requested: bool | None = None
        self.armed_by_ack: bool | None = None   # an accepted arm/disarm the next HEARTBEAT has not shown yet

    def see(self, t: float, msg) -> None:
        kind = msg.get_type()
        if msg.get_srcSystem() == GCS_SYSTEM:
            if kind == "SET_POSITION_TARGET_LOCAL_NED" and msg.coordinate_frame in (1, 8):
                self.last_setpoint_s = t
            elif kind == "COMMAND_LONG" and msg.command == M.MAV_CMD_COMPONENT_ARM_DISARM:
                self.arm_requested = msg.param1 >= 0.5
        elif kind == "COMMAND_ACK" and msg.command == M.MAV_CMD_COMPONENT_ARM_DISARM and msg.result == 0:
            self.armed_by_ack = self.arm_requested
        elif kind == "HEARTBEAT":
            self.heartbeat = msg
            self.armed_by_ack = None
        elif kind == "EKF_STATUS_REPORT":
            self.ekf_flags = msg.flags
        elif kind == "HOME_POSITION":
            self.home_seen = True

    def key(self, t: float, msg, autopilot: str) -> tuple | None:
        hb = self.heartbeat
        if hb is None:
            return None
        armed = bool(hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED) if self.armed_by_ack is None else self.armed_by_ack
        state = (armed, hb.custom_mode, hb.system_status)
        kind = msg.get_type()
        if kind == "SET_MODE":
            return ("SET_MODE", msg.custom_mode, armed)
        if kind in ("MISSION_REQUEST_LIST",):
            return (kind, self.home_seen)
        if kind != "COMMAND_LONG":
            return None
        cmd, p = msg.command, (msg.param1, msg.param2, msg.param3)
        if cmd in (M.MAV_CMD_REQUEST_MESSAGE, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAV_CMD_CONDITION_YAW):
            return (cmd, int(p[0]))
        extra: tuple = ()
        if autopilot == "ardupilot":
            extra = (self.ekf_flags == 831,)
        elif cmd == M.MAV_CMD_DO_SET_MODE:
            extra = (t - self.last_setpoint_s < 1.0,)
        if cmd == M.MAV_CMD_DO_SET_MODE:
            return (cmd, int(p[1]), int(p[2]), *state, *extra)
        if cmd == M.MAV_CMD_COMPONENT_ARM_DISARM:
            return (cmd, int(p[0]), *state, *extra)
        if autopilot == "px4":
            return (cmd, armed, hb.custom_mode)   # PX4's system_status says "armable", not "landed"
        return (cmd, *state, *extra)


def outcomes(timeline: list[tuple[float, object]], autopilot: str) -> dict[tuple, set[tuple]]:
    """situation key -> set of (COMMAND_ACK results...) or (MISSION_COUNT,) seen for it."""
    situation = Situation()
    found: dict[tuple, set[tuple]] = defaultdict(set)
    pending: list[tuple[float, tuple, str, int, list]] = []
    for t, msg in timeline:
        kind = msg.get_type()
        if msg.get_srcSystem() == GCS_SYSTEM and kind in ("COMMAND_LONG", "SET_MODE", "MISSION_REQUEST_LIST"):
            key = situation.key(t, msg, autopilot)
            if key is not None:
                command = msg.command if kind == "COMMAND_LONG" else M.MAV_CMD_DO_SET_MODE
                pending = [p for p in pending if p[0] > t - ACK_WINDOW_S and p[3] != command]
                pending.append((t, key, kind, command, []))
        elif kind == "COMMAND_ACK" and msg.get_srcSystem() != GCS_SYSTEM:
            for p in reversed(pending):
                if p[3] == msg.command and t - p[0] <= ACK_WINDOW_S and p[2] != "MISSION_REQUEST_LIST":
                    p[4].append(msg.result)
                    break
        elif kind == "MISSION_COUNT":
            for p in reversed(pending):
                if p[2] == "MISSION_REQUEST_LIST":
                    p[4].append(msg.count)
                    break
        situation.see(t, msg)
        for p in [p for p in pending if t - p[0] > ACK_WINDOW_S]:
            found[p[1]].add(tuple(p[4]))
            pending.remove(p)
    for p in pending:
        found[p[1]].add(tuple(p[4]))
    return found


def vehicle_types(timeline) -> set[str]:
    return {m.get_type() for _t, m in timeline if m.get_srcSystem() != GCS_SYSTEM}


def rate_hz(timeline, kind: str, start_s: float, end_s: float) -> float:
    n = sum(1 for t, m in timeline if start_s <= t < end_s and m.get_type() == kind and m.get_srcSystem() != GCS_SYSTEM)
    return n / (end_s - start_s)


def heartbeat_modes(timeline) -> dict[tuple, set[tuple]]:
    """(custom_mode, armed) -> {(base_mode, system_status)} seen."""
    seen: dict[tuple, set[tuple]] = defaultdict(set)
    for _t, m in timeline:
        if m.get_type() == "HEARTBEAT" and m.get_srcSystem() != GCS_SYSTEM:
            seen[(m.custom_mode, bool(m.base_mode & 128))].add((m.base_mode, m.system_status))
    return seen


def version_fields(log) -> tuple:
    """AUTOPILOT_VERSION (asked with REQUEST_MESSAGE in both captures): what a GCS identifies firmware by."""
    m = next(m for _t, m in log if m.get_type() == "AUTOPILOT_VERSION")
    return m.capabilities, m.flight_sw_version, bytes(m.flight_custom_version)


def at(timeline, kind: str, t_s: float):
    """The last message of ``kind`` from the vehicle at or before ``t_s``."""
    last = None
    for t, m in timeline:
        if t > t_s:
            break
        if m.get_type() == kind and m.get_srcSystem() != GCS_SYSTEM:
            last = m
    return last


# ---------------------------------------------------------------------------- the committed fixture
@pytest.mark.slow
def test_fixture_parses_and_the_current_sim_still_flies_it_the_same() -> None:
    recorded = read_tlog(FIXTURE)
    assert len(recorded) > 500 and FIXTURE.stat().st_size < 60_000
    hb = next(m for _t, m in recorded if m.get_type() == "HEARTBEAT")
    assert (hb.type, hb.autopilot, hb.get_srcSystem(), hb.get_srcComponent()) == (2, 3, 1, 1)
    acks = [(m.command, m.result) for _t, m in recorded if m.get_type() == "COMMAND_ACK"]
    assert acks == [(512, 0), (22, 4), (176, 0), (400, 0), (22, 0), (21, 0)]
    replayed = replay_into_sim(recorded, "ardupilot", None)
    assert outcomes(replayed, "ardupilot") == outcomes(recorded, "ardupilot")
    for t_s in (12.0, 17.0, 20.0, 28.0):   # hovering, after the forward leg, after the turn, landed
        then, now = at(recorded, "LOCAL_POSITION_NED", t_s), at(replayed, "LOCAL_POSITION_NED", t_s)
        assert math.dist((then.x, then.y, then.z), (now.x, now.y, now.z)) < 0.5, f"flight path drifted at {t_s} s"


# ---------------------------------------------------------------------------- against real ArduCopter
@pytest.fixture(scope="module")
def arducopter(tlogs_dir: Path):
    real = read_tlog(tlogs_dir / "arducopter-sitl-guided-velocity.tlog")
    return real, replay_into_sim(real, "ardupilot", ARDU_HOME)


@pytest.mark.slow
def test_arducopter_acks_match_real_in_the_same_situations(arducopter) -> None:
    real, sim = arducopter
    real_out, sim_out = outcomes(real, "ardupilot"), outcomes(sim, "ardupilot")
    common = set(real_out) & set(sim_out)
    mismatched = {k: (real_out[k], sim_out[k]) for k in common if real_out[k] != sim_out[k]}
    assert not mismatched, f"situation: (real, sim) results {mismatched}"
    commands = {k[0] for k in common}
    assert {512, 511, 176, 400, 22, 21, "SET_MODE", "MISSION_REQUEST_LIST"} <= commands, sorted(map(str, commands))
    assert sim_out[("SET_MODE", 4, False)] == {()}, "no COMMAND_ACK for the SET_MODE message"


@pytest.mark.slow
def test_arducopter_heartbeat_messages_and_rates_match_real(arducopter) -> None:
    real, sim = arducopter
    assert vehicle_types(sim) <= vehicle_types(real), "the sim invents no message ArduCopter does not send"
    assert version_fields(sim) == version_fields(real)
    real_modes, sim_modes = heartbeat_modes(real), heartbeat_modes(sim)
    for pair in set(real_modes) & set(sim_modes):
        assert sim_modes[pair] <= real_modes[pair], f"HEARTBEAT for (mode, armed) {pair}"
    assert (4, True) in sim_modes and (9, False) in sim_modes
    for kind in ("ATTITUDE", "LOCAL_POSITION_NED", "HEARTBEAT", "EXTENDED_SYS_STATE", "GLOBAL_POSITION_INT",
                 "SYS_STATUS", "VFR_HUD"):
        assert rate_hz(sim, kind, 51, 90) == pytest.approx(rate_hz(real, kind, 51, 90), rel=0.15), kind


@pytest.mark.slow
def test_arducopter_flight_facts_match_real(arducopter) -> None:
    real, sim = arducopter
    for log in (real, sim):
        assert -at(log, "LOCAL_POSITION_NED", 50.0).z == pytest.approx(2.0, abs=0.2), "takeoff to 2 m"
        assert at(log, "VFR_HUD", 83.5).heading == pytest.approx(180, abs=6), "nose turned toward the travel"
        assert at(log, "LOCAL_POSITION_NED", 85.5).vx < -0.8, "last velocity kept until GUID_TIMEOUT"
        late = at(log, "LOCAL_POSITION_NED", 89.5)
        assert math.hypot(late.vx, late.vy) < 0.15, "then it holds"
        assert at(log, "HEARTBEAT", 91.0).custom_mode == 4, "still GUIDED"
    real_leg = at(real, "LOCAL_POSITION_NED", 56.5).x - at(real, "LOCAL_POSITION_NED", 50.6).x
    sim_leg = at(sim, "LOCAL_POSITION_NED", 56.5).x - at(sim, "LOCAL_POSITION_NED", 50.6).x
    assert sim_leg == pytest.approx(real_leg, rel=0.25), "forward leg (1 m/s for 4 s, then stop)"


# ---------------------------------------------------------------------------- against real PX4
@pytest.fixture(scope="module")
def px4(tlogs_dir: Path):
    real = read_tlog(tlogs_dir / "px4-sih-offboard-velocity.tlog")
    return real, replay_into_sim(real, "px4", PX4_HOME)


@pytest.mark.slow
def test_px4_acks_match_real_in_the_same_situations(px4) -> None:
    real, sim = px4
    real_out, sim_out = outcomes(real, "px4"), outcomes(sim, "px4")
    common = set(real_out) & set(sim_out)
    mismatched = {k: (real_out[k], sim_out[k]) for k in common if real_out[k] != sim_out[k]}
    assert not mismatched, f"situation: (real, sim) results {mismatched}"
    assert {(0, 1), (0, 0)} <= {r for k in common if k[0] == 176 for r in real_out[k]}, "both double-ACK forms"
    assert {400, 176, 22, 21, 115, 512, "SET_MODE"} <= {k[0] for k in common}


@pytest.mark.slow
def test_px4_heartbeat_messages_rates_and_failsafe_match_real(px4) -> None:
    real, sim = px4
    assert vehicle_types(sim) <= vehicle_types(real), "the sim invents no message PX4 does not send"
    assert version_fields(sim) == version_fields(real)
    real_modes, sim_modes = heartbeat_modes(real), heartbeat_modes(sim)
    for pair in set(real_modes) & set(sim_modes):
        assert {b for b, _s in sim_modes[pair]} <= {b for b, _s in real_modes[pair]}, f"base_mode for {pair}"
    for kind in ("HEARTBEAT", "SYS_STATUS", "EXTENDED_SYS_STATE", "VFR_HUD", "GPS_RAW_INT"):
        assert rate_hz(sim, kind, 20, 70) == pytest.approx(rate_hz(real, kind, 20, 70), rel=0.15), kind
    for log in (real, sim):
        texts = [(t, m.text) for t, m in log if m.get_type() == "STATUSTEXT"]
        failsafe_s = next(t for t, text in texts if text.startswith("Failsafe activated"))
        assert 48.4 <= failsafe_s <= 48.9, "COM_OF_LOSS_T after the last setpoint (47.65 s)"
        assert at(log, "HEARTBEAT", 50.5).custom_mode == 84148224, "RTL without RC"
        assert at(log, "HEARTBEAT", 30.0).custom_mode == 393216 and at(log, "HEARTBEAT", 30.0).base_mode == 145


def geofence_bits(timeline) -> set[tuple[bool, bool, bool]]:
    """SYS_STATUS geofence bit as (present, enabled, healthy), over every SYS_STATUS the vehicle sent."""
    bit = M.MAV_SYS_STATUS_GEOFENCE
    return {(bool(m.onboard_control_sensors_present & bit), bool(m.onboard_control_sensors_enabled & bit),
             bool(m.onboard_control_sensors_health & bit))
            for _t, m in timeline if m.get_type() == "SYS_STATUS" and m.get_srcSystem() == 1}


@pytest.mark.slow
@pytest.mark.parametrize("capture", ["arducopter", "px4"])
def test_sys_status_geofence_bit_matches_real(capture: str, request: pytest.FixtureRequest) -> None:
    """ArduCopter reports the fence present and healthy (disabled: FENCE_ENABLE 0); PX4 SIH does not report it.

    With present=1, health=0 MAVProxy prints "fence breach" on every connect.
    """
    real, sim = request.getfixturevalue(capture)
    assert geofence_bits(real) and geofence_bits(sim) == geofence_bits(real)
