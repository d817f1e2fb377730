"""Amounts said after a command (issue 33): parsing in English and Spanish, and bounded motions in the mapper."""

from __future__ import annotations

import math

import pytest

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link.state import VehicleState
from gcs_voice.settings import load_settings
from gcs_voice.domain.amounts import Amount, alike, amount_reason, ends_in_number, number_words, split_amount

SETTINGS = load_settings()


@pytest.mark.parametrize("text, lang, command, value, unit, height", [
    ("go forward three metres", "en", "go forward", 3, "m", False),
    ("move left 2 m", "en", "move left", 2, "m", False),
    ("forward 3m", "en", "forward", 3, "m", False),
    ("up one metre", "en", "up", 1, "m", False),
    ("go back twenty meters", "en", "go back", 20, "m", False),
    ("turn left 45 degrees", "en", "turn left", 45, "deg", False),
    ("turn right ninety", "en", "turn right", 90, "", False),
    ("turn left one hundred and twenty degrees", "en", "turn left", 120, "deg", False),
    ("turn right a hundred eighty", "en", "turn right", 180, "", False),
    ("climb to 5 metres", "en", "climb", 5, "m", True),
    ("go up two metres high", "en", "go up", 2, "m", True),
    ("avanza tres metros", "es", "avanza", 3, "m", False),
    ("sube un metro", "es", "sube", 1, "m", False),
    ("ve a la derecha doce metros", "es", "ve a la derecha", 12, "m", False),
    ("gira a la derecha cuarenta y cinco grados", "es", "gira a la derecha", 45, "deg", False),
    ("gira a la izquierda ciento ochenta grados", "es", "gira a la izquierda", 180, "deg", False),
    ("sube a cinco metros", "es", "sube", 5, "m", True),
    ("baja dos metros de altura", "es", "baja", 2, "m", True),
    # as Whisper writes them: a number in digit parts, "for" before a unit word
    ("rotate right 100 and 35 degrees", "en", "rotate right", 135, "deg", False),
    ("turn left 100 and 20 degrees", "en", "turn left", 120, "deg", False),
    ("gira a la derecha ciento 35 grados", "es", "gira a la derecha", 135, "deg", False),
    ("go to the right for meters", "en", "go to the right", 4, "m", False),
    ("up to for meters", "en", "up", 4, "m", True),
    ("go forward for 3 meters", "en", "go forward for", 3, "m", False),
])
def test_amounts_are_read_in_both_languages(text: str, lang: str, command: str, value: int, unit: str,
                                            height: bool) -> None:
    split = split_amount(text, lang)
    assert split.reason == ""
    assert split.command == command
    assert split.amount is not None
    assert (split.amount.value, split.amount.unit, split.amount.height) == (value, unit, height)


@pytest.mark.parametrize("text, lang", [("go forward", "en"), ("ve a la derecha", "es"), ("gira a la izquierda", "es"),
                                        ("turn counterclockwise", "en"), ("go ahead a", "en")])
def test_plain_commands_have_no_amount(text: str, lang: str) -> None:
    split = split_amount(text, lang)
    assert (split.command, split.amount, split.reason) == (text, None, "")


@pytest.mark.parametrize("text, lang, said", [
    ("go forward 500 metres", "en", "out of range"),
    ("go forward twenty one metres", "en", "out of range"),
    ("avanza cincuenta metros", "es", "out of range"),
    ("forward five forty", "en", "unclear amount"),
    ("turn left two hundred degrees", "en", "out of range"),
    ("turn left three degrees", "en", "out of range"),
    ("go forward 4 12 meters", "en", "unclear amount"),    # Whisper's "4 12" for "forward twelve": no guess
    ("turn left 2 100 degrees", "en", "out of range"),
])
def test_unclear_or_out_of_range_amounts_are_refused_not_clipped(text: str, lang: str, said: str) -> None:
    split = split_amount(text, lang)
    assert split.amount is None and said in split.reason


@pytest.mark.parametrize("value, action, reason", [
    (Amount(3, "m"), "turn_left", "not measured in metres"),
    (Amount(45, "deg"), "go_forward", "not measured in degrees"),
    (Amount(5, "m", height=True), "go_left", "a height goes with up or down"),
    (Amount(3, ""), "stop", "takes no amount"),
    (Amount(3, ""), "turn_right", "out of range"),        # "turn right three": 3 degrees is below 5
    (Amount(45, ""), "go_forward", "out of range"),       # "forward forty five": 45 m is beyond 20
])
def test_an_amount_must_fit_its_motion(value: Amount, action: str, reason: str) -> None:
    amount, why = amount_reason(value, action, "en")
    assert amount is None and reason in why


def test_no_unit_means_degrees_for_turns_and_metres_otherwise() -> None:
    assert amount_reason(Amount(90, ""), "turn_right", "en")[0] == Amount(90, "deg")
    assert amount_reason(Amount(3, ""), "go_back", "es")[0] == Amount(3, "m")
    assert Amount(3, "m").label == "3 m" and Amount(45, "deg").label == "45°" and Amount(5, "m", True).label == "to 5 m"


def test_amounts_that_sound_alike_are_known() -> None:
    assert 50 in alike(15, "en") and 15 in alike(50, "en")
    assert 12 in alike(2, "es") and 2 in alike(12, "es")
    assert alike(3, "en") == ()
    # above a hundred, by what follows it: "one hundred and eighty" against "one hundred and eighteen"
    assert 118 in alike(180, "en") and 150 in alike(115, "en") and 116 in alike(160, "es")


def test_for_is_a_number_only_right_before_a_unit() -> None:
    assert split_amount("go forward for", "en").amount is None
    assert split_amount("go forward", "en").amount is None


@pytest.mark.parametrize("lang", ["en", "es"])
def test_every_amount_spelt_in_words_reads_back(lang: str) -> None:
    for value in range(1, 181):
        split = split_amount(f"go {number_words(value, lang)}", lang)
        assert split.amount is not None and split.amount.value == value, (value, split)


# -- bounded motions ---------------------------------------------------------------------------------------------

def at(north: float = 0.0, east: float = 0.0, height: float = 3.0, heading: float = 0.0) -> VehicleState:
    return VehicleState(system_id=1, heading_deg=heading, north_m=north, east_m=east, down_m=-height,
                        home_north_m=0.0, home_east_m=0.0, home_down_m=0.0, last_heard_s=0.0, link_ok=True)


def fly(mapper: ActionMapper, state: VehicleState, seconds: float, dt: float = 0.1) -> VehicleState:
    """A perfect vehicle: follows the setpoint's velocity, then snaps to its holds (what a position controller
    does in the end)."""
    for _ in range(int(seconds / dt)):
        sp = mapper.setpoint(state)
        north, east, down = sp.ned_m_s()
        state = at(state.north_m + north * dt, state.east_m + east * dt, -(state.down_m + down * dt),
                   state.heading_deg)
        if sp.is_stop and mapper.action == "stop":
            return at(sp.hold_north_m, sp.hold_east_m, -sp.hold_down_m, state.heading_deg)
    return state


@pytest.mark.parametrize("heading", [0.0, 30.0, 270.0])
@pytest.mark.parametrize("action, forward, right", [("go_forward", 1, 0), ("go_back", -1, 0), ("go_right", 0, 1),
                                                    ("go_left", 0, -1)])
def test_a_bounded_move_ends_by_itself_holding_its_target(action: str, forward: int, right: int,
                                                          heading: float) -> None:
    mapper = ActionMapper(SETTINGS)
    start = at(1.0, 2.0, heading=heading)
    mapped = mapper.apply(action, start, Amount(3, "m"))
    assert mapped.amount == "3 m" and not mapped.refused
    moving = mapper.setpoint(start)
    assert math.hypot(moving.forward_m_s, moving.right_m_s) == pytest.approx(SETTINGS.horizontal_speed_m_s)
    end = fly(mapper, start, 60.0)
    assert mapper.action == "stop" and mapper.bound is None
    yaw = math.radians(heading)
    want = (1.0 + 3 * (forward * math.cos(yaw) - right * math.sin(yaw)),
            2.0 + 3 * (forward * math.sin(yaw) + right * math.cos(yaw)))
    assert mapper.hold_point == pytest.approx(want, abs=1e-9)   # the target itself, not where it stopped
    assert (end.north_m, end.east_m) == pytest.approx(want, abs=1e-9)
    assert any("3 m reached" in e for e in mapper.events)


def test_up_down_and_height_targets() -> None:
    mapper = ActionMapper(SETTINGS)
    state = fly(mapper, at(height=3.0), 0.0)
    mapper.apply("up", state, Amount(2, "m"))
    state = fly(mapper, state, 60.0)
    assert state.height_m == pytest.approx(5.0) and mapper.action == "stop"
    mapper.apply("down", state, Amount(2, "m", height=True))
    state = fly(mapper, state, 60.0)
    assert state.height_m == pytest.approx(2.0) and mapper.action == "stop"
    refused = mapper.apply("up", state, Amount(1, "m", height=True))
    assert "that is down" in refused.refused and mapper.action == "stop"


def test_a_bounded_turn_turns_by_the_amount() -> None:
    mapper = ActionMapper(SETTINGS)
    assert mapper.apply("turn_left", at(heading=10.0), Amount(45, "deg")).yaw_target_deg == pytest.approx(325.0)
    assert mapper.apply("turn_right", at(heading=325.0), Amount(180, "deg")).yaw_target_deg == pytest.approx(145.0)
    assert mapper.apply("turn_right", at(heading=145.0)).yaw_target_deg == pytest.approx(235.0)  # plain: 90


@pytest.mark.parametrize("state, action, amount, reason", [
    (at(north=18.0), "go_forward", Amount(3, "m"), "beyond the fence"),
    (at(height=9.0), "up", Amount(2, "m"), "above the ceiling"),
    (at(height=3.0), "up", Amount(11, "m", height=True), "above the ceiling"),
    (at(height=2.0), "down", Amount(2, "m"), "below the floor"),
    (VehicleState(system_id=1, heading_deg=0.0, last_heard_s=0.0, link_ok=True), "go_left", Amount(2, "m"),
     "position unknown"),
])
def test_an_amount_that_crosses_a_limit_is_refused_and_nothing_changes(state: VehicleState, action: str,
                                                                       amount: Amount, reason: str) -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_right", state)
    mapped = mapper.apply(action, state, amount)
    assert reason in mapped.refused
    assert mapper.action == "go_right" and mapper.bound is None


def test_stop_and_any_new_command_end_a_bounded_motion() -> None:
    mapper = ActionMapper(SETTINGS)
    state = at()
    mapper.apply("go_forward", state, Amount(10, "m"))
    state = fly(mapper, state, 2.0)
    mapper.apply("stop", state)
    assert mapper.bound is None and mapper.setpoint(state).is_stop
    assert mapper.hold_point == pytest.approx((state.north_m, state.east_m))
    mapper.apply("go_forward", state, Amount(10, "m"))
    mapper.apply("go_left", state)            # open-ended again: runs until the next command
    assert mapper.bound is None
    far = fly(mapper, state, 20.0)
    assert mapper.action == "go_left" and far.east_m < state.east_m - 9.0


def test_plain_motions_are_unchanged() -> None:
    mapper = ActionMapper(SETTINGS)
    mapper.apply("go_forward", at())
    state = fly(mapper, at(), 30.0)
    assert mapper.action == "go_forward" and mapper.bound is None and state.north_m > 10.0


def test_a_paused_bounded_motion_resumes_toward_the_same_target() -> None:
    """While an utterance is decided the vehicle holds; speech that was no command resumes the bounded motion
    (not an open-ended one), and it still ends at its target."""
    mapper = ActionMapper(SETTINGS)
    state = at()
    mapper.apply("go_right", state, Amount(4, "m"))
    state = fly(mapper, state, 2.0)
    assert mapper.pause(state) == "go_right" and mapper.setpoint(state).is_stop and mapper.bound is None
    assert mapper.resume(state) == "go_right" and mapper.bound is not None
    end = fly(mapper, state, 60.0)
    assert mapper.action == "stop" and (end.north_m, end.east_m) == pytest.approx((0.0, 4.0), abs=1e-9)
    mapper.apply("go_right", end, Amount(2, "m"))
    mapper.pause(end)
    mapper.forget_pause()
    mapper.apply("stop", end)                 # a stop decided during the pause: the target is forgotten
    assert mapper.bound is None and mapper.paused_bound is None


@pytest.mark.parametrize(("text", "lang", "ends"), [
    ("turn left one hundred and", "en", True),       # the number is still being said
    ("go forward 3 meters", "en", True),
    ("go to the right for", "en", True),             # "for" may be Whisper's four before a unit
    ("may i have a 16 ounce dark", "en", False),     # a number, then words no amount uses
    ("i m going to go to the other", "en", False),
    ("gira a la derecha cuarenta y", "es", True),
    ("avanza tres metros", "es", True),
    ("quiero un cafe con leche", "es", False),
])
def test_a_transcript_ends_in_a_number_only_when_an_amount_is_being_said(text: str, lang: str, ends: bool) -> None:
    """What tells Whisper's free pass to read on for an amount (gcs_voice/asr/whisper_score.py, _may_say_more)."""
    assert ends_in_number(text, lang) is ends
