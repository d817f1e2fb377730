"""The link and the mapper against the real bundled simulator (gcs-sim) on loopback: outcomes in flight.

The simulator runs as its own process (``python -m sim_bridge.cli``), as a vehicle would: the link
never imports it. Real time, because the link's timers (10 Hz stream, 2 s link loss) are wall-clock.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import pytest
from pymavlink import mavutil

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.link.state import VehicleState
from gcs_voice.settings import load_settings
from gcs_voice.session.sim_process import BundledSim

pytestmark = pytest.mark.slow


def _fly_until(link: VehicleLink, mapper: ActionMapper, action: str, done: Callable[[VehicleState], bool],
               what: str, timeout_s: float = 20.0) -> VehicleState:
    """Apply ``action`` and wait for its outcome on the wire (not for a wall-clock guess); fail if it never comes."""
    mapper.apply(action, link.state)
    reached = link.wait_for(done, timeout_s)
    assert reached is not None, f"{action}: {what} not seen within {timeout_s:.0f} s; state {link.state}"
    return reached


def _stopped(state: VehicleState) -> bool:
    return math.hypot(state.north_m_s or 0.0, state.east_m_s or 0.0) < 0.1 and abs(state.down_m_s or 0.0) < 0.1


def _along_m(start: VehicleState, now: VehicleState, heading_deg: float) -> tuple[float, float]:
    """(forward, right) displacement from ``start`` for a vehicle facing ``heading_deg``."""
    dn, de = now.north_m - start.north_m, now.east_m - start.east_m
    h = math.radians(heading_deg)
    return dn * math.cos(h) + de * math.sin(h), -dn * math.sin(h) + de * math.cos(h)


def _heading_error_deg(heading_deg: float, target_deg: float) -> float:
    return abs((heading_deg - target_deg + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_fly_the_nine_actions_in_the_simulator(autopilot: str, tmp_path: Path) -> None:
    settings = load_settings()
    mapper = ActionMapper(settings)
    with BundledSim(autopilot, room="open_field", extra_args=["--duration", "300"]) as sim, \
            VehicleLink(sim.connection, settings, tlog_path=tmp_path / "flight.tlog") as link:
        state = link.connect(timeout_s=20)
        assert state.autopilot == ("PX4" if autopilot == "px4" else "ArduPilot")
        result = link.takeoff(1.5, source=mapper.setpoint)
        assert result.ok, result
        mapper.reset_heading(link.state)
        link.start_stream(mapper.setpoint)
        assert link.state.mode == ("OFFBOARD" if autopilot == "px4" else "GUIDED")
        assert 1.2 < link.state.height_m < 1.9
        heading0 = mapper.yaw_target_deg

        def facing(target_deg: float):
            return lambda s: s.heading_deg is not None and _heading_error_deg(s.heading_deg, target_deg) < 5.0

        start = link.state
        _fly_until(link, mapper, "go_forward", lambda s: _along_m(start, s, heading0)[0] > 1.0, "1 m forward")
        heard = link.state
        # stop holds where it was heard: the overshoot is flown back, to rest within 0.2 m of that point
        moved = _fly_until(link, mapper, "stop", lambda s: _stopped(s) and math.hypot(
            s.north_m - heard.north_m, s.east_m - heard.east_m) < 0.2, "at rest within 0.2 m of where stop was heard")
        # and the leg held its height
        assert abs(moved.height_m - start.height_m) < 0.2
        forward_m, sideways_m = _along_m(start, moved, heading0)
        assert 0.8 < forward_m < 2.5 and abs(sideways_m) < 0.3

        _fly_until(link, mapper, "turn_right", facing(heading0 + 90.0), "facing +90 deg")
        _fly_until(link, mapper, "turn_right", facing(heading0 + 180.0), "facing +180 deg")
        assert mapper.yaw_target_deg == pytest.approx((heading0 + 180.0) % 360.0)

        start = link.state
        # facing back: right is the original left
        _fly_until(link, mapper, "go_right", lambda s: -_along_m(start, s, heading0)[1] > 0.7, "0.7 m to the left")
        moved = _fly_until(link, mapper, "stop", _stopped, "at rest")
        assert -_along_m(start, moved, heading0)[1] > 0.6, "go_right after a 180 deg turn moves toward the original left"
        assert _heading_error_deg(moved.heading_deg, heading0 + 180.0) < 8.0  # heading kept while moving

        before_up = link.state.height_m
        _fly_until(link, mapper, "up", lambda s: s.height_m > before_up + 0.3, "0.3 m higher")
        _fly_until(link, mapper, "turn_left", facing(heading0 + 90.0), "facing +90 deg")
        _fly_until(link, mapper, "turn_left", facing(heading0), "facing the start heading")
        assert mapper.yaw_target_deg == pytest.approx(heading0 % 360.0)
        start = link.state
        _fly_until(link, mapper, "go_back", lambda s: _along_m(start, s, heading0)[0] < -0.5, "0.5 m back")
        moved = _fly_until(link, mapper, "stop", _stopped, "at rest")
        assert _along_m(start, moved, heading0)[0] < -0.4

        _fly_until(link, mapper, "down", lambda s: mapper.action == "stop", "down stopped at the floor")
        settled = link.wait_for(lambda s: _stopped(s) and 0.3 < s.height_m < 0.75, 10.0)
        assert settled is not None, f"not at rest 0.3-0.75 m up after down: {link.state}"
        assert "floor" in mapper.events[-1]

        landed = link.land()
        assert landed.ok, landed
        assert link.state.mode == "LAND" and not link.streaming
        touchdown = link.wait_for(lambda s: s.landed_state == "ON_GROUND" or (s.height_m or 0.0) < 0.1, 15.0)
        assert touchdown is not None, "never reached the ground after LAND"
        track = []
        disarmed = link.wait_for(lambda s: track.append((s.mode, s.landed_state, round(s.height_m or 0, 2))) or
                                 s.armed is False, 20.0)
        assert disarmed is not None, f"not disarmed 20 s after LAND; (mode, landed, height): {track[::10]}"
    # the tlog holds our setpoints, all in the one encoding
    log = mavutil.mavlink_connection(str(tmp_path / "flight.tlog"))
    encodings, setpoint_t, mode_requests = set(), [], []
    while (msg := log.recv_match(type=["SET_POSITION_TARGET_LOCAL_NED", "COMMAND_LONG"])) is not None:
        if msg.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
            encodings.add((msg.coordinate_frame, msg.type_mask))
            setpoint_t.append(msg._timestamp)
        elif msg.command == 176:
            mode_requests.append((msg._timestamp, msg.param2, msg.param3))
    # docs/link.md: stop/turn carry position + velocity + yaw (2496) on both; PX4's horizontal legs hold their
    # height (2499) and vertical ones their point (2500); ArduCopter drops a partial position, so 2503
    expected = {(1, 2496), (1, 2499), (1, 2500)} if autopilot == "px4" else {(1, 2496), (1, 2503)}
    assert encodings == expected
    if autopilot == "px4":  # OFFBOARD asked for only after >= 0.5 s of setpoints at > 2 Hz
        offboard_t = [t for t, main, sub in mode_requests if (main, sub) == (6, 0)]
        assert offboard_t
        before = [t for t in setpoint_t if t < offboard_t[0]]
        assert len(before) >= 5 and offboard_t[0] - before[0] >= 0.5
        assert max(b - a for a, b in zip(before, before[1:])) < 0.5
        assert all(main != 4 or sub != 0 for _, main, sub in mode_requests)  # never ArduCopter's GUIDED number
    else:
        assert {(main, sub) for _, main, sub in mode_requests} == {(4.0, 0.0)}  # GUIDED only


def test_link_loss_with_the_simulator_paused(tmp_path: Path) -> None:
    """SIGSTOP the simulator: link lost after 2 s, nothing sent; SIGCONT: the first setpoint is a stop."""
    settings = load_settings()
    mapper = ActionMapper(settings)
    tlog = tmp_path / "loss.tlog"
    with BundledSim(room="open_field", extra_args=["--duration", "300"]) as sim, \
            VehicleLink(sim.connection, settings, tlog_path=tlog) as link:
        link.connect(timeout_s=20)
        assert link.takeoff(1.5, source=mapper.setpoint).ok
        mapper.reset_heading(link.state)
        link.start_stream(mapper.setpoint)
        _fly_until(link, mapper, "go_forward", lambda s: math.hypot(s.north_m_s or 0.0, s.east_m_s or 0.0) > 0.3,
                   "moving")
        sim.pause()
        paused_wall = time.time()
        assert link.wait_for(lambda s: not s.link_ok, 3.5) is not None
        lost_wall = time.time()
        assert 1.8 < lost_wall - paused_wall < 2.8
        time.sleep(1.0)       # a silence to check: nothing may be sent in it
        sim.resume()
        assert link.wait_for(lambda s: s.link_ok, 5.0) is not None
        sent_at_return = link.setpoints_sent
        assert link.wait_for(lambda s: link.setpoints_sent >= sent_at_return + 3, 5.0) is not None
        assert mapper.action == "stop"  # the mapper also turned the lost action into a stop
        assert link.land().ok
    log = mavutil.mavlink_connection(str(tlog))
    sent = []
    while (msg := log.recv_match(type="SET_POSITION_TARGET_LOCAL_NED")) is not None:
        sent.append((msg._timestamp, msg))
    during = [t for t, _ in sent if lost_wall + 0.15 < t < lost_wall + 1.0]
    assert not during, "setpoints were sent while the link was lost"
    after = [m for t, m in sent if t > lost_wall + 1.0]
    assert after and (after[0].vx, after[0].vy, after[0].vz) == (0.0, 0.0, 0.0)
    before = [m for t, m in sent if t < paused_wall]
    assert math.hypot(before[-1].vx, before[-1].vy) == pytest.approx(settings.horizontal_speed_m_s)


def test_tcp_client_to_the_simulator(tmp_path: Path) -> None:
    """``--connect tcp:HOST:PORT`` (like SITL's 5760): state and telemetry arrive, commands are answered."""
    with BundledSim(room="open_field", tcp=True, udp=False) as sim:
        assert sim.connection == f"tcp:127.0.0.1:{sim.tcp_port}"
        with VehicleLink(sim.connection) as link:
            state = link.connect(timeout_s=10)
            assert state.autopilot == "ArduPilot"
            assert link.wait_for(lambda s: s.heading_deg is not None and s.height_m is not None, 3.0) is not None
            assert link.set_mode("GUIDED").ok
