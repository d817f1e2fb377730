"""Touchdowns the way a client can command them: tilted, sideways, onto furniture, against a wall.

Regression for a flight where a sideways, tilted touchdown launched the vehicle (climb at 74 m/s, 135 m up).
Real JSBSim and our controller in lockstep; the assertions are on what the vehicle did.
"""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from conftest import fly

from sim_bridge.control import ControlTarget
from sim_bridge.multicopter import PHYSICS_FAULT_EVENT, TIPPED_OVER_EVENT, Multicopter
from sim_bridge.world import load_room

STEP_S = 0.05
HOVER_DOWN_M = -1.5
MAX_H_SPEED_M_S = 5.0 * 1.2      # control.toml limits plus a margin for the touchdown itself
MAX_V_SPEED_M_S = 2.5 * 1.5
REST_SPEED_M_S = 0.05


def hover_at(room: str, north_m: float, east_m: float, down_m: float = HOVER_DOWN_M) -> Multicopter:
    vehicle = Multicopter(load_room(room))
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, down_m)))
    fly(vehicle, 2.5)
    vehicle.set_target(ControlTarget(pos_ned_m=(north_m, east_m, down_m)))
    fly(vehicle, 3.5)
    vehicle.pop_events()
    return vehicle



def assert_sane_touchdown(vehicle: Multicopter, seconds: float, highest_up_m: float) -> None:
    """Never above the highest commanded point + 1 m, within the speed limits, at rest upright, no NaN."""
    states = fly(vehicle, seconds)
    for s in states:
        assert np.all(np.isfinite(s.pos_ned_m)) and np.all(np.isfinite(s.vel_ned_m_s))
        assert -s.pos_ned_m[2] < highest_up_m + 1.0, f"climbed to {-s.pos_ned_m[2]:.2f} m at {s.t_s:.2f} s"
        assert math.hypot(*s.vel_ned_m_s[:2]) < MAX_H_SPEED_M_S
        assert abs(s.vel_ned_m_s[2]) < MAX_V_SPEED_M_S
    for s in states[-round(1.0 / STEP_S):]:   # the last second: at rest, standing level on something
        assert s.on_ground
        assert np.linalg.norm(s.vel_ned_m_s) < REST_SPEED_M_S
        assert abs(s.roll_rad) < math.radians(10) and abs(s.pitch_rad) < math.radians(10)
    names = [event.obstacle_name for event in vehicle.pop_events()]
    assert PHYSICS_FAULT_EVENT not in names and TIPPED_OVER_EVENT not in names


@pytest.mark.slow
@pytest.mark.parametrize("room", ["open_field", "living_room"])
@pytest.mark.parametrize("speed_m_s, heading_deg, yaw_rate_rad_s", [
    (2.0, 0.0, 0.0), (5.0, 45.0, 0.0), (5.0, 90.0, 1.5), (3.0, 200.0, -1.5)])
def test_full_speed_descent_while_moving_sideways_lands_at_rest(room, speed_m_s, heading_deg,
                                                                 yaw_rate_rad_s) -> None:
    vehicle = hover_at(room, 0.0, 0.0)
    heading = math.radians(heading_deg)
    vehicle.set_target(ControlTarget(vel_ned_m_s=(speed_m_s * math.cos(heading), speed_m_s * math.sin(heading),
                                                  2.5), yaw_rate_rad_s=yaw_rate_rad_s))
    assert_sane_touchdown(vehicle, 6.0, 1.5)


@pytest.mark.slow
@pytest.mark.parametrize("room", ["open_field", "living_room"])
@pytest.mark.parametrize("north_m, east_m, yaw_rate_rad_s", [(4.0, 0.0, 0.0), (-5.7, 5.7, 1.0)])
def test_position_target_metres_away_below_ground_lands_at_rest(room, north_m, east_m, yaw_rate_rad_s) -> None:
    """The reported trigger: steering toward a point metres away while descending (here 0.5 m underground)."""
    vehicle = hover_at(room, 0.0, 0.0)
    vehicle.set_target(ControlTarget(pos_ned_m=(north_m, east_m, 0.5), yaw_rate_rad_s=yaw_rate_rad_s))
    assert_sane_touchdown(vehicle, 6.0, 1.5)


@pytest.mark.slow
@pytest.mark.parametrize("north_m, east_m, top_m, vel_ne_m_s", [
    (-1.9, 1.3, 0.75, (0.5, 0.5)),     # dining table, 1.0 x 1.2 m
    (-0.4, -1.1, 0.45, (-0.6, 0.0)),   # coffee table, 0.8 x 0.6 m: slides off or lands on it
])
def test_sideways_descent_onto_furniture_tops(north_m, east_m, top_m, vel_ne_m_s) -> None:
    vehicle = hover_at("living_room", north_m, east_m)
    vehicle.set_target(ControlTarget(vel_ned_m_s=(*vel_ne_m_s, 2.5)))
    assert_sane_touchdown(vehicle, 6.0, 1.5)
    assert -vehicle.state.pos_ned_m[2] < top_m + 0.05


@pytest.mark.slow
def test_descent_into_a_wall_at_floor_level_lands_at_rest() -> None:
    vehicle = hover_at("living_room", 2.0, 0.0, -0.6)   # 1 m from the north wall, low
    vehicle.set_target(ControlTarget(vel_ned_m_s=(4.0, 0.0, 2.5)))
    assert_sane_touchdown(vehicle, 5.0, 0.6)
    assert vehicle.state.pos_ned_m[0] < 3.0 - 0.2     # the wall (north 3 m) minus most of the vehicle radius


@pytest.mark.parametrize("room", ["open_field", "living_room"])
def test_armed_on_the_ground_with_a_big_sideways_target_stays_put(room) -> None:
    vehicle = Multicopter(load_room(room))
    vehicle.set_armed(True)
    start = vehicle.state.pos_ned_m.copy()
    for vd_m_s in (0.0, 2.5):
        vehicle.set_target(ControlTarget(vel_ned_m_s=(5.0, -5.0, vd_m_s), yaw_rate_rad_s=1.5))
        states = fly(vehicle, 2.0)
        assert all(s.on_ground for s in states)
        assert np.linalg.norm(vehicle.state.pos_ned_m - start) < 0.02


def test_a_push_no_vehicle_can_fight_ends_in_the_safety_net_not_in_nan() -> None:
    """The last net in ``Multicopter``: far past the speed limits while armed -> reset at rest, disarmed, event."""
    vehicle = hover_at("open_field", 0.0, 0.0)
    vehicle.set_disturbance_force_ned_n((50.0, 0.0, 0.0))   # 3.6 g sideways, far past the 30 deg tilt limit
    states = fly(vehicle, 3.0)
    assert all(np.all(np.isfinite(s.vel_ned_m_s)) for s in states)
    assert max(math.hypot(*s.vel_ned_m_s[:2]) for s in states) < 3.0 * 5.0 + 1.0
    assert PHYSICS_FAULT_EVENT in [event.obstacle_name for event in vehicle.pop_events()]
    assert not vehicle.state.armed


@pytest.mark.slow
@pytest.mark.parametrize("physics_hz", [200.0, 400.0])
def test_touchdowns_come_to_rest_at_other_physics_rates(physics_hz) -> None:
    vehicle = Multicopter(load_room("open_field"), physics_hz=physics_hz)
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, HOVER_DOWN_M)))
    fly(vehicle, 4.0)
    vehicle.set_target(ControlTarget(vel_ned_m_s=(0.0, 5.0, 2.5), yaw_rate_rad_s=1.5))
    assert_sane_touchdown(vehicle, 6.0, 1.5)


def test_physics_rates_whose_ground_contact_is_unstable_are_refused() -> None:
    with pytest.raises(ValueError, match="physics_hz"):
        Multicopter(physics_hz=100.0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_random_target_sequences_never_tip_fly_away_or_break(seed) -> None:
    """Seeded fuzz: 10 flights of 16 random targets, 0.5 s each: positions metres away (up to 2 m high or
    underground), sideways velocities beyond the limits while descending or level, random yaw rates."""
    rng = random.Random(seed)
    for room in ("open_field", "living_room") * 5:
        vehicle = Multicopter(load_room(room))
        vehicle.set_armed(True)
        highest_up_m = 0.0
        for _ in range(16):
            yaw_rate = rng.choice([None, rng.uniform(-1.6, 1.6)])
            if rng.random() < 0.5:
                target = ControlTarget(vel_ned_m_s=(rng.uniform(-6, 6), rng.uniform(-6, 6),
                                                    rng.choice([2.5, rng.uniform(0.0, 3.0)])), yaw_rate_rad_s=yaw_rate)
            else:
                pos = (rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-2.0, 1.0))
                highest_up_m = max(highest_up_m, -pos[2])
                target = ControlTarget(pos_ned_m=pos, yaw_rate_rad_s=yaw_rate)
            vehicle.set_target(target)
            for s in fly(vehicle, 0.5):
                assert np.all(np.isfinite(s.vel_ned_m_s)) and np.all(np.isfinite(s.pos_ned_m))
                assert -s.pos_ned_m[2] < highest_up_m + 1.0
                assert math.hypot(*s.vel_ned_m_s[:2]) < MAX_H_SPEED_M_S and abs(s.vel_ned_m_s[2]) < MAX_V_SPEED_M_S
        names = [event.obstacle_name for event in vehicle.pop_events()]
        assert PHYSICS_FAULT_EVENT not in names and TIPPED_OVER_EVENT not in names
        assert vehicle.state.armed
