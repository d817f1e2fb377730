"""The mapper's output: a velocity in the heading target's frame plus that heading, and what to hold.

A hold is a local NED position (metres from the EKF origin) per axis: ``stop`` and a turn hold the
point where they were heard (all three axes), a horizontal motion holds its height (down only), a
vertical one its horizontal point. None = that axis is flown by velocity alone. Why: a zero-velocity
setpoint with the position ignored let PX4 SIH creep 0.1-0.2 m/s and sink 1.8 -> 0.65 m
(../shared/tlogs/PX4.md). Owned by the actions layer; ``gcs_voice.link.setpoints`` encodes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Setpoint", "body_to_ned", "ned_to_body", "wrap_deg", "round_deg"]


def wrap_deg(angle_deg: float) -> float:
    """An angle in [0, 360)."""
    wrapped = math.fmod(angle_deg, 360.0)
    if wrapped < 0:
        wrapped += 360.0
    return 0.0 if wrapped >= 360.0 else wrapped + 0.0  # + 0.0 turns -0.0 into 0.0


def round_deg(angle_deg: float, ndigits: int = 1) -> float:
    """An angle rounded for display, in [0, 360): rounding after wrapping turned 359.97 into 360.0."""
    return round(wrap_deg(round(wrap_deg(angle_deg), ndigits)), ndigits) + 0.0


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
    #: position to hold, local NED metres; None = not held on that axis
    hold_north_m: float | None = None
    hold_east_m: float | None = None
    hold_down_m: float | None = None

    def __post_init__(self) -> None:
        for name in ("forward_m_s", "right_m_s", "down_m_s", "yaw_deg"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"Setpoint.{name} must be finite, got {getattr(self, name)!r}")
        for name in ("hold_north_m", "hold_east_m", "hold_down_m"):
            value = getattr(self, name)
            if value is not None and not math.isfinite(value):
                raise ValueError(f"Setpoint.{name} must be finite or None, got {value!r}")
        if (self.hold_north_m is None) != (self.hold_east_m is None):
            raise ValueError("Setpoint: hold north and east together (a horizontal point) or neither")

    @classmethod
    def stop(cls, yaw_deg: float) -> "Setpoint":
        """Zero velocity, keep the heading target."""
        return cls(0.0, 0.0, 0.0, yaw_deg)

    @property
    def holds(self) -> tuple[bool, bool, bool]:
        """Which NED axes carry a position target."""
        return self.hold_north_m is not None, self.hold_east_m is not None, self.hold_down_m is not None

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


def ned_to_body(north_m_s: float, east_m_s: float, yaw_deg: float) -> tuple[float, float]:
    """The inverse of :func:`body_to_ned`: a (north, east) velocity as (forward, right) at heading ``yaw_deg``."""
    yaw_rad = math.radians(yaw_deg)
    cos_yaw, sin_yaw = math.cos(yaw_rad), math.sin(yaw_rad)
    return north_m_s * cos_yaw + east_m_s * sin_yaw, -north_m_s * sin_yaw + east_m_s * cos_yaw
