"""SET_POSITION_TARGET_LOCAL_NED -> one NED setpoint with absolute yaw, by each autopilot's frame rules.

The frame conversion happens here, once: body frames are rotated by the current heading, offsets are
added to the current position, and a body-frame yaw becomes absolute when the autopilot takes it as
relative (ArduCopter) or is used as given (PX4). What the vehicle receives is always NED.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.frames import wrap_pi

__all__ = ["FrameRules", "Setpoint", "SetpointRejected", "decode_setpoint", "TYPE_MASK"]


class TYPE_MASK:  # noqa: N801 - a namespace of POSITION_TARGET_TYPEMASK bits
    POSITION = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
                | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)
    VELOCITY = (mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
                | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE)
    ACCELERATION = (mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE)
    FORCE = mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET
    YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    YAW_RATE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE


BODY_FRAMES = frozenset({mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_OFFSET_NED})
OFFSET_FRAMES = frozenset({mavlink.MAV_FRAME_LOCAL_OFFSET_NED, mavlink.MAV_FRAME_BODY_NED,
                           mavlink.MAV_FRAME_BODY_OFFSET_NED})


class SetpointRejected(ValueError):
    """The setpoint is dropped; ``reason`` is 'frame', 'invalid' or 'nan' (the personality words it)."""

    def __init__(self, reason: str, frame: int) -> None:
        super().__init__(reason)
        self.reason = reason
        self.frame = frame


@dataclass(frozen=True)
class FrameRules:
    """How one autopilot reads SET_POSITION_TARGET_LOCAL_NED."""

    frames: frozenset[int]
    body_yaw_relative: bool          # ArduCopter: yaw in a body frame is an offset from the current heading
    any_bit_ignores_group: bool      # ArduCopter: one ignore bit set drops the whole position/velocity group
    body_position_ignored: bool      # PX4: position fields in BODY_NED are ignored


@dataclass
class Setpoint:
    """An external setpoint in NED. ``None`` per position axis = not controlled."""

    vel_ned_m_s: tuple[float, float, float]
    pos_ned_m: tuple[float | None, float | None, float | None]
    yaw_rad: float | None
    yaw_rate_rad_s: float | None
    auto_yaw: bool
    received_s: float
    clamp_counted: bool = False

    def with_yaw(self, yaw_rad: float) -> "Setpoint":
        return replace(self, yaw_rad=yaw_rad, yaw_rate_rad_s=None, auto_yaw=False)


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def decode_setpoint(msg: mavlink.MAVLink_set_position_target_local_ned_message, rules: FrameRules,
                    yaw_now_rad: float, pos_now_ned_m: tuple[float, float, float], now_s: float,
                    auto_yaw_enabled: bool) -> Setpoint:
    """Apply ``rules`` to ``msg``; raises SetpointRejected for frames, masks or numbers it cannot use."""
    frame = msg.coordinate_frame
    if frame not in rules.frames:
        raise SetpointRejected("frame", frame)
    mask = msg.type_mask
    if mask & TYPE_MASK.FORCE and (mask & TYPE_MASK.ACCELERATION) != TYPE_MASK.ACCELERATION:
        raise SetpointRejected("invalid", frame)
    if rules.any_bit_ignores_group:
        pos_used = [not (mask & TYPE_MASK.POSITION)] * 3
        vel_used = not (mask & TYPE_MASK.VELOCITY)
    else:
        pos_used = [not (mask & bit) for bit in (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE,
                                                 mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE,
                                                 mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)]
        vel_bits = mask & TYPE_MASK.VELOCITY
        if vel_bits not in (0, TYPE_MASK.VELOCITY):
            raise SetpointRejected("invalid", frame)
        vel_used = vel_bits == 0
    if frame in BODY_FRAMES and rules.body_position_ignored:
        pos_used = [False] * 3
    if not vel_used and not any(pos_used):
        raise SetpointRejected("invalid", frame)
    yaw_used = not (mask & TYPE_MASK.YAW)
    yaw_rate_used = not (mask & TYPE_MASK.YAW_RATE)

    cos_y, sin_y = math.cos(yaw_now_rad), math.sin(yaw_now_rad)
    body = frame in BODY_FRAMES
    vel = (0.0, 0.0, 0.0)
    if vel_used:
        if not _finite(msg.vx, msg.vy, msg.vz):
            raise SetpointRejected("nan", frame)
        vel = (msg.vx * cos_y - msg.vy * sin_y, msg.vx * sin_y + msg.vy * cos_y, msg.vz) if body \
            else (float(msg.vx), float(msg.vy), float(msg.vz))
    pos: list[float | None] = [None, None, None]
    if any(pos_used):
        if not _finite(*(v for v, used in zip((msg.x, msg.y, msg.z), pos_used) if used)):
            raise SetpointRejected("nan", frame)
        x, y, z = (msg.x if pos_used[0] else 0.0), (msg.y if pos_used[1] else 0.0), (msg.z if pos_used[2] else 0.0)
        if body:
            x, y = x * cos_y - y * sin_y, x * sin_y + y * cos_y
        if frame in OFFSET_FRAMES:
            x, y, z = x + pos_now_ned_m[0], y + pos_now_ned_m[1], z + pos_now_ned_m[2]
        pos = [v if used else None for v, used in zip((x, y, z), pos_used)]
    yaw = yaw_rate = None
    if yaw_used:
        if not _finite(msg.yaw):
            raise SetpointRejected("nan", frame)
        yaw = msg.yaw + yaw_now_rad if (body and rules.body_yaw_relative) else float(msg.yaw)
        yaw = wrap_pi(yaw)
    elif yaw_rate_used:
        if not _finite(msg.yaw_rate):
            raise SetpointRejected("nan", frame)
        yaw_rate = float(msg.yaw_rate)
    return Setpoint(vel_ned_m_s=vel, pos_ned_m=(pos[0], pos[1], pos[2]), yaw_rad=yaw, yaw_rate_rad_s=yaw_rate,
                    auto_yaw=auto_yaw_enabled and not yaw_used and not yaw_rate_used, received_s=now_s)
