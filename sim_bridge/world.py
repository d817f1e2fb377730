"""Rooms as data, and the contact model that keeps the vehicle out of walls and furniture.

A room file is JSON in the shape of rotorpy's ``worlds/*.json`` (``bounds.extents`` and ``blocks[].extents``
as [xmin, xmax, ymin, ymax, zmin, zmax]) plus a ``name`` per block. Frame: x north, y east, z up from the
floor, metres. With ``"walls": true`` the bounds are solid walls and a ceiling (the floor is JSBSim's ground);
otherwise they only describe the map. ``start`` gives the free spot where the vehicle starts (home) and its
heading. The vehicle is a sphere around its CG; touching a surface produces a spring-damper push-out force
(``data/contact.toml``) that stops it at the surface, and one ``Contact`` event per touch.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from sim_bridge.frames import room_to_ned

__all__ = ["RoomError", "Block", "Room", "Contact", "ContactParams", "ContactModel", "load_room",
           "load_contact_params", "ROOMS_DIR"]

ROOMS_DIR = Path(__file__).resolve().parent / "rooms"
CONTACT_PARAMS_PATH = Path(__file__).resolve().parent / "data" / "contact.toml"
SUPPORT_NORMAL_UP = 0.7   # a contact whose normal points this much upward carries the vehicle (a table top)
_WALL_NAMES = ("south wall", "north wall", "west wall", "east wall", "floor", "ceiling")  # per bounds face


class RoomError(ValueError):
    """A room file is missing or malformed; the message is one line naming the file."""


@dataclass(frozen=True)
class Block:
    """A named solid box in the room frame (x north, y east, z up; metres)."""

    name: str
    min_m: tuple[float, float, float]
    max_m: tuple[float, float, float]


@dataclass(frozen=True)
class Room:
    name: str
    source: str
    bounds_min_m: tuple[float, float, float]
    bounds_max_m: tuple[float, float, float]
    walls: bool
    blocks: tuple[Block, ...]
    start_xy_m: tuple[float, float]
    start_yaw_deg: float
    home_lat_deg: float | None = None
    home_lon_deg: float | None = None
    home_alt_m: float | None = None


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


def _extents(value: object, where: str, source: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    if (not isinstance(value, list) or len(value) != 6
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)):
        raise RoomError(f"{source}: {where}: extents must be 6 finite numbers [xmin, xmax, ymin, ymax, zmin, zmax]")
    xmin, xmax, ymin, ymax, zmin, zmax = (float(x) for x in value)
    if not (xmin < xmax and ymin < ymax and zmin < zmax):
        raise RoomError(f"{source}: {where}: each min must be below its max in {value}")
    return (xmin, ymin, zmin), (xmax, ymax, zmax)


def _resolve(path_or_name: str | Path) -> Path:
    path = Path(path_or_name)
    if path.suffix != ".json" and not path.exists():
        path = ROOMS_DIR / f"{path_or_name}.json"
    return path


def load_room(path_or_name: str | Path) -> Room:
    """A room from a JSON path, or a bundled room by name (``living_room``, ``open_field``)."""
    path = _resolve(path_or_name)
    source = str(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        bundled = ", ".join(sorted(p.stem for p in ROOMS_DIR.glob("*.json")))
        raise RoomError(f"{source}: no such room file (bundled rooms: {bundled})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RoomError(f"{source}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise RoomError(f"{source}: not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    if not isinstance(data, dict):
        raise RoomError(f"{source}: the top level must be an object")
    bounds = data.get("bounds")
    if not isinstance(bounds, dict):
        raise RoomError(f"{source}: missing 'bounds' object with 'extents'")
    bmin, bmax = _extents(bounds.get("extents"), "bounds", source)
    walls = data.get("walls", False)
    if not isinstance(walls, bool):
        raise RoomError(f"{source}: 'walls' must be true or false")
    raw_blocks = data.get("blocks", [])
    if not isinstance(raw_blocks, list):
        raise RoomError(f"{source}: 'blocks' must be a list")
    blocks = []
    for i, raw in enumerate(raw_blocks):
        if not isinstance(raw, dict) or not isinstance(raw.get("name"), str) or not raw["name"].strip():
            raise RoomError(f"{source}: blocks[{i}] needs a non-empty 'name'")
        lo, hi = _extents(raw.get("extents"), f"block '{raw['name']}'", source)
        blocks.append(Block(raw["name"].strip(), lo, hi))
    if len({b.name for b in blocks}) != len(blocks):
        raise RoomError(f"{source}: block names must be unique")
    start = data.get("start", {})
    if not isinstance(start, dict):
        raise RoomError(f"{source}: 'start' must be an object with 'pos_m' [x, y] and 'yaw_deg'")
    pos = start.get("pos_m", [(bmin[0] + bmax[0]) / 2, (bmin[1] + bmax[1]) / 2])
    yaw = start.get("yaw_deg", 0.0)
    if (not isinstance(pos, list) or len(pos) != 2 or not all(isinstance(x, (int, float)) for x in pos)
            or not isinstance(yaw, (int, float)) or not math.isfinite(yaw)):
        raise RoomError(f"{source}: start.pos_m must be [x, y] and start.yaw_deg a number")
    if not (bmin[0] <= pos[0] <= bmax[0] and bmin[1] <= pos[1] <= bmax[1]):
        raise RoomError(f"{source}: start.pos_m {pos} lies outside the bounds")
    for block in blocks:
        if block.min_m[0] <= pos[0] <= block.max_m[0] and block.min_m[1] <= pos[1] <= block.max_m[1]:
            raise RoomError(f"{source}: start.pos_m {pos} lies under block '{block.name}': start on a free spot")
    home = data.get("home", {})
    home_values = [home.get(k) for k in ("lat_deg", "lon_deg", "alt_m")] if isinstance(home, dict) else [0]
    if home and not all(isinstance(v, (int, float)) and math.isfinite(v) for v in home_values):
        raise RoomError(f"{source}: 'home' needs numeric lat_deg, lon_deg and alt_m")
    return Room(
        name=str(data.get("name", path.stem)), source=source, bounds_min_m=bmin, bounds_max_m=bmax,
        walls=walls, blocks=tuple(blocks), start_xy_m=(float(pos[0]), float(pos[1])), start_yaw_deg=float(yaw),
        home_lat_deg=home_values[0] if home else None, home_lon_deg=home_values[1] if home else None,
        home_alt_m=home_values[2] if home else None,
    )


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
