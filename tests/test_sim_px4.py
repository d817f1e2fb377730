"""gcs-sim --autopilot px4, seen from a pymavlink ground station (lockstep, real JSBSim physics).

Expectations from ../shared/tlogs/PX4.md (PX4 SITL with SIH, measured).
"""

from __future__ import annotations

import math
import struct

import pytest
from tools.flight.lockstep_gcs import VELOCITY_ONLY, VELOCITY_YAW, LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

ACCEPTED, TEMP_REJECTED = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_TEMPORARILY_REJECTED
OFFBOARD, HOLD, MISSION, RTL, TAKEOFF = 393216, 50593792, 67371008, 84148224, 33816576
NAN = math.nan


@pytest.fixture
def gcs():
    g = LockstepGcs("px4", room="open_field")
    yield g
    g.close()


def _texts(g: LockstepGcs) -> list[str]:
    """STATUSTEXT reassembled by id (PX4 chunks texts over 50 characters), trailing TAB kept."""
    out: list[str] = []
    open_ids: dict[int, int] = {}
    for _t, m in g.of_type("STATUSTEXT"):
        if m.id and m.id in open_ids:
            out[open_ids[m.id]] += m.text
        else:
            if m.id:
                open_ids[m.id] = len(out)
            out.append(m.text)
    return out


def _next_heartbeat(g: LockstepGcs, every=None):
    """PX4 sends no extra HEARTBEAT on a mode change: the next 1 Hz beat shows it."""
    return g.wait("HEARTBEAT", 1.1, every=every)


def _hold_airborne(g: LockstepGcs) -> None:
    g.boot()
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [ACCEPTED]
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, 488.0 + 3.0) == [ACCEPTED]
    g.run(8.0)
    assert g.last("HEARTBEAT").custom_mode == HOLD, "Takeoff ends in Hold"


def test_heartbeat_and_mode_numbers(gcs: LockstepGcs) -> None:
    g = gcs
    g.boot()
    hb = g.last("HEARTBEAT")
    assert (hb.autopilot, hb.type, hb.custom_mode, hb.base_mode) == (M.MAV_AUTOPILOT_PX4, 2, HOLD, 29)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 4, 0) == [ACCEPTED, ACCEPTED]
    assert _next_heartbeat(g).custom_mode == MISSION, "main 4 sub 0 is Mission"
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [TEMP_REJECTED]
    assert "Arming denied: Resolve system health failures first\t" in _texts(g)
    chunks = [m for _t, m in g.of_type("STATUSTEXT") if m.text.startswith("Arming denied")]
    assert chunks[0].id != 0 and chunks[0].chunk_seq == 0 and len(chunks[0].text) == 50
    assert g.command(M.MAV_CMD_CONDITION_YAW, 90, 30, 1, 1) == [M.MAV_RESULT_UNSUPPORTED]
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, NAN) == [ACCEPTED]
    assert _next_heartbeat(g).custom_mode == TAKEOFF and not g.server.vehicle.armed, "takeoff mode, not armed"


def test_offboard_needs_streaming_setpoints_and_double_ack(gcs: LockstepGcs) -> None:
    g = gcs
    _hold_airborne(g)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == [ACCEPTED, TEMP_REJECTED], "first ACK always ACCEPTED"
    assert "Switching to Offboard is currently not available\t" in _texts(g)
    assert _next_heartbeat(g).custom_mode == HOLD
    zero = lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY)   # noqa: E731
    g.run(1.5, every=zero)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == [ACCEPTED, ACCEPTED]
    hb = _next_heartbeat(g, every=zero)
    assert hb.custom_mode == OFFBOARD and hb.base_mode == 145

    start = g.last("LOCAL_POSITION_NED")
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_NED, VELOCITY_ONLY, vx=1.0))
    g.run(1.5, every=zero)
    pos = g.last("LOCAL_POSITION_NED")
    assert pos.x - start.x == pytest.approx(3.0, abs=0.6) and abs(pos.y - start.y) < 0.2
    assert abs(math.degrees(g.last("ATTITUDE").yaw)) < 3.0, "PX4 does not turn the nose toward the travel"
    g.run(4.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_NED, VELOCITY_YAW, yaw=math.radians(90)))
    assert math.degrees(g.last("ATTITUDE").yaw) == pytest.approx(90.0, abs=4.0), "body-frame yaw is absolute"
    target = g.last("POSITION_TARGET_LOCAL_NED")
    assert target.coordinate_frame == M.MAV_FRAME_LOCAL_NED and target.yaw == pytest.approx(math.radians(90), abs=0.01)


def test_unsupported_frames_are_refused_and_do_not_count_as_signal(gcs: LockstepGcs) -> None:
    g = gcs
    _hold_airborne(g)
    g.run(1.5, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_ONLY, vx=1.0))
    assert "SET_POSITION_TARGET_LOCAL_NED coordinate frame 9 unsupported\t" in _texts(g)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == [ACCEPTED, TEMP_REJECTED]
    g.setpoint(M.MAV_FRAME_BODY_NED, 3575, vx=1.0)   # vx only: PX4 calls it invalid
    g.run(0.1)
    assert "SET_POSITION_TARGET_LOCAL_NED invalid\t" in _texts(g)


@pytest.mark.parametrize("obl_rc_act, expected_mode", [(0, RTL), (5, HOLD)])
def test_offboard_loss_failsafe(gcs: LockstepGcs, obl_rc_act: int, expected_mode: int) -> None:
    g = gcs
    g.run(0.5)
    as_float = struct.unpack("<f", struct.pack("<i", obl_rc_act))[0]   # PX4 integers go bytewise
    g.send(g.mav.param_set_encode(1, 1, b"COM_OBL_RC_ACT", as_float, M.MAV_PARAM_TYPE_INT32))
    echo = g.wait("PARAM_VALUE", 0.5, cond=lambda m: m.param_id == "COM_OBL_RC_ACT")
    assert struct.unpack("<i", struct.pack("<f", echo.param_value))[0] == obl_rc_act
    _hold_airborne(g)
    zero = lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY)   # noqa: E731
    g.run(1.0, every=zero)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == [ACCEPTED, ACCEPTED]
    g.run(2.0, every=zero)
    stop_s = g.t_s - 0.1
    assert g.wait("STATUSTEXT", 3.0, cond=lambda m: m.text == "Failsafe activated\t") is not None
    assert 0.9 <= g.t_s - stop_s <= 1.2, "COM_OF_LOSS_T = 1 s"
    changed = g.wait("HEARTBEAT", 1.1)
    assert changed.custom_mode == expected_mode and changed.system_status == M.MAV_STATE_CRITICAL
