"""Replay real ArduCopter and PX4 SITL captures (../shared/tlogs) through the state tracker.

Expected values come from the captures' READMEs (ARDUCOPTER.md, PX4.md, README.md tables), not from
running the tracker.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from pymavlink import mavutil

from gcs_voice.link.state import CommandAck, StatusText, VehicleState, VehicleStateTracker

ARDUCOPTER_LOG = "arducopter-sitl-guided-velocity.tlog"
PX4_LOG = "px4-sih-offboard-velocity.tlog"


class Replay:
    """State at chosen times (seconds from the first record) plus every ACK and text, with times."""

    def __init__(self, path: Path, checkpoints: list[float]) -> None:
        self.tracker = VehicleStateTracker()
        self.at: dict[float, VehicleState] = {}
        self.acks: list[tuple[float, CommandAck]] = []
        self.texts: list[tuple[float, StatusText]] = []
        self.unknown = 0
        log = mavutil.mavlink_connection(str(path))
        pending = sorted(checkpoints)
        t0 = None
        while (msg := log.recv_match()) is not None:
            t0 = msg._timestamp if t0 is None else t0
            t = msg._timestamp - t0
            while pending and t > pending[0]:
                self.at[pending.pop(0)] = self.tracker.snapshot(msg._timestamp)
            if msg.get_type().startswith("UNKNOWN_"):
                self.unknown += 1
            if msg.get_srcSystem() == 255:  # what the ground station sent
                continue
            for event in self.tracker.update(msg, msg._timestamp):
                (self.acks if isinstance(event, CommandAck) else self.texts).append((round(t, 2), event))
        self.final = self.tracker.state

    def acks_of(self, command: int) -> list[tuple[float, int]]:
        return [(t, a.result) for t, a in self.acks if a.command == command]


@pytest.fixture(scope="module")
def arducopter(tlogs_dir: Path) -> Replay:
    return Replay(tlogs_dir / ARDUCOPTER_LOG, [1.0, 2.0, 3.0, 5.5, 5.8, 40.0, 42.7, 43.0, 50.5, 54.6, 62.5,
                                              70.0, 83.5, 91.0, 93.0])


@pytest.fixture(scope="module")
def px4(tlogs_dir: Path) -> Replay:
    return Replay(tlogs_dir / PX4_LOG, [0.45, 3.0, 4.5, 6.5, 11.0, 12.0, 12.6, 21.0, 27.0, 27.8, 47.5, 49.0,
                                        60.2, 73.0])


def test_arducopter_modes_and_arming(arducopter: Replay) -> None:
    at = arducopter.at
    assert at[1.0].system_id is None  # only a STATUSTEXT so far; first HEARTBEAT at 1.80
    assert at[2.0].autopilot == "ArduPilot" and at[2.0].mode == "STABILIZE" and at[2.0].armed is False
    assert at[3.0].mode == "GUIDED"  # DO_SET_MODE during boot, reset to STABILIZE at 3.23
    assert at[5.5].mode == "STABILIZE"
    for t in (5.8, 40.0, 42.7):
        assert at[t].mode == "GUIDED" and at[t].armed is False, t
    assert at[43.0].armed is True and at[43.0].mode == "GUIDED"
    assert at[91.0].mode == "GUIDED" and at[91.0].landed_state == "IN_AIR"
    assert at[93.0].mode == "LAND" and at[93.0].landed_state == "LANDING"
    assert arducopter.final.mode == "LAND" and arducopter.final.armed is False
    assert arducopter.final.landed_state == "ON_GROUND"
    assert (arducopter.final.system_id, arducopter.final.component_id) == (1, 1)


def test_arducopter_battery_is_read_and_drains_in_flight(arducopter: Replay) -> None:
    """SYS_STATUS.battery_remaining (ARDUCOPTER.md: "battery_remaining 96") is the state's battery; the first
    SYS_STATUS of a booting ArduCopter says -1 (not known), which is None, not -1 %."""
    at = arducopter.at
    assert at[43.0].battery_pct is not None and 0 < at[43.0].battery_pct <= 100
    assert arducopter.final.battery_pct is not None and arducopter.final.battery_pct < at[43.0].battery_pct
    tracker = VehicleStateTracker()
    mav = mavutil.mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    hb = mav.heartbeat_encode(2, 3, 0, 0, 0)
    tracker.update(hb, 0.0)
    for remaining, expected in ((-1, None), (80, 80), (120, 80), (-1, None)):
        msg = mav.sys_status_encode(0, 0, 0, 0, 12000, 0, remaining, 0, 0, 0, 0, 0, 0)
        tracker.update(msg, 1.0)
        assert tracker.state.battery_pct == expected, remaining


def test_arducopter_position_and_heading(arducopter: Replay) -> None:
    at = arducopter.at
    assert at[50.5].height_m == pytest.approx(2.0, abs=0.2)  # takeoff to 2 m done at 48.6
    # forward 1 m/s for 4 s at heading 0 from 50.63: about 3.3 m north, nothing east
    assert at[54.6].north_m - at[50.5].north_m == pytest.approx(3.3, abs=0.4)
    assert abs(at[54.6].east_m - at[50.5].east_m) < 0.3
    assert min(at[62.5].heading_deg, 360 - at[62.5].heading_deg) < 5
    assert at[70.0].heading_deg == pytest.approx(90, abs=4)
    assert at[83.5].heading_deg == pytest.approx(180, abs=6)  # yaw ignored: nose turned to travel (south)
    assert arducopter.final.height_m == pytest.approx(0.0, abs=0.1)
    assert arducopter.final.home_alt_amsl_m == pytest.approx(500.08, abs=0.01)


def test_arducopter_acks_and_texts(arducopter: Replay) -> None:
    assert len(arducopter.acks) == 26 and len(arducopter.texts) == 51  # README "Message counts"
    arm = arducopter.acks_of(400)
    assert [r for _, r in arm] == [4] * 13 + [0]  # 2.36 during boot, 12 tries 6.65-39.72, accepted 42.72
    assert arm[-1][0] == pytest.approx(42.72, abs=0.02)
    assert arducopter.acks_of(176) == [(2.41, 0), (3.24, 4), (5.64, 0)]
    assert [r for _, r in arducopter.acks_of(22)] == [4, 4, 0, 4]
    assert [r for _, r in arducopter.acks_of(21)] == [0]
    texts = [e.text for _, e in arducopter.texts]
    for expected in ("Arm: System not initialised", "Arm: Need Alt Estimate", "Arm: AHRS: waiting for home",
                     "PreArm: Need Position Estimate", "No such mode 99", "Arming motors", "Disarming motors"):
        assert expected in texts
    assert texts.count("Arm: Need Position Estimate") == 7  # 21.68 ... 39.72
    assert all(e.severity == 2 for _, e in arducopter.texts if e.text.startswith("Arm:"))
    assert texts[0] == "Calibrating barometer"  # before the first HEARTBEAT, still read


def test_px4_modes(px4: Replay) -> None:
    at = px4.at
    assert at[0.45].autopilot == "PX4" and at[0.45].mode == "LOITER" and at[0.45].armed is False
    assert at[3.0].mode == "LOITER"
    assert at[4.5].mode == "OFFBOARD" and at[4.5].armed is False  # DO_SET_MODE at 3.41, beat at 4.42
    assert at[6.5].mode == "MISSION"  # ArduCopter's "4" on PX4
    assert at[11.0].mode == "TAKEOFF" and at[11.0].armed is False
    assert at[12.0].mode == "LOITER"  # SET_MODE message at 10.49: Hold
    assert at[12.6].armed is True
    assert at[21.0].mode == "LOITER" and at[21.0].landed_state == "IN_AIR"
    assert at[21.0].height_m == pytest.approx(5.0, abs=1.0)
    assert at[27.0].mode == "LOITER"  # the ACCEPTED+REJECTED pair at 22.61 changed nothing
    assert at[27.8].mode == "OFFBOARD" and at[27.8].armed is True
    assert at[47.5].mode == "OFFBOARD"
    assert at[49.0].mode == "RTL" and at[49.0].system_status == 5
    assert at[60.2].mode == "LAND"
    assert at[73.0].landed_state == "ON_GROUND"
    assert px4.final.mode == "OFFBOARD" and px4.final.armed is False  # back in OFFBOARD by itself
    assert px4.final.custom_mode == 393216 and px4.final.base_mode == 17


def test_px4_rangefinder_is_used_only_while_fresh(tlogs_dir: Path) -> None:
    """PX4 SIH sends a downward DISTANCE_SENSOR at 0.5 Hz: 5.02 m at 28.7 s from the first record."""
    tracker = VehicleStateTracker()
    log = mavutil.mavlink_connection(str(tlogs_dir / PX4_LOG))
    t0, readings = None, []
    while (msg := log.recv_match()) is not None:
        t0 = msg._timestamp if t0 is None else t0
        if msg.get_srcSystem() == 255:
            continue
        tracker.update(msg, msg._timestamp)
        if msg.get_type() == "DISTANCE_SENSOR":
            fresh = tracker.snapshot(msg._timestamp + 0.5).ground_clearance_m
            stale = tracker.snapshot(msg._timestamp + 1.5).ground_clearance_m
            readings.append((round(msg._timestamp - t0, 1), fresh, stale))
    assert len(readings) == 38
    assert (28.7, 5.02, None) in readings
    assert all(stale is None for _, _, stale in readings)


def test_px4_heading_follows_yaw_target(px4: Replay) -> None:
    # yaw target 1.608 rad (92 deg) from 36.24 s; reached within 3 deg after 3 s
    state = px4.at[47.5]
    assert state.heading_deg is not None and math.isfinite(state.heading_deg)
    assert px4.at[27.0].heading_deg == pytest.approx(353, abs=8)


def test_px4_double_ack_and_chunked_texts(px4: Replay) -> None:
    # README counts 19 COMMAND_ACK and 25 STATUSTEXT records; 7 texts came as 2 chunks each
    assert len(px4.acks) == 19 and len(px4.texts) == 25 - 7
    mode_acks = px4.acks_of(176)
    assert [(t, r) for t, r in mode_acks if 22 < t < 23] == [(22.62, 0), (22.62, 1)]
    assert [r for t, r in mode_acks if 26 < t < 27.5] == [0, 0]
    assert [r for _, r in px4.acks_of(400)] == [1, 1, 1, 0]
    assert px4.acks_of(115) == [(9.87, 3)]
    texts = [e.text for _, e in px4.texts]
    assert texts.count("Arming denied: Resolve system health failures first") == 3  # 50 + 2 chars, reassembled
    for expected in ("Armed by external command", "Switching to Offboard is currently not available",
                     "SET_POSITION_TARGET_LOCAL_NED coordinate frame 9 unsupported", "Failsafe activated",
                     "Disarmed by landing", "[logger] ./log/2026-11-25/10_18_14.ulg"):
        assert expected in texts
    assert "SET_POSITION_TARGET_LOCAL_NED coordinate frame 12 unsupported" in texts  # split after "12 "
    assert "RTL: start return at 497 m (7 m above destination)" in texts  # 50 chars + a chunk holding "\t"
    assert not any(t.endswith("\t") or t.endswith("firs") or not t for t in texts)


def test_px4_newer_messages_do_not_break_anything(px4: Replay) -> None:
    assert px4.unknown > 100  # EVENT, CURRENT_EVENT_SEQUENCE, LINK_NODE_STATUS, ... as UNKNOWN_n
    assert px4.final.heartbeats == 75
