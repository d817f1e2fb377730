"""Setpoint encoding: named type_mask bits, LOCAL_NED frame, body->NED rotation by the heading target, yaw always."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.setpoints import SETPOINT_FRAME, TYPE_MASK_VELOCITY_YAW, Setpoint, setpoint_fields, wrap_deg


def _decode(setpoint: Setpoint):
    """Pack and parse as on the wire, so what we check is what a vehicle reads."""
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    msg = mav.set_position_target_local_ned_encode(*setpoint_fields(setpoint, 1, 1, 1234))
    return mavlink.MAVLink(None).parse_char(msg.pack(mav))


def test_type_mask_uses_velocity_and_yaw_only() -> None:
    assert TYPE_MASK_VELOCITY_YAW == 2503  # what both SITLs accepted as "velocity + yaw"
    used = ~TYPE_MASK_VELOCITY_YAW
    for bit in ("VX", "VY", "VZ", "YAW"):
        assert used & getattr(mavlink, f"POSITION_TARGET_TYPEMASK_{bit}_IGNORE")
    for bit in ("X", "Y", "Z", "AX", "AY", "AZ", "YAW_RATE"):
        assert TYPE_MASK_VELOCITY_YAW & getattr(mavlink, f"POSITION_TARGET_TYPEMASK_{bit}_IGNORE")
    assert not TYPE_MASK_VELOCITY_YAW & mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET
    assert SETPOINT_FRAME == mavlink.MAV_FRAME_LOCAL_NED == 1


@pytest.mark.parametrize(
    ("heading_deg", "forward", "right", "north", "east"),
    [
        (0, 1, 0, 1, 0), (90, 1, 0, 0, 1), (180, 1, 0, -1, 0), (270, 1, 0, 0, -1),
        (0, 0, 1, 0, 1), (90, 0, 1, -1, 0), (180, 0, 1, 0, -1), (270, 0, 1, 1, 0),
        (45, 1, 0, math.sqrt(0.5), math.sqrt(0.5)), (-90, 1, 0, 0, -1), (450, 0, -1, 1, 0),
    ],
)
def test_body_velocity_rotated_by_heading_target(heading_deg, forward, right, north, east) -> None:
    msg = _decode(Setpoint(forward, right, 0.3, heading_deg))
    assert (msg.vx, msg.vy, msg.vz) == pytest.approx((north, east, 0.3), abs=1e-6)
    assert msg.coordinate_frame == 1 and msg.type_mask == 2503
    assert (msg.target_system, msg.target_component) == (1, 1)


@pytest.mark.parametrize(("yaw_deg", "yaw_rad"), [(0, 0.0), (90, math.pi / 2), (180, math.pi), (270, -math.pi / 2),
                                                  (-90, -math.pi / 2), (360, 0.0), (725, math.radians(5))])
def test_yaw_is_absolute_and_wrapped(yaw_deg, yaw_rad) -> None:
    assert _decode(Setpoint.stop(yaw_deg)).yaw == pytest.approx(yaw_rad, abs=1e-6)


def test_stop_keeps_heading_and_nan_is_refused() -> None:
    stop = Setpoint.stop(123.0)
    assert stop.is_stop and stop.yaw_deg == 123.0 and stop.ned_m_s() == (0.0, 0.0, 0.0)
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError):
            Setpoint(bad, 0, 0, 0)
        with pytest.raises(ValueError):
            Setpoint(0, 0, 0, bad)
    assert wrap_deg(-1e-20) == 0.0 and wrap_deg(-90) == 270.0 and wrap_deg(720.5) == pytest.approx(0.5)
    assert math.copysign(1.0, wrap_deg(-0.0)) == 1.0


# (setpoint, type_mask for ArduCopter, for PX4): the table in docs/link.md
HOLD_ALL = Setpoint(0.0, 0.0, 0.0, 90.0, 1.0, 2.0, -1.5)
HOLD_HEIGHT = Setpoint(0.5, 0.0, 0.0, 90.0, None, None, -1.5)
HOLD_POINT = Setpoint(0.0, 0.0, -0.3, 90.0, 1.0, 2.0, None)
NO_HOLD = Setpoint(0.5, 0.0, 0.0, 90.0)


@pytest.mark.parametrize("setpoint, arducopter, px4", [
    (HOLD_ALL, 2496, 2496), (HOLD_HEIGHT, 2503, 2499), (HOLD_POINT, 2503, 2500), (NO_HOLD, 2503, 2503)])
def test_type_mask_per_autopilot(setpoint: Setpoint, arducopter: int, px4: int) -> None:
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    for separately, mask in ((False, arducopter), (True, px4)):
        msg = mav.set_position_target_local_ned_encode(*setpoint_fields(setpoint, 1, 1, 0, separately))
        msg = mavlink.MAVLink(None).parse_char(msg.pack(mav))
        assert msg.type_mask == mask
        # every field that is used carries the value; ignored positions are zero
        used = [not mask & bit for bit in (1, 2, 4)]
        for value, hold, is_used in zip((msg.x, msg.y, msg.z), (setpoint.hold_north_m, setpoint.hold_east_m,
                                                                 setpoint.hold_down_m), used):
            assert value == (pytest.approx(hold) if is_used else 0.0)
        assert not mask & (8 | 16 | 32)   # velocity always used (zero for a stop): PX4 needs all three
        assert msg.vx == pytest.approx(setpoint.ned_m_s()[0], abs=1e-6)


def test_a_hold_names_both_horizontal_axes() -> None:
    with pytest.raises(ValueError):
        Setpoint(0.0, 0.0, 0.0, 0.0, 1.0, None, None)
    with pytest.raises(ValueError):
        Setpoint(0.0, 0.0, 0.0, 0.0, None, None, math.nan)
