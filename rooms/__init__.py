"""Room files: the one reader, shared by the simulator (contacts) and the flight plot (the map).

A room file is JSON in the shape of rotorpy's ``worlds/*.json`` (``bounds.extents`` and ``blocks[].extents``
as [xmin, xmax, ymin, ymax, zmin, zmax]) plus a ``name`` per block. Frame: x north, y east, z up from the
floor, metres. With ``"walls": true`` the bounds are solid walls and a ceiling; otherwise they only describe
the map. ``start`` gives the free spot where the vehicle starts (home, local NED 0, 0) and its heading;
without it, the middle of the bounds. ``home`` optionally gives its latitude, longitude and altitude.

Data only: no physics and no plotting here, so ``gcs_voice`` can read rooms without importing ``sim_bridge``.
Bundled rooms live beside this file; add one by dropping a JSON file here.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

__all__ = ["RoomError", "Block", "Room", "load_room", "bundled_rooms", "ROOMS_DIR"]

ROOMS_DIR = Path(__file__).resolve().parent


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
        bundled = ", ".join(bundled_rooms())
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


def bundled_rooms() -> list[str]:
    """Names of the rooms that ship with the package (``living_room``, ``open_field``, ...)."""
    return sorted(p.stem for p in ROOMS_DIR.glob("*.json"))
