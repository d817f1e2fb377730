"""Setpoint encoding for ArduPilot and PX4: SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_LOCAL_NED, absolute yaw.

Why LOCAL_NED (see ../shared/tlogs/README.md): PX4 offboard accepts only MAV_FRAME_LOCAL_NED and
MAV_FRAME_BODY_NED; ArduCopter takes body-frame yaw as *relative* (re-sending +90 deg keeps turning)
and, when yaw is ignored, turns its nose toward the direction of travel. A LOCAL_NED velocity with an
absolute yaw target means the same thing to both.

Holds (``Setpoint.hold_*``) go out as position targets beside the velocity, as MAVSDK's offboard
examples and QGroundControl do. The type_mask per action and autopilot (table in docs/link.md):

- every axis held (stop, turn): position + velocity + yaw, 2496, on both;
- some axes held (a horizontal motion holds its height, a vertical one its point): PX4 honours each
  ignore bit on its own, so position on the held axes + velocity + yaw (2499 horizontal, 2500 vertical);
  ArduCopter drops the whole position when any of x/y/z is ignored (``GCS_MAVLINK_Copter``), so it gets
  velocity + yaw (2503) and holds its height itself in GUIDED velocity control;
- nothing held (position unknown): velocity + yaw, 2503.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.actions.setpoint import Setpoint, body_to_ned, wrap_deg

__all__ = ["Setpoint", "TYPE_MASK_VELOCITY_YAW", "TYPE_MASK_POSITION_VELOCITY_YAW", "SETPOINT_FRAME",
           "body_to_ned", "wrap_deg", "setpoint_fields", "type_mask_for"]

_POSITION_BITS = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE, mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE,
                  mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)
#: always ignored: accelerations and yaw rate (we give an absolute yaw)
_ALWAYS_IGNORED: int = (
    mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
#: Bits that *ignore* a field: position, acceleration and yaw rate are ignored; velocity and yaw are used.
TYPE_MASK_VELOCITY_YAW: int = _POSITION_BITS[0] | _POSITION_BITS[1] | _POSITION_BITS[2] | _ALWAYS_IGNORED
#: position + velocity (feed-forward) + yaw
TYPE_MASK_POSITION_VELOCITY_YAW: int = _ALWAYS_IGNORED
SETPOINT_FRAME: int = mavlink.MAV_FRAME_LOCAL_NED


def type_mask_for(setpoint: Setpoint, axes_separately: bool) -> int:
    """The type_mask for ``setpoint``: position on its held axes when the autopilot can take that.

    ``axes_separately``: the autopilot honours each position ignore bit on its own (PX4); False when one
    set bit drops the whole position (ArduCopter), so a partial hold is sent as velocity only.
    """
    held = setpoint.holds
    if all(held):
        return TYPE_MASK_POSITION_VELOCITY_YAW
    if any(held) and axes_separately:
        return _ALWAYS_IGNORED | sum(bit for bit, used in zip(_POSITION_BITS, held) if not used)
    return TYPE_MASK_VELOCITY_YAW


def setpoint_fields(setpoint: Setpoint, target_system: int, target_component: int, time_boot_ms: int = 0,
                    axes_separately: bool = False) -> tuple:
    """SET_POSITION_TARGET_LOCAL_NED fields, in ``set_position_target_local_ned_encode`` order.

    Yaw goes out in radians in (-pi, pi]; ignored positions, accelerations and yaw rate are zero.
    """
    north_m_s, east_m_s, down_m_s = setpoint.ned_m_s()
    yaw_rad = math.radians(wrap_deg(setpoint.yaw_deg))
    if yaw_rad > math.pi:
        yaw_rad -= 2.0 * math.pi
    mask = type_mask_for(setpoint, axes_separately)
    position = [value if value is not None and not mask & bit else 0.0
                for value, bit in zip((setpoint.hold_north_m, setpoint.hold_east_m, setpoint.hold_down_m),
                                      _POSITION_BITS)]
    return (
        time_boot_ms & 0xFFFFFFFF, target_system, target_component, SETPOINT_FRAME, mask,
        *position, north_m_s, east_m_s, down_m_s, 0.0, 0.0, 0.0, yaw_rad, 0.0,
    )
