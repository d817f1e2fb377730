"""The contact model that keeps the vehicle out of walls and furniture; rooms are read by ``rooms``.

With ``"walls": true`` a room's bounds are solid walls and a ceiling (the floor is JSBSim's ground). The
vehicle is a sphere around its CG; touching a surface produces a spring-damper push-out force
(``data/contact.toml``) that stops it at the surface, and one ``Contact`` event per touch.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from rooms import ROOMS_DIR, Block, Room, RoomError, load_room
from sim_bridge.frames import room_to_ned

__all__ = ["RoomError", "Block", "Room", "Contact", "ContactParams", "ContactModel", "load_room",
           "load_contact_params", "ROOMS_DIR"]

CONTACT_PARAMS_PATH = Path(__file__).resolve().parent / "data" / "contact.toml"
SUPPORT_NORMAL_UP = 0.7   # a contact whose normal points this much upward carries the vehicle (a table top)
_WALL_NAMES = ("south wall", "north wall", "west wall", "east wall", "floor", "ceiling")  # per bounds face


@dataclass(frozen=True)
class Contact:
    """The vehicle touched something: simulated time, what (block name or e.g. "north wall"), where (NED, m)."""

    t_s: float
    obstacle_name: str
    pos_ned_m: tuple[float, float, float]


@dataclass(frozen=True)
class ContactParams:
    vehicle_radius_m: float
    stiffness_n_m: float
    damping_n_s_m: float
    event_repeat_s: float


def load_contact_params(path: str | Path = CONTACT_PARAMS_PATH) -> ContactParams:
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))["contact"]
        return ContactParams(**{k: float(v) for k, v in data.items()})
    except (OSError, tomllib.TOMLDecodeError, KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: bad contact parameters: {exc}") from None


class ContactModel:
    """Sphere-vs-boxes contact in NED (relative to home = the room's start spot on the floor)."""

    def __init__(self, room: Room, params: ContactParams) -> None:
        self.params = params
        self.supported = False  # after force_ned_n: resting on top of a block (counts as on the ground)
        home = room.start_xy_m
        self._boxes: list[tuple[str, tuple[float, ...], tuple[float, ...]]] = []
        for block in room.blocks:
            a = room_to_ned(block.min_m, home)
            b = room_to_ned(block.max_m, home)
            self._boxes.append((block.name, tuple(map(min, a, b)), tuple(map(max, a, b))))
        self._walls: list[tuple[str, int, float, float]] = []  # name, axis, plane, inward sign
        if room.walls:
            lo = room_to_ned(room.bounds_min_m, home)
            hi = room_to_ned(room.bounds_max_m, home)
            self._walls = [
                (_WALL_NAMES[0], 0, lo[0], +1.0), (_WALL_NAMES[1], 0, hi[0], -1.0),
                (_WALL_NAMES[2], 1, lo[1], +1.0), (_WALL_NAMES[3], 1, hi[1], -1.0),
                (_WALL_NAMES[5], 2, hi[2], +1.0),  # ceiling: NED down of the ceiling is negative
            ]

    def force_ned_n(self, center_ned_m: tuple[float, float, float],
                    vel_ned_m_s: tuple[float, float, float]) -> tuple[tuple[float, float, float], list[str]]:
        """Push-out force (N, NED) on a sphere at ``center_ned_m`` and the names of what it touches."""
        r = self.params.vehicle_radius_m
        cn, ce, cd = center_ned_m
        self.supported = False
        total = [0.0, 0.0, 0.0]
        touching: list[str] = []
        for name, lo, hi in self._boxes:
            # broad phase: outside the box grown by r on every side means no contact (cheap, the usual case)
            if (cn <= lo[0] - r or cn >= hi[0] + r or ce <= lo[1] - r or ce >= hi[1] + r
                    or cd <= lo[2] - r or cd >= hi[2] + r):
                continue
            qn = lo[0] if cn < lo[0] else (hi[0] if cn > hi[0] else cn)
            qe = lo[1] if ce < lo[1] else (hi[1] if ce > hi[1] else ce)
            qd = lo[2] if cd < lo[2] else (hi[2] if cd > hi[2] else cd)
            offset = (cn - qn, ce - qe, cd - qd)
            distance = math.sqrt(offset[0] ** 2 + offset[1] ** 2 + offset[2] ** 2)
            if distance >= r:
                continue
            if distance > 1e-9:
                normal = [d / distance for d in offset]
                depth = r - distance
            else:  # centre inside the box: leave through the nearest face
                gaps = [(center_ned_m[i] - lo[i], i, -1.0) for i in range(3)] + \
                       [(hi[i] - center_ned_m[i], i, 1.0) for i in range(3)]
                gap, axis, sign = min(gaps)
                normal = [0.0, 0.0, 0.0]
                normal[axis] = sign
                depth = r + gap
            self._push(total, normal, depth, vel_ned_m_s)
            touching.append(name)
            self.supported = self.supported or normal[2] < -SUPPORT_NORMAL_UP
        for name, axis, plane, inward in self._walls:
            gap = (center_ned_m[axis] - plane) * inward  # distance from the wall into the room
            if gap >= r:
                continue
            normal = [0.0, 0.0, 0.0]
            normal[axis] = inward
            self._push(total, normal, r - gap, vel_ned_m_s)
            touching.append(name)
        return (total[0], total[1], total[2]), touching

    def _push(self, total: list[float], normal: list[float], depth_m: float, vel: tuple[float, float, float]) -> None:
        closing_m_s = sum(n * v for n, v in zip(normal, vel))  # negative when moving into the surface
        magnitude = self.params.stiffness_n_m * depth_m - self.params.damping_n_s_m * closing_m_s
        if magnitude <= 0.0:  # a contact pushes, never pulls
            return
        for i in range(3):
            total[i] += magnitude * normal[i]
