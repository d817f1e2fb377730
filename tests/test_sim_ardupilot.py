"""gcs-sim as ArduCopter, seen from a pymavlink ground station on loopback UDP (lockstep, real JSBSim physics).

Each expectation comes from ../shared/tlogs/ARDUCOPTER.md (measured on real ArduCopter SITL).
"""

from __future__ import annotations

import math

import pytest
from tools.flight.lockstep_gcs import VELOCITY_ONLY, VELOCITY_YAW, LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

ACCEPTED, FAILED = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_FAILED
GUIDED, LAND, STABILIZE = 4, 9, 0
NAN = math.nan


def _heading_deg(gcs: LockstepGcs) -> float:
    return gcs.last("GLOBAL_POSITION_INT").hdg / 100.0


def _angle_diff_deg(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


@pytest.fixture
def gcs():
    g = LockstepGcs("ardupilot", room="open_field")
    yield g
    g.close()


def _airborne(g: LockstepGcs, alt_m: float = 2.0) -> None:
    g.boot()
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == [ACCEPTED]
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [ACCEPTED]
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, alt_m) == [ACCEPTED]
    g.run(9.0)


def test_guided_flight_takeoff_forward_turn_land(gcs: LockstepGcs) -> None:
    g = gcs
    _airborne(g)
    pos = g.last("LOCAL_POSITION_NED")
    assert -pos.z == pytest.approx(2.0, abs=0.15)
    assert g.last("HEARTBEAT").custom_mode == GUIDED and g.last("HEARTBEAT").base_mode == 217

    start_n = pos.x
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW, vx=1.0))
    g.run(2.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW))
    pos = g.last("LOCAL_POSITION_NED")
    assert pos.x - start_n == pytest.approx(3.0, abs=0.6), "1 m/s for 3 s, then a stop"
    assert abs(pos.y) < 0.2 and -pos.z == pytest.approx(2.0, abs=0.2)

    g.run(4.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, yaw=math.radians(90)))
    assert abs(_angle_diff_deg(_heading_deg(g), 90.0)) < 4.0
    assert math.degrees(g.last("ATTITUDE").yaw) == pytest.approx(90.0, abs=4.0)

    assert g.command(M.MAV_CMD_NAV_LAND, 0, 0, 0, NAN, NAN, NAN, NAN) == [ACCEPTED]
    assert g.last("HEARTBEAT").custom_mode == LAND   # the extra HEARTBEAT on a mode change
    g.run(9.0)
    assert -g.last("LOCAL_POSITION_NED").z < 0.1
    assert not g.last("HEARTBEAT").base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert g.last("HEARTBEAT").custom_mode == LAND, "ArduCopter stays in LAND after disarming"
    assert "Disarming motors" in g.texts() and any(t.startswith("SIM Hit ground") for t in g.texts())


def test_refusals_are_failed_like_arducopter(gcs: LockstepGcs) -> None:
    g = gcs
    g.run(0.2)
    assert g.last("HEARTBEAT").system_status == M.MAV_STATE_BOOT
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [FAILED]
    assert "Arm: System not initialised" in g.texts()
    g.boot()
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2) == [FAILED], "disarmed in STABILIZE"
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 99) == [FAILED]
    assert "No such mode 99" in g.texts()
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == [ACCEPTED]
    n_texts = len(g.texts())
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2) == [FAILED], "disarmed in GUIDED"
    assert len(g.texts()) == n_texts, "takeoff refusals come without a text"
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, LAND) == [ACCEPTED]
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [FAILED]
    assert "Arm: Mode not armable" in g.texts()
    assert g.command(M.MAV_CMD_CONDITION_YAW + 10_000) == [M.MAV_RESULT_UNSUPPORTED]


def test_set_mode_message_gets_no_ack_but_an_immediate_heartbeat(gcs: LockstepGcs) -> None:
    g = gcs
    g.boot()
    start = len(g.received)
    g.send(g.mav.set_mode_encode(1, 1, GUIDED))
    g.run(0.05)   # well before the next 1 Hz beat
    new = [m for _t, m in g.received[start:]]
    assert not [m for m in new if m.get_type() == "COMMAND_ACK"]
    beats = [m for m in new if m.get_type() == "HEARTBEAT"]
    assert beats and beats[-1].custom_mode == GUIDED and beats[-1].base_mode == 89


def test_extended_sys_state_only_on_request(gcs: LockstepGcs) -> None:
    g = gcs
    g.run(3.0)
    assert not g.of_type("EXTENDED_SYS_STATE")
    assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 1_000_000) == [ACCEPTED]
    g.run(3.0)
    states = g.of_type("EXTENDED_SYS_STATE")
    assert 2 <= len(states) <= 4 and states[-1][1].landed_state == M.MAV_LANDED_STATE_ON_GROUND
    assert states[-1][1].vtol_state == M.MAV_VTOL_STATE_MC


def test_setpoint_timeout_holds_after_three_seconds(gcs: LockstepGcs) -> None:
    g = gcs
    _airborne(g)
    g.run(2.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=1.0))
    stop_s = g.t_s
    g.run(2.5)
    assert g.last("LOCAL_POSITION_NED").vx > 0.9, "keeps the last velocity until GUID_TIMEOUT"
    g.run(3.0)
    assert abs(g.last("LOCAL_POSITION_NED").vx) < 0.1, "then brakes and holds"
    assert g.last("HEARTBEAT").custom_mode == GUIDED, "no mode change"
    assert g.t_s - stop_s > 5.0


def test_nose_turns_toward_travel_when_yaw_is_ignored(gcs: LockstepGcs) -> None:
    g = gcs
    _airborne(g)
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, vy=-1.0))   # west
    assert abs(_angle_diff_deg(_heading_deg(g), 270.0)) < 5.0
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, vx=-1.0))   # south
    assert abs(_angle_diff_deg(_heading_deg(g), 180.0)) < 5.0


def test_body_frame_yaw_is_relative_to_current_heading(gcs: LockstepGcs) -> None:
    g = gcs
    _airborne(g)
    g.run(4.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, yaw=math.radians(90)))
    north_before = g.last("LOCAL_POSITION_NED").x
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW, vx=1.0, yaw=0.0))
    assert abs(_angle_diff_deg(_heading_deg(g), 90.0)) < 5.0, "body yaw 0 keeps the heading"
    pos = g.last("LOCAL_POSITION_NED")
    assert pos.y > 2.0 and abs(pos.x - north_before) < 0.3, "forward is east after the turn"


def test_velocity_setpoint_outside_guided_is_ignored(gcs: LockstepGcs) -> None:
    g = gcs
    _airborne(g)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 5) == [ACCEPTED]   # LOITER
    g.run(2.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=2.0))
    assert abs(g.last("LOCAL_POSITION_NED").vx) < 0.1


def test_fence_stops_before_the_living_room_wall() -> None:
    g = LockstepGcs("ardupilot", room="living_room")
    try:
        g.boot()
        g.server.params.set("FENCE_ENABLE", 1)
        _airborne(g, 1.2)
        g.run(6.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=1.0))
        north = g.last("LOCAL_POSITION_NED").x
        assert 2.0 < north < 2.75, "room wall at +3 m north, fence margin 0.5 m"
        assert not any("north wall" in t for t in g.texts())
    finally:
        g.close()
