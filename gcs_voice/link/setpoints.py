"""One setpoint encoding for ArduPilot and PX4: LOCAL_NED velocity rotated by the heading target, absolute yaw.

Why this one (see ../shared/tlogs/README.md): PX4 offboard accepts only MAV_FRAME_LOCAL_NED and
MAV_FRAME_BODY_NED; ArduCopter takes body-frame yaw as *relative* (re-sending +90 deg keeps turning)
and, when yaw is ignored, turns its nose toward the direction of travel. A LOCAL_NED velocity with an
absolute yaw target means the same thing to both.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.actions.setpoint import Setpoint, body_to_ned, wrap_deg

__all__ = ["Setpoint", "TYPE_MASK_VELOCITY_YAW", "SETPOINT_FRAME", "body_to_ned", "wrap_deg", "setpoint_fields"]

#: Bits that *ignore* a field: position, acceleration and yaw rate are ignored; velocity and yaw are used.
TYPE_MASK_VELOCITY_YAW: int = (
    mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
SETPOINT_FRAME: int = mavlink.MAV_FRAME_LOCAL_NED


def setpoint_fields(setpoint: Setpoint, target_system: int, target_component: int, time_boot_ms: int = 0) -> tuple:
    """SET_POSITION_TARGET_LOCAL_NED fields, in ``set_position_target_local_ned_encode`` order.

    Yaw goes out in radians in (-pi, pi]; positions, accelerations and yaw rate are zero and ignored.
    """
    north_m_s, east_m_s, down_m_s = setpoint.ned_m_s()
    yaw_rad = math.radians(wrap_deg(setpoint.yaw_deg))
    if yaw_rad > math.pi:
        yaw_rad -= 2.0 * math.pi
    return (
        time_boot_ms & 0xFFFFFFFF, target_system, target_component, SETPOINT_FRAME, TYPE_MASK_VELOCITY_YAW,
        0.0, 0.0, 0.0, north_m_s, east_m_s, down_m_s, 0.0, 0.0, 0.0, yaw_rad, 0.0,
    )
