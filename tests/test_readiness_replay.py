"""The bridge's arming decisions over the real boots in ../shared/tlogs: which command, and when.

``link.readiness.next_step`` is fed the captured vehicle's messages one at a time (the ground station's
own packets are skipped) and every change of decision is recorded with its time from the first record.
The replay is open loop: the vehicle answered the capture's ground station, not ours, so what is
checked is what our bridge *would* send at each point of the real boot. Expected times come from the
captures' notes (ARDUCOPTER.md, PX4.md, README.md), not from running this code.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink import mavutil

from gcs_voice.link.readiness import ARM, READY, SET_MODE, WAIT, Step, assess, next_step
from gcs_voice.link.state import VehicleState, VehicleStateTracker

ARDUCOPTER_LOG = "arducopter-sitl-guided-velocity.tlog"
PX4_LOG = "px4-sih-offboard-velocity.tlog"


def decisions(path: Path, until_s: float) -> list[tuple[float, Step, VehicleState]]:
    """(time, step, state) at every change of step, from the first record to ``until_s``."""
    tracker = VehicleStateTracker()
    log = mavutil.mavlink_connection(str(path))
    out: list[tuple[float, Step, VehicleState]] = []
    t0 = None
    while (msg := log.recv_match()) is not None:
        t0 = msg._timestamp if t0 is None else t0
        t = msg._timestamp - t0
        if t > until_s:
            break
        if msg.get_srcSystem() == 255:
            continue
        tracker.update(msg, msg._timestamp)
        step = next_step(tracker.state, msg._timestamp)
        if not out or out[-1][1] != step:
            out.append((round(t, 2), step, tracker.state))
    return out


@pytest.fixture(scope="module")
def arducopter(tlogs_dir: Path) -> list[tuple[float, Step, VehicleState]]:
    return decisions(tlogs_dir / ARDUCOPTER_LOG, until_s=42.8)   # until the first armed HEARTBEAT


@pytest.fixture(scope="module")
def px4(tlogs_dir: Path) -> list[tuple[float, Step, VehicleState]]:
    return decisions(tlogs_dir / PX4_LOG, until_s=4.0)   # the boot, before the capture's GCS chose OFFBOARD


def test_arducopter_boot_is_waited_for_and_guided_reasserted(arducopter) -> None:
    first_beat = next(t for t, _s, state in arducopter if state.heartbeats)
    assert first_beat == pytest.approx(1.80, abs=0.01)
    # BOOT (system_status 1) until "ArduPilot Ready" at 3.23: nothing is asked of the vehicle
    booting = [(t, s) for t, s, _ in arducopter if t < 3.23]
    assert booting and all(s.action == WAIT for _, s in booting)
    assert any("initialisation" in s.why for _, s in booting)
    # GUIDED asked for when the boot ends (STABILIZE at 3.23), and again when the RC switch resets it (3.43)
    mode_requests = [t for t, s, _ in arducopter if s.action == SET_MODE]
    assert mode_requests == [pytest.approx(3.23, abs=0.01), pytest.approx(3.43, abs=0.01)]
    assert all(s.mode == "GUIDED" for _, s, _ in arducopter if s.action == SET_MODE)


def test_arducopter_arms_once_the_ekf_has_a_position_and_never_outside_guided(arducopter) -> None:
    arms = [(t, state) for t, s, state in arducopter if s.action == ARM]
    # pre-arm bit and EKF flags 167 -> 831 at 42.43, right after "EKF3 IMU0 is using GPS" (42.20);
    # the capture's ground station (arming every 3 s) got its first ACCEPTED at 42.72
    assert [t for t, _ in arms] == [pytest.approx(42.43, abs=0.02)]
    for _t, state in arms:
        assert state.mode == "GUIDED" and state.armed is False
    # every ARM decision in between would have been refused by the vehicle: none was taken
    waits = [s.why for t, s, _ in arducopter if s.action == WAIT and 6.0 < t < 42.4]
    assert waits and all("pre-arm checks" in w and "position (EKF)" in w for w in waits)
    assert any("Need Position Estimate" in w for w in waits)   # the vehicle's own words, shown to the user


def test_arducopter_readiness_by_signal(arducopter) -> None:
    at = {t: state for t, _s, state in arducopter}
    before = max(t for t in at if t < 42.4)
    after = min(t for t in at if t >= 42.43)
    assert at[before].ekf_flags == 167 and not assess(at[before]).ready
    assert at[after].ekf_flags == 831 and assess(at[after]).ready
    assert at[after].sensors_health & mavutil.mavlink.MAV_SYS_STATUS_PREARM_CHECK


def test_px4_waits_for_its_preflight_checks_then_arms_in_hold(px4) -> None:
    steps = [(t, s) for t, s, _ in px4]
    assert all(s.action == WAIT for t, s in steps if t < 2.40)
    assert any("pre-arm checks" in s.why and "heading estimate not stable" in s.why for _, s in steps)
    arms = [(t, state) for t, s, state in px4 if s.action == ARM]
    # HEARTBEAT system_status 0 -> 3 at 2.40 (PX4.md: ready about 4 s after the process started)
    assert arms and arms[0][0] == pytest.approx(2.40, abs=0.02)
    assert all(state.mode == "LOITER" and not state.armed for _, state in arms)


def test_px4_mode_changed_behind_our_back_is_asked_back(tlogs_dir: Path) -> None:
    """The capture's GCS put PX4 in OFFBOARD (4.42) and MISSION (6.44) disarmed: Hold is asked for again."""
    steps = decisions(tlogs_dir / PX4_LOG, until_s=9.0)
    requests = [(t, s.mode) for t, s, _ in steps if s.action == SET_MODE]
    assert requests == [(pytest.approx(4.42, abs=0.02), "LOITER"), (pytest.approx(6.44, abs=0.02), "LOITER")]
    assert not [t for t, s, state in steps if s.action == ARM and state.mode != "LOITER"]


def test_armed_in_the_wrong_mode_is_corrected(tlogs_dir: Path) -> None:
    """PX4 armed in TAKEOFF (the capture's 12.52): the step is the arming mode, never READY."""
    steps = decisions(tlogs_dir / PX4_LOG, until_s=13.0)
    last_t, last, state = steps[-1]
    assert state.armed and state.mode == "TAKEOFF"
    assert last.action == SET_MODE and last.mode == "LOITER"
    assert READY not in [s.action for _, s, st in steps if st.mode != "LOITER"]
