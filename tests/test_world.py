"""Rooms as data, and contacts: the vehicle stops at walls and furniture and says so."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import fly

from sim_bridge.control import ControlTarget
from sim_bridge.multicopter import Multicopter
from sim_bridge.world import ROOMS_DIR, RoomError, load_room


def take_off(room_name: str, down_m: float = -1.0) -> Multicopter:
    vehicle = Multicopter(load_room(room_name))
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, down_m)))
    fly(vehicle, 4.0)
    return vehicle


def test_bundled_rooms_load() -> None:
    living = load_room("living_room")
    names = {block.name for block in living.blocks}
    assert {"sofa (three-seat)", "sofa (two-seat)", "coffee table", "dining table", "shelf", "plant"} <= names
    assert sum("chair" in name for name in names) >= 2
    size = np.subtract(living.bounds_max_m, living.bounds_min_m)
    assert living.walls and 5.5 <= size[0] <= 6.5 and 4.5 <= size[1] <= 5.5 and size[2] == pytest.approx(2.6)
    field = load_room(ROOMS_DIR / "open_field.json")
    assert not field.walls and not field.blocks


def test_living_room_start_spot_is_free() -> None:
    vehicle = take_off("living_room")
    assert vehicle.pop_events() == []
    assert abs(vehicle.state.pos_ned_m[2] + 1.0) < 0.05


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad_room.json"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("text, says", [
    ("{not json", "not valid JSON"),
    ('{"blocks": []}', "bounds"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0]}}', "extents must be 6"),
    ('{"bounds": {"extents": [6, 0, 0, 5, 0, 2.6]}}', "min must be below"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0, 2.6]}, "blocks": [{"extents": [0, 1, 0, 1, 0, 1]}]}', "name"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0, 2.6]}, "blocks": [{"name": "sofa", "extents": [0, 1, 0, 1]}]}',
     "block 'sofa'"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0, 2.6]}, "start": {"pos_m": [9, 1]}}', "outside the bounds"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0, 2.6]}, "start": {"pos_m": [1, 1]}, '
     '"blocks": [{"name": "sofa", "extents": [0, 2, 0, 2, 0, 1]}]}', "under block 'sofa'"),
    ('{"bounds": {"extents": [0, 6, 0, 5, 0, 2.6]}, "walls": "yes"}', "'walls' must be true or false"),
    ('[1, 2]', "top level must be an object"),
])
def test_malformed_room_gives_one_line_naming_the_file(tmp_path: Path, text: str, says: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(RoomError) as caught:
        load_room(path)
    message = str(caught.value)
    assert str(path) in message and says in message and "\n" not in message
    assert isinstance(caught.value, ValueError)


def test_unknown_room_name_lists_the_bundled_ones() -> None:
    with pytest.raises(RoomError, match="living_room"):
        load_room("kitchen")


@pytest.mark.slow
def test_wall_stops_the_vehicle_and_reports_it() -> None:
    vehicle = take_off("living_room", down_m=-1.2)    # sphere clears the two-seat sofa below
    room = vehicle.room
    wall_north_m = room.bounds_max_m[0] - room.start_xy_m[0]
    vehicle.set_target(ControlTarget(vel_ned_m_s=(2.0, 0.0, 0.0)))
    states = fly(vehicle, 4.0)
    radius_m = 0.25
    assert max(s.pos_ned_m[0] for s in states) < wall_north_m - radius_m + 0.05   # never through
    assert states[-1].pos_ned_m[0] > wall_north_m - radius_m - 0.05              # pinned at the wall
    assert abs(states[-1].vel_ned_m_s[0]) < 0.05
    events = vehicle.pop_events()
    assert [e.obstacle_name for e in events] == ["north wall"]
    assert events[0].pos_ned_m[0] == pytest.approx(wall_north_m - radius_m, abs=0.1)
    assert vehicle.pop_events() == []


@pytest.mark.slow
def test_furniture_stops_the_vehicle_and_reports_it() -> None:
    vehicle = take_off("living_room", down_m=-1.0)
    room = vehicle.room
    shelf = next(b for b in room.blocks if b.name == "shelf")
    shelf_east_m = shelf.min_m[1] - room.start_xy_m[1]
    vehicle.set_target(ControlTarget(vel_ned_m_s=(0.0, 1.0, 0.0), yaw_rad=0.0))
    states = fly(vehicle, 4.0)
    assert max(s.pos_ned_m[1] for s in states) < shelf_east_m - 0.2
    assert abs(states[-1].vel_ned_m_s[1]) < 0.05
    names = [e.obstacle_name for e in vehicle.pop_events()]
    assert names == ["shelf"]
    assert math.isfinite(vehicle.state.yaw_rad)


@pytest.mark.slow
def test_landing_on_a_table_counts_as_on_the_ground() -> None:
    vehicle = take_off("living_room", down_m=-1.2)
    room = vehicle.room
    table = next(b for b in room.blocks if b.name == "coffee table")
    over_n = (table.min_m[0] + table.max_m[0]) / 2 - room.start_xy_m[0]
    over_e = (table.min_m[1] + table.max_m[1]) / 2 - room.start_xy_m[1]
    vehicle.set_target(ControlTarget(pos_ned_m=(over_n, over_e, -1.2)))
    fly(vehicle, 5.0)
    assert not vehicle.state.on_ground
    vehicle.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.5)))
    states = fly(vehicle, 4.0)
    assert states[-1].on_ground
    assert states[-1].pos_ned_m[2] < -table.max_m[2] + 0.2   # on the table top, not the floor
    vehicle.set_armed(False)
    resting = vehicle.state.pos_ned_m.copy()
    states = fly(vehicle, 3.0)
    assert all(s.on_ground for s in states)
    assert np.abs(states[-1].pos_ned_m - resting).max() < 0.02
    assert "coffee table" in [e.obstacle_name for e in vehicle.pop_events()]
