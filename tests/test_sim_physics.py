"""The simulated quadrotor (real JSBSim, our controller), flown in lockstep: outcomes, not internals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import fly

from sim_bridge.control import DEFAULT_GAINS_PATH, ControlTarget, load_gains, sanitize_target
from sim_bridge.frames import geodetic_to_ned_m, ned_to_geodetic
from sim_bridge.multicopter import Multicopter
from sim_bridge.world import load_room

STEP_S = 0.05
CRUISE_DOWN_M = -1.5



@pytest.fixture()
def hovering() -> Multicopter:
    """Armed, taken off to 1.5 m in the open field, settled."""
    vehicle = Multicopter(load_room("open_field"))
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, CRUISE_DOWN_M)))
    fly(vehicle, 6.0)
    assert not vehicle.state.on_ground
    return vehicle


def test_loading_and_flying_print_nothing(capfd: pytest.CaptureFixture[str]) -> None:
    vehicle = Multicopter(load_room("living_room"))
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, -2.5)))   # up into the ceiling
    fly(vehicle, 3.0)
    vehicle.reset()
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_bad_gains_file_is_one_line_naming_file_and_key(tmp_path) -> None:
    good = DEFAULT_GAINS_PATH.read_text(encoding="utf-8")
    for broken, says in ((good.replace("tilt_deg = ", "tilt_degrees = "), "limits.tilt_deg"),
                         (good.replace("kp_yaw_per_s = 3.0", 'kp_yaw_per_s = "fast"'), "attitude.kp_yaw_per_s"),
                         (good + "\n[", "cannot read")):
        path = tmp_path / "gains.toml"
        path.write_text(broken, encoding="utf-8")
        with pytest.raises(ValueError) as caught:
            Multicopter(gains_path=path)
        assert str(path) in str(caught.value) and says in str(caught.value)


def test_hover_holds_altitude_within_5_cm(hovering: Multicopter) -> None:
    downs = [s.pos_ned_m[2] for s in fly(hovering, 10.0)]
    assert max(abs(d - CRUISE_DOWN_M) for d in downs) < 0.05
    assert 0.3 < hovering.state.throttle < 0.6   # found by the trim search, not assumed


@pytest.mark.parametrize("vel_ned_m_s", [(1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)])
def test_velocity_target_is_reached_and_moves_the_right_way(hovering: Multicopter, vel_ned_m_s) -> None:
    start = hovering.state.pos_ned_m.copy()
    hovering.set_target(ControlTarget(vel_ned_m_s=vel_ned_m_s))
    states = fly(hovering, 3.0)
    wanted = np.array(vel_ned_m_s)
    assert np.linalg.norm(states[-1].vel_ned_m_s - wanted) < 0.1
    moved = states[-1].pos_ned_m - start
    along = float(moved @ wanted)
    assert along > 2.0                                   # most of 3 s at 1 m/s
    assert np.linalg.norm(moved - along * wanted) < 0.1  # and not sideways


def test_yaw_target_plus_90_deg_is_reached(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=math.pi / 2))
    fly(hovering, 4.0)
    assert abs(math.degrees(hovering.state.yaw_rad) - 90.0) < 3.0


def test_yaw_rate_turns_clockwise_then_holds(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rate_rad_s=math.radians(30)))
    fly(hovering, 2.0)
    turned_deg = math.degrees(hovering.state.yaw_rad)
    assert 40.0 < turned_deg < 75.0
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0)))  # neither yaw nor rate: keep heading
    fly(hovering, 1.0)
    held_deg = math.degrees(hovering.state.yaw_rad)
    fly(hovering, 3.0)
    assert abs(math.degrees(hovering.state.yaw_rad) - held_deg) < 2.0


def test_disarmed_on_the_ground_stays_put() -> None:
    vehicle = Multicopter(load_room("living_room"))
    start = vehicle.state.pos_ned_m.copy()
    yaw = vehicle.state.yaw_rad
    states = fly(vehicle, 10.0)
    assert all(s.on_ground and not s.armed and s.throttle == 0.0 for s in states)
    assert np.abs(states[-1].pos_ned_m - start).max() < 1e-3
    assert np.abs(states[-1].vel_ned_m_s).max() < 1e-3
    assert abs(states[-1].yaw_rad - yaw) < 1e-3


def test_armed_on_the_ground_without_climb_spins_but_stays() -> None:
    vehicle = Multicopter()
    start = vehicle.state.pos_ned_m.copy()
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(vel_ned_m_s=(1.0, 0.0, 0.0)))  # no climb asked: sit on the floor
    states = fly(vehicle, 3.0)
    assert all(s.on_ground for s in states)
    assert states[-1].throttle > 0.0
    assert np.abs(states[-1].pos_ned_m - start).max() < 0.01


def test_descent_lands_and_reports_on_ground(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.7)))
    states = fly(hovering, 5.0)
    landed = [s.on_ground for s in states]
    first = landed.index(True)
    assert all(landed[first:])                    # no bouncing back into the air
    assert abs(states[-1].pos_ned_m[2]) < 0.01
    assert all(not s.on_ground for s in states[:first - 2]) and first * STEP_S > 1.5


@pytest.mark.parametrize("bad", [
    ControlTarget(vel_ned_m_s=(math.nan, 0.0, 0.0)),
    ControlTarget(vel_ned_m_s=(0.0, math.inf, -math.inf), yaw_rad=math.nan),
    ControlTarget(pos_ned_m=(math.nan, math.nan, math.nan), yaw_rate_rad_s=math.inf),
    ControlTarget(vel_ned_m_s=("fast", None, 1), yaw_rad="north"),  # type: ignore[arg-type]
    ControlTarget(vel_ned_m_s=(1.0, 2.0)),  # type: ignore[arg-type]
])
def test_garbage_targets_do_not_crash_or_move(hovering: Multicopter, bad: ControlTarget) -> None:
    before = hovering.state
    hovering.set_target(bad)
    states = fly(hovering, 3.0)
    assert all(np.isfinite(s.pos_ned_m).all() and np.isfinite(s.vel_ned_m_s).all() for s in states)
    assert np.linalg.norm(states[-1].pos_ned_m - before.pos_ned_m) < 0.05
    assert abs(states[-1].yaw_rad - before.yaw_rad) < math.radians(2)


def test_absurd_targets_are_clamped_to_the_limits() -> None:
    gains = load_gains()
    clean = sanitize_target(ControlTarget(vel_ned_m_s=(300.0, 400.0, -99.0), yaw_rad=7.0,
                                          yaw_rate_rad_s=-50.0), gains)
    assert math.hypot(*clean.vel_ned_m_s[:2]) == pytest.approx(gains.limits_horizontal_speed_m_s)
    assert clean.vel_ned_m_s[0] / clean.vel_ned_m_s[1] == pytest.approx(0.75)  # direction kept
    assert clean.vel_ned_m_s[2] == -gains.limits_vertical_speed_m_s
    assert clean.yaw_rad == pytest.approx(7.0 - 2 * math.pi)
    assert clean.yaw_rate_rad_s == pytest.approx(-math.radians(gains.limits_yaw_rate_deg_s))


def test_absurd_velocity_is_flown_at_the_speed_limit(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(1e9, 0.0, 0.0)))
    states = fly(hovering, 6.0)
    top_speed = max(np.linalg.norm(s.vel_ned_m_s[:2]) for s in states)
    assert 4.5 < top_speed < 5.6


def test_step_ignores_bad_durations(hovering: Multicopter) -> None:
    t = hovering.t_s
    for dt in (math.nan, -1.0, 0.0, math.inf):
        hovering.step(dt)
    assert hovering.t_s == t


def test_step_keeps_time_exact_over_odd_durations() -> None:
    vehicle = Multicopter(physics_hz=300.0)
    for _ in range(70):
        vehicle.step(1.0 / 70.0)
    assert vehicle.t_s == pytest.approx(1.0, abs=1.0 / 300.0)


def test_reset_returns_to_start_disarmed(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(1.0, 0.0, 0.0)))
    fly(hovering, 1.0)
    hovering.reset()
    state = hovering.state
    assert state.t_s == 0.0 and not state.armed and state.on_ground
    assert np.abs(state.pos_ned_m).max() < 0.01


def test_geodetic_position_agrees_with_ned(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(pos_ned_m=(3.0, -2.0, -2.5)))
    fly(hovering, 8.0)
    state = hovering.state
    north_m, east_m = geodetic_to_ned_m(state.lat_deg, state.lon_deg, hovering.home_lat_deg, hovering.home_lon_deg)
    assert np.allclose(state.pos_ned_m, (3.0, -2.0, -2.5), atol=0.05)
    assert (north_m, east_m) == pytest.approx((state.pos_ned_m[0], state.pos_ned_m[1]), abs=1e-3)
    assert state.alt_amsl_m == pytest.approx(hovering.home_alt_m + 2.5, abs=0.05)
    assert ned_to_geodetic(north_m, east_m, hovering.home_lat_deg, hovering.home_lon_deg) == pytest.approx(
        (state.lat_deg, state.lon_deg), abs=1e-9)


def test_yaw_turns_the_short_way_across_north_south(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=math.radians(170)))
    fly(hovering, 4.0)
    hovering.set_target(ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=math.radians(-170)))
    states = fly(hovering, 3.0)
    yaws_deg = [math.degrees(s.yaw_rad) for s in states]
    assert all(abs(y) > 150.0 for y in yaws_deg)        # never swung back through north
    assert abs(yaws_deg[-1] + 170.0) < 3.0


def test_position_hold_rejects_a_steady_push(hovering: Multicopter) -> None:
    hold = np.array((0.0, 0.0, CRUISE_DOWN_M))
    hovering.set_target(ControlTarget(pos_ned_m=tuple(hold)))
    hovering.set_disturbance_force_ned_n((0.0, 1.0, 1.0))   # east and down, about 7 % of the weight each
    pushed = fly(hovering, 6.0)
    drift_m = max(np.linalg.norm(s.pos_ned_m - hold) for s in pushed)
    assert 0.05 < drift_m < 0.3                               # it felt the push, and held on
    assert abs(pushed[-1].pos_ned_m[2] - hold[2]) < 0.01       # height: the integrator took the push over
    assert abs(pushed[-1].pos_ned_m[1]) < 0.7 * drift_m        # sideways: slowly (see docs/bench/sim.md)
    hovering.set_disturbance_force_ned_n((math.nan, "x", math.inf))  # type: ignore[arg-type]  # = no push
    fly(hovering, 10.0)
    assert np.linalg.norm(hovering.state.pos_ned_m - hold) < 0.05


def test_repeated_garbage_keeps_the_first_hold_point(hovering: Multicopter) -> None:
    hovering.set_target(ControlTarget(vel_ned_m_s=(1.0, 0.0, 0.0)))
    fly(hovering, 2.0)
    first_garbage_at = hovering.state.pos_ned_m.copy()
    stopped_past_m = 0.0
    for _ in range(round(5.0 / STEP_S)):   # a stream of bad setpoints: hold where the first one came
        hovering.set_target(ControlTarget(vel_ned_m_s=(math.nan, 0.0, 0.0)))
        fly(hovering, STEP_S)
        stopped_past_m = max(stopped_past_m, hovering.state.pos_ned_m[0] - first_garbage_at[0])
    assert stopped_past_m > 0.15                                            # braking from 1 m/s takes room
    assert np.linalg.norm(hovering.state.pos_ned_m - first_garbage_at) < 0.05  # and it came back
