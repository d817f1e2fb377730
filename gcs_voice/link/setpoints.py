"""One setpoint encoding for ArduPilot and PX4: LOCAL_NED velocity rotated by the heading target, absolute yaw.

Why this one (see ../shared/tlogs/README.md): PX4 offboard accepts only MAV_FRAME_LOCAL_NED and
MAV_FRAME_BODY_NED; ArduCopter takes body-frame yaw as *relative* (re-sending +90 deg keeps turning)
and, when yaw is ignored, turns its nose toward the direction of travel. A LOCAL_NED velocity with an
absolute yaw target means the same thing to both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

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


def wrap_deg(angle_deg: float) -> float:
    """An angle in [0, 360)."""
    wrapped = math.fmod(angle_deg, 360.0)
    if wrapped < 0:
        wrapped += 360.0
    return 0.0 if wrapped >= 360.0 else wrapped + 0.0  # + 0.0 turns -0.0 into 0.0


@dataclass(frozen=True)
class Setpoint:
    """A velocity in the body frame of the *heading target* plus that heading (MAVSDK-style names).

    ``forward_m_s`` along the heading, ``right_m_s`` to its right, ``down_m_s`` positive down (NED),
    ``yaw_deg`` the absolute heading target, clockwise from north.
    """

    forward_m_s: float = 0.0
    right_m_s: float = 0.0
    down_m_s: float = 0.0
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("forward_m_s", "right_m_s", "down_m_s", "yaw_deg"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"Setpoint.{name} must be finite, got {getattr(self, name)!r}")

    @classmethod
    def stop(cls, yaw_deg: float) -> "Setpoint":
        """Zero velocity, keep the heading target."""
        return cls(0.0, 0.0, 0.0, yaw_deg)

    @property
    def is_stop(self) -> bool:
        return self.forward_m_s == 0.0 and self.right_m_s == 0.0 and self.down_m_s == 0.0

    def ned_m_s(self) -> tuple[float, float, float]:
        """(north, east, down) velocity."""
        north, east = body_to_ned(self.forward_m_s, self.right_m_s, self.yaw_deg)
        return north, east, self.down_m_s


def body_to_ned(forward_m_s: float, right_m_s: float, yaw_deg: float) -> tuple[float, float]:
    """Rotate a horizontal body-frame velocity by the heading ``yaw_deg`` into (north, east)."""
    yaw_rad = math.radians(yaw_deg)
    cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
    return forward_m_s * cos_yaw - right_m_s * sin_yaw, forward_m_s * sin_yaw + right_m_s * cos_yaw


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
