"""Vehicle behaviours and setpoint frames without sockets: the real Multicopter (JSBSim) underneath."""

from __future__ import annotations

import math

import pytest

from pymavlink.dialects.v20 import ardupilotmega as M

from sim_bridge.autopilot.ardupilot import ArduCopter
from sim_bridge.autopilot.px4 import PX4
from sim_bridge.multicopter import Multicopter
from sim_bridge.setpoints import SetpointRejected, decode_setpoint
from sim_bridge.vehicle import Behaviour, Vehicle, VehicleEvent
from sim_bridge.world import load_room

MAV = M.MAVLink(None, 255, 190)


def _msg(frame: int, mask: int, vx=0.0, vy=0.0, vz=0.0, yaw=0.0, x=0.0, y=0.0, z=0.0):
    return MAV.set_position_target_local_ned_encode(0, 1, 1, frame, mask, x, y, z, vx, vy, vz, 0, 0, 0, yaw, 0)


def test_body_frames_rotate_by_heading_and_ardupilot_yaw_is_relative() -> None:
    east = math.radians(90)
    sp = decode_setpoint(_msg(M.MAV_FRAME_BODY_OFFSET_NED, 2503, vx=1.0, yaw=0.1), ArduCopter.frame_rules,
                         east, (0, 0, -1), 0.0, True)
    assert sp.vel_ned_m_s[0] == pytest.approx(0, abs=1e-9) and sp.vel_ned_m_s[1] == pytest.approx(1.0)
    assert sp.yaw_rad == pytest.approx(east + 0.1) and not sp.auto_yaw
    sp = decode_setpoint(_msg(M.MAV_FRAME_BODY_NED, 2503, vx=1.0, yaw=0.1), PX4.frame_rules, east, (0, 0, -1), 0.0, False)
    assert sp.yaw_rad == pytest.approx(0.1), "PX4: absolute heading"
    sp = decode_setpoint(_msg(M.MAV_FRAME_LOCAL_NED, 3527, vy=-1.0), ArduCopter.frame_rules, 0.0, (0, 0, -1), 0.0, True)
    assert sp.auto_yaw and sp.yaw_rad is None and sp.yaw_rate_rad_s is None


def test_offset_frames_add_the_current_position_and_masks_follow_each_autopilot() -> None:
    sp = decode_setpoint(_msg(M.MAV_FRAME_LOCAL_OFFSET_NED, 3576, x=1.0, y=2.0, z=-0.5), ArduCopter.frame_rules,
                         0.0, (5.0, 5.0, -1.0), 0.0, True)
    assert sp.pos_ned_m == pytest.approx((6.0, 7.0, -1.5)) and sp.vel_ned_m_s == (0.0, 0.0, 0.0)
    # ArduCopter: one velocity ignore bit drops the velocity group; PX4 calls a partial mask invalid
    with pytest.raises(SetpointRejected) as ardu:
        decode_setpoint(_msg(M.MAV_FRAME_LOCAL_NED, 3575, vx=1.0), ArduCopter.frame_rules, 0.0, (0, 0, 0), 0.0, True)
    assert ardu.value.reason == "invalid"
    with pytest.raises(SetpointRejected) as px4:
        decode_setpoint(_msg(M.MAV_FRAME_BODY_NED, 3575, vx=1.0), PX4.frame_rules, 0.0, (0, 0, 0), 0.0, False)
    assert px4.value.reason == "invalid"
    # PX4 mixes a z position into a velocity setpoint (LOCAL_NED, per-axis bits)
    sp = decode_setpoint(_msg(M.MAV_FRAME_LOCAL_NED, 3520 | 3, vx=1.0, z=-2.0), PX4.frame_rules, 0.0, (0, 0, -1), 0.0,
                         False)
    assert sp.pos_ned_m == (None, None, -2.0) and sp.vel_ned_m_s == (1.0, 0.0, 0.0)
    for frame, rules in ((M.MAV_FRAME_BODY_OFFSET_NED, PX4.frame_rules), (M.MAV_FRAME_GLOBAL, ArduCopter.frame_rules)):
        with pytest.raises(SetpointRejected) as refused:
            decode_setpoint(_msg(frame, 3527, vx=1.0), rules, 0.0, (0, 0, 0), 0.0, False)
        assert refused.value.reason == "frame"
    with pytest.raises(SetpointRejected) as nan:
        decode_setpoint(_msg(M.MAV_FRAME_LOCAL_NED, 3527, vx=math.nan), PX4.frame_rules, 0.0, (0, 0, 0), 0.0, False)
    assert nan.value.reason == "nan"


def _run(vehicle: Vehicle, seconds: float) -> list[VehicleEvent]:
    events = []
    for _ in range(int(round(seconds / 0.01))):
        events += vehicle.step(0.01)
    return events


@pytest.fixture(scope="module")
def room():
    return load_room("living_room")


def test_takeoff_waits_for_spool_up_then_climbs_and_holds(room) -> None:
    vehicle = Vehicle(Multicopter(room))
    vehicle.limits.takeoff_delay_s = 2.0
    vehicle.arm()
    vehicle.takeoff(1.5)
    _run(vehicle, 1.8)
    assert vehicle.altitude_m < 0.05 and vehicle.landed_state() == M.MAV_LANDED_STATE_TAKEOFF
    events = _run(vehicle, 5.0)
    assert VehicleEvent.LIFTOFF in events and VehicleEvent.TAKEOFF_DONE in events
    assert vehicle.behaviour is Behaviour.HOLD and vehicle.altitude_m == pytest.approx(1.5, abs=0.1)
    vehicle.land()
    events = _run(vehicle, 6.0)
    assert VehicleEvent.TOUCHDOWN in events and VehicleEvent.DISARMED_LANDED in events and not vehicle.armed


def test_ground_setpoints_ardupilot_sits_px4_offboard_climbs(room) -> None:
    from sim_bridge.setpoints import Setpoint

    climb = Setpoint((0.0, 0.0, -0.5), (None, None, None), None, None, False, received_s=0.0)
    sitting = Vehicle(Multicopter(room))
    sitting.arm()
    sitting.follow(climb)
    _run(sitting, 2.0)
    assert sitting.altitude_m < 0.05, "ArduCopter GUIDED: a velocity command does not take off"
    flying = Vehicle(Multicopter(room))
    flying.limits.setpoint_timeout_s = None
    flying.arm()
    flying.follow(climb, from_ground=True)
    _run(flying, 2.5)
    assert flying.altitude_m > 0.5, "PX4 offboard: it does"


def test_rtl_returns_home_within_the_ceiling_and_lands(room) -> None:
    vehicle = Vehicle(Multicopter(room), ceiling_m=2.2)
    vehicle.limits.takeoff_delay_s = 0.5
    vehicle.arm()
    vehicle.takeoff(1.0)
    _run(vehicle, 4.0)
    from sim_bridge.setpoints import Setpoint

    vehicle.follow(Setpoint((0.0, 1.0, 0.0), (None, None, None), 0.0, None, False, received_s=vehicle.time_s))
    _run(vehicle, 1.5)
    vehicle.return_to_launch()
    assert vehicle.rtl_alt_m == pytest.approx(2.0), "RTL_ALT 15 m capped 0.2 m under the ceiling"
    events = _run(vehicle, 20.0)
    assert VehicleEvent.RTL_LANDING in events and not vehicle.armed
    assert math.hypot(*vehicle.state.pos_ned_m[:2]) < 0.3


def test_land_descends_where_it_stopped_not_toward_an_old_hold_point(room) -> None:
    from sim_bridge.setpoints import Setpoint

    vehicle = Vehicle(Multicopter(load_room("open_field")))
    vehicle.limits.takeoff_delay_s = 0.5
    vehicle.arm()
    vehicle.takeoff(1.5)
    _run(vehicle, 5.0)                      # holding over the takeoff spot
    vehicle.follow(Setpoint((1.0, 0.0, 0.0), (None, None, None), 0.0, None, False, received_s=vehicle.time_s))
    _run(vehicle, 3.0)
    vehicle.land()
    start = vehicle.state.pos_ned_m.copy()
    tilt_deg = 0.0
    for _ in range(600):
        vehicle.step(0.01)
        if vehicle.altitude_m < 0.3:        # tilt at touchdown (braking from 1 m/s leans it more, higher up)
            tilt_deg = max(tilt_deg, math.degrees(max(abs(vehicle.state.roll_rad), abs(vehicle.state.pitch_rad))))
    drift_m = math.hypot(*(vehicle.state.pos_ned_m[:2] - start[:2]))
    assert drift_m < 0.8, "brakes, then lands below (a bug flew back to the takeoff spot, 3 m away)"
    assert tilt_deg < 5.0 and not vehicle.armed


@pytest.mark.parametrize("mask, arducopter_pos, px4_pos", [
    (2496, (1.0, 2.0, -1.5), (1.0, 2.0, -1.5)),      # stop / turn: position + velocity + yaw, both
    (2499, (None, None, None), (None, None, -1.5)),  # horizontal motion holding its height: PX4 only
    (2500, (None, None, None), (1.0, 2.0, None)),    # vertical motion holding its point: PX4 only
])
def test_position_targets_with_velocity_per_personality(mask: int, arducopter_pos, px4_pos) -> None:
    """gcs-voice's holds (docs/link.md): ArduCopter's GUIDED takes pos+vel but drops the whole position when
    any x/y/z ignore bit is set; PX4 offboard honours each axis on its own."""
    msg = _msg(M.MAV_FRAME_LOCAL_NED, mask, vx=0.5, yaw=0.3, x=1.0, y=2.0, z=-1.5)
    for rules, expected in ((ArduCopter.frame_rules, arducopter_pos), (PX4.frame_rules, px4_pos)):
        sp = decode_setpoint(msg, rules, 0.0, (0.0, 0.0, -1.0), 0.0, True)
        assert sp.pos_ned_m == expected
        assert sp.vel_ned_m_s == (0.5, 0.0, 0.0) and sp.yaw_rad == pytest.approx(0.3)
