"""ActionMapper: direction of every class at several headings, turn accumulation, floor, ceiling, fence, NaN."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from gcs_voice.actions.mapper import ActionMapper, UnknownActionError
from gcs_voice.domain.dictionary import ACTIONS, FLIGHT_ACTIONS
from gcs_voice.link.state import VehicleState
from gcs_voice.settings import load_settings

SETTINGS = load_settings()
H, V = SETTINGS.horizontal_speed_m_s, SETTINGS.vertical_speed_m_s


def flying(heading_deg: float = 0.0, height_m: float = 3.0, north_m: float = 0.0, east_m: float = 0.0) -> VehicleState:
    return VehicleState(system_id=1, heading_deg=heading_deg, north_m=north_m, east_m=east_m, down_m=-height_m,
                        home_north_m=0.0, home_east_m=0.0, home_down_m=0.0, last_heard_s=0.0, link_ok=True)


# (action, forward, right) -> direction in the body frame of the heading target
BODY = {"go_forward": (1, 0), "go_back": (-1, 0), "go_right": (0, 1), "go_left": (0, -1)}


@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 90.0, 180.0, 271.5])
@pytest.mark.parametrize("action", sorted(BODY))
def test_horizontal_moves_keep_heading(action: str, heading_deg: float) -> None:
    mapper = ActionMapper(SETTINGS)
    state = flying(heading_deg)
    mapped = mapper.apply(action, state)
    sp = mapper.setpoint(state)
    forward, right = BODY[action]
    yaw = math.radians(heading_deg)
    expected_north = H * (forward * math.cos(yaw) - right * math.sin(yaw))
    expected_east = H * (forward * math.sin(yaw) + right * math.cos(yaw))
    assert sp.ned_m_s() == pytest.approx((expected_north, expected_east, 0.0), abs=1e-9)
    assert sp.yaw_deg == pytest.approx(heading_deg) == mapped.yaw_target_deg
    assert mapped.flight_operation is None and mapper.limit_reason == ""


def test_go_right_at_heading_90_flies_south() -> None:
    mapper = ActionMapper(SETTINGS)
    state = flying(90.0)
    mapper.apply("go_right", state)
    north, east, down = mapper.setpoint(state).ned_m_s()
    assert north == pytest.approx(-H) and abs(east) < 1e-12 and down == 0.0


@pytest.mark.parametrize(("action", "down_m_s"), [("up", -V), ("down", V), ("stop", 0.0)])
def test_vertical_and_stop(action: str, down_m_s: float) -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_forward", flying(10.0))
    mapper.apply(action, flying(50.0))  # heading moved, target did not
    sp = mapper.setpoint(flying(50.0))
    assert (sp.forward_m_s, sp.right_m_s, sp.down_m_s) == (0.0, 0.0, down_m_s)
    assert sp.yaw_deg == 10.0


def test_turns_accumulate_from_the_target_not_the_heading() -> None:
    mapper = ActionMapper(SETTINGS)
    assert mapper.apply("turn_right", flying(10.0)).yaw_target_deg == 100.0
    assert mapper.apply("turn_right", flying(40.0)).yaw_target_deg == 190.0  # vehicle still turning
    assert mapper.apply("turn_left", flying(150.0)).yaw_target_deg == 100.0
    for _ in range(3):
        mapper.apply("turn_left", flying(0.0))
    assert mapper.yaw_target_deg == pytest.approx(190.0)
    sp = mapper.setpoint(flying(0.0))
    assert sp.is_stop and sp.yaw_deg == pytest.approx(190.0)
    mapper.apply("go_forward", flying(190.0))
    north, east, _ = mapper.setpoint(flying(190.0)).ned_m_s()
    assert north == pytest.approx(H * math.cos(math.radians(190))) and east == pytest.approx(H * math.sin(math.radians(190)))


def test_down_stops_itself_at_the_floor() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("down", flying(height_m=2.0))
    for height in (2.0, 1.2, 0.51):
        assert mapper.setpoint(flying(height_m=height)).down_m_s == V
    sp = mapper.setpoint(flying(height_m=0.5))
    assert sp.is_stop and mapper.action == "stop" and "floor" in mapper.events[-1]
    assert mapper.setpoint(flying(height_m=1.0)).is_stop  # stays stopped: the action became stop
    mapper.apply("down", flying(height_m=0.4))
    assert mapper.setpoint(flying(height_m=0.4)).is_stop
    mapper.apply("up", flying(height_m=0.4))
    assert mapper.setpoint(flying(height_m=0.4)).down_m_s == -V


def test_down_stops_above_a_table_seen_by_the_rangefinder() -> None:
    mapper = ActionMapper(SETTINGS)
    over_table = replace(flying(height_m=1.5), ground_clearance_m=0.8)
    mapper.apply("down", over_table)
    assert mapper.setpoint(over_table).down_m_s == V
    sp = mapper.setpoint(replace(flying(height_m=1.2), ground_clearance_m=0.5))
    assert sp.is_stop and "rangefinder" in mapper.events[-1]
    mapper.apply("down", flying(height_m=1.2))  # no rangefinder reading (stale): home height rules
    assert mapper.setpoint(flying(height_m=1.2)).down_m_s == V


def test_ceiling_zeroes_only_the_climb() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("up", flying(height_m=SETTINGS.ceiling_m - 0.1))
    assert mapper.setpoint(flying(height_m=SETTINGS.ceiling_m - 0.1)).down_m_s == -V
    sp = mapper.setpoint(flying(height_m=SETTINGS.ceiling_m))
    assert sp.down_m_s == 0.0 and "ceiling" in mapper.limit_reason
    mapper.apply("down", flying(height_m=SETTINGS.ceiling_m + 1))
    assert mapper.setpoint(flying(height_m=SETTINGS.ceiling_m + 1)).down_m_s == V  # coming back is allowed


def test_on_change_is_called_once_per_automatic_stop_and_per_new_limit() -> None:
    """The session loop sleeps until this wakes it: a change said once, nothing for a setpoint that changes nothing."""
    mapper = ActionMapper(SETTINGS)
    changes: list[tuple[str, str]] = []
    mapper.on_change = lambda: changes.append((mapper.action, mapper.limit_reason))
    mapper.apply("up", flying(height_m=SETTINGS.ceiling_m))
    for _ in range(3):
        mapper.setpoint(flying(height_m=SETTINGS.ceiling_m))
    assert changes == [("up", f"ceiling {SETTINGS.ceiling_m:g} m")]
    mapper.apply("down", flying(height_m=2.0))
    mapper.setpoint(flying(height_m=2.0))   # the limit is gone: said too (the loop forgets it)
    mapper.setpoint(flying(height_m=0.5))
    mapper.setpoint(flying(height_m=0.5))
    assert changes[1:] == [("down", ""), ("stop", "")] and "floor" in mapper.events[-1]


def test_fence_blocks_outward_motion_only() -> None:
    r = SETTINGS.fence_radius_m
    mapper = ActionMapper(SETTINGS)
    at_edge = flying(0.0, north_m=r + 0.1)
    mapper.apply("go_forward", at_edge)  # heading north, already north of the fence
    sp = mapper.setpoint(at_edge)
    assert sp.is_stop and "fence" in mapper.limit_reason
    mapper.apply("go_back", at_edge)  # back toward home
    assert mapper.setpoint(at_edge).forward_m_s == -H and mapper.limit_reason == ""
    mapper.apply("go_right", at_edge)  # east, tangential at the edge: not outward
    sp = mapper.setpoint(at_edge)
    assert sp.right_m_s == H  # exactly tangential is not outward
    inside = flying(0.0, north_m=r - 1.0)
    mapper.apply("go_forward", inside)
    assert mapper.setpoint(inside).forward_m_s == H


def test_unknown_height_or_position_commands_nothing_unsafe() -> None:
    mapper = ActionMapper(SETTINGS)
    blind = VehicleState(system_id=1, heading_deg=0.0, last_heard_s=0.0, link_ok=True)
    for action in ("up", "down", "go_forward"):
        mapper.apply(action, blind)
        assert mapper.setpoint(blind).is_stop, action


def test_nan_never_leaves_the_mapper() -> None:
    mapper = ActionMapper(SETTINGS)
    nan_state = replace(flying(), heading_deg=math.nan, north_m=math.nan, down_m=math.inf)
    for action in ("go_forward", "turn_right", "up", "down", "stop"):
        mapper.apply(action, nan_state)
        sp = mapper.setpoint(nan_state)
        assert all(math.isfinite(v) for v in (sp.forward_m_s, sp.right_m_s, sp.down_m_s, sp.yaw_deg))
    assert mapper.yaw_target_deg == 90.0  # NaN heading -> 0 deg target, then one turn_right


def test_link_loss_turns_the_action_into_stop() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_forward", flying(45.0))
    lost = replace(flying(45.0), link_ok=False)
    assert mapper.setpoint(lost).is_stop and mapper.action == "stop"
    assert mapper.setpoint(flying(45.0)).is_stop  # back: still a stop until the next command


def test_flight_actions_and_unknown_ids() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_left", flying())
    for action in FLIGHT_ACTIONS:
        mapped = mapper.apply(action, flying())
        assert mapped.flight_operation == action and mapper.action == "stop"
    assert set(ACTIONS) >= {"take_off", "land", "arm", "disarm"}
    with pytest.raises(UnknownActionError):
        mapper.apply("barrel_roll", flying())


def test_stop_holds_where_it_was_heard_and_motions_hold_their_height() -> None:
    mapper = ActionMapper(SETTINGS)
    hover = flying(height_m=2.0, north_m=1.0, east_m=-1.0)
    first = mapper.setpoint(hover)   # after take-off: hold here
    assert (first.hold_north_m, first.hold_east_m, first.hold_down_m) == (1.0, -1.0, -2.0)
    mapper.apply("go_forward", hover)
    moving = mapper.setpoint(flying(height_m=1.7, north_m=2.0, east_m=-1.0))   # sinking: the height is held
    assert moving.holds == (False, False, True) and moving.hold_down_m == -2.0
    heard = flying(height_m=1.9, north_m=3.2, east_m=-0.9)
    mapper.apply("stop", heard)
    later = mapper.setpoint(flying(height_m=1.9, north_m=3.9, east_m=-0.9))   # overshoot: back to the stop point
    assert (later.hold_north_m, later.hold_east_m, later.hold_down_m) == (3.2, -0.9, -2.0)
    assert later.is_stop
    mapper.apply("turn_right", flying(north_m=3.5, east_m=-0.9))   # a turn keeps the stop's point
    turning = mapper.setpoint(hover)
    assert (turning.hold_north_m, turning.hold_east_m, turning.hold_down_m) == (3.2, -0.9, -2.0)
    assert turning.yaw_deg == pytest.approx(SETTINGS.turn_step_deg)


def test_vertical_motion_holds_its_point_and_the_new_height_is_kept() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("stop", flying(height_m=2.0, north_m=5.0, east_m=5.0))
    mapper.apply("up", flying(height_m=2.0, north_m=5.1, east_m=5.0))
    climbing = mapper.setpoint(flying(height_m=2.5, north_m=5.2, east_m=5.0))
    assert climbing.holds == (True, True, False) and (climbing.hold_north_m, climbing.hold_east_m) == (5.0, 5.0)
    assert climbing.down_m_s == pytest.approx(-V)
    mapper.apply("go_left", flying(height_m=3.0, north_m=5.0, east_m=5.0))
    assert mapper.setpoint(flying(height_m=2.8)).hold_down_m == -3.0   # where the climb ended


def test_floor_and_link_loss_stops_hold_the_position_they_stopped_at() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("down", flying(height_m=2.0, north_m=1.0, east_m=1.0))
    at_floor = flying(height_m=SETTINGS.floor_m - 0.01, north_m=1.0, east_m=1.0)
    stopped = mapper.setpoint(at_floor)
    assert mapper.action == "stop" and stopped.hold_down_m == pytest.approx(at_floor.down_m)
    mapper.apply("go_back", flying(height_m=0.5, north_m=1.0, east_m=1.0))
    lost = replace(flying(height_m=0.5, north_m=0.4, east_m=1.0), link_ok=False)
    held = mapper.setpoint(lost)
    assert mapper.action == "stop" and (held.hold_north_m, held.hold_east_m) == (0.4, 1.0)


def test_unknown_position_holds_nothing() -> None:
    mapper = ActionMapper(SETTINGS)
    blind = VehicleState(system_id=1, heading_deg=0.0, last_heard_s=0.0, link_ok=True)
    mapper.apply("stop", blind)
    assert mapper.setpoint(blind).holds == (False, False, False)


def test_pause_holds_a_moving_vehicle_and_resume_goes_on_with_the_same_motion() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_forward", flying(90.0, height_m=2.0))
    assert mapper.pause(flying(90.0, height_m=2.0, north_m=0.0, east_m=1.2)) == "go_forward"
    held = mapper.setpoint(flying(90.0, height_m=2.0, north_m=0.0, east_m=1.5))   # overshoot: back to the pause point
    assert held.is_stop and (held.hold_north_m, held.hold_east_m) == (0.0, 1.2) and mapper.paused == "go_forward"
    assert mapper.resume(flying(90.0, height_m=2.0, east_m=1.3)) == "go_forward"
    moving = mapper.setpoint(flying(90.0, height_m=2.0, east_m=1.3))
    assert moving.forward_m_s == pytest.approx(H) and moving.yaw_deg == pytest.approx(90.0) and mapper.paused is None
    assert mapper.resume(flying(90.0)) is None   # once


@pytest.mark.parametrize("action", ["stop", "turn_right", "turn_left"])
def test_pause_leaves_alone_what_does_not_move_the_vehicle(action: str) -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply(action, flying())
    assert mapper.pause(flying()) is None and mapper.action == action and mapper.paused is None


def test_a_decided_action_or_an_automatic_stop_ends_the_pause() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_left", flying())
    mapper.pause(flying())
    mapper.apply("stop", flying())   # the decision was a stop: nothing to resume any more
    assert mapper.paused is None and mapper.resume(flying()) is None and mapper.setpoint(flying()).is_stop
    mapper.apply("up", flying())
    mapper.pause(flying())
    mapper.setpoint(replace(flying(), link_ok=False))   # the link was lost while paused
    assert mapper.paused is None and mapper.resume(flying()) is None and mapper.setpoint(flying()).is_stop
    mapper.apply("down", flying())
    mapper.pause(flying())
    mapper.halt()   # Ctrl-C while paused
    assert mapper.resume(flying()) is None and mapper.setpoint(flying()).is_stop
    assert mapper.pause(flying()) is None


def test_a_resumed_descent_still_stops_at_the_floor() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("down", flying(height_m=2.0))
    mapper.pause(flying(height_m=1.0))
    assert mapper.forget_pause() == "down" and mapper.resume(flying(height_m=1.0)) is None   # stayed stopped
    mapper.apply("down", flying(height_m=1.0))
    mapper.pause(flying(height_m=0.6))
    mapper.resume(flying(height_m=0.6))
    assert mapper.setpoint(flying(height_m=0.6)).down_m_s == pytest.approx(V)
    assert mapper.setpoint(flying(height_m=SETTINGS.floor_m - 0.01)).is_stop and mapper.action == "stop"


@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 200.0])
def test_return_home_flies_straight_home_at_its_height_and_holds_there(heading_deg: float) -> None:
    """return_home_lands = 0: a bounded motion toward home (whatever the heading), the height held, ending by
    itself at home with a hold there; the heading is kept."""
    mapper = ActionMapper(SETTINGS)
    away = flying(heading_deg, height_m=2.0, north_m=3.0, east_m=-4.0)
    mapper.setpoint(away)
    mapped = mapper.apply("return_home", away)
    assert mapped.flight_operation is None and mapped.refused == "" and mapped.amount == "5.0 m"
    sp = mapper.setpoint(away)
    north, east, down = sp.ned_m_s()
    assert (north, east) == pytest.approx((-3.0 / 5.0 * H, 4.0 / 5.0 * H)) and down == 0.0
    assert sp.hold_down_m == -2.0 and sp.yaw_deg == pytest.approx(heading_deg)
    near = flying(heading_deg, height_m=2.0, north_m=0.3, east_m=-0.4)   # 0.5 m to go: slowing down
    assert math.hypot(*mapper.setpoint(near).ned_m_s()[:2]) == pytest.approx(0.5, abs=0.01)
    home = flying(heading_deg, height_m=2.0, north_m=0.01, east_m=-0.02)
    held = mapper.setpoint(home)
    assert held.is_stop and (held.hold_north_m, held.hold_east_m) == (0.0, 0.0) and mapper.action == "stop"
    assert any("home reached" in e for e in mapper.events)


def test_return_home_ends_with_stop_refuses_without_a_position_and_is_a_stop_at_home() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("return_home", flying(north_m=5.0))
    mapper.apply("stop", flying(north_m=4.0))
    assert mapper.setpoint(flying(north_m=4.0)).is_stop and mapper.bound is None
    lost = replace(flying(), north_m=math.nan)
    assert "position unknown" in mapper.apply("return_home", lost).refused
    at_home = mapper.apply("return_home", flying(north_m=0.02))
    assert at_home.action == "stop" and at_home.amount == "home"
