"""Amounts heard by real Whisper (scoring mode) on espeak-ng speech: the amount is acted on only when clear."""

from __future__ import annotations

import pytest

from gcs_voice.asr.registry import load_recognizer
from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import get_matcher
from gcs_voice.domain.amounts import Amount
from tests.asr_speech import pcm_of

EN, ES = load_language("en"), load_language("es")


@pytest.fixture(scope="module")
def whisper_score(whisper_model_dir):
    return load_recognizer("whisper", [EN, ES], model=str(whisper_model_dir), mode="score")


def _decide(recognizer, pcm: bytes, lang: str):
    stream = recognizer.start_stream(lang)
    stream.accept(pcm)
    result = stream.finish()
    return result, get_matcher("phonetic").decide(result, [EN if lang == "en" else ES])


@pytest.mark.slow
@pytest.mark.parametrize(("text", "voice", "lang", "action", "amount"), [
    ("go forward three metres", "en-us", "en", "go_forward", Amount(3, "m")),
    ("turn left forty five degrees", "en-us", "en", "turn_left", Amount(45, "deg")),
    ("go left ten metres", "en-us", "en", "go_left", Amount(10, "m")),
    ("climb to five metres", "en-us", "en", "up", Amount(5, "m", height=True)),
    ("sube a cinco metros", "es", "es", "up", Amount(5, "m", height=True)),
    # Whisper writes "Turn left 100 and 20 degrees." for it: read as 120 (and weighed against "100 and 2")
    ("turn left one hundred and twenty degrees", "en-us", "en", "turn_left", Amount(120, "deg")),
    # Whisper writes "Go to the right for meters.": 'for' before a unit word is the number four
    ("go to the right four metres", "en-us", "en", "go_right", Amount(4, "m")),
    # the command word misheard before its amount ("defend 13 meters.", "Move backwards 10 meters"): the phrases
    # are scored with Whisper's own amount after them, not ended where the speech goes on
    ("descend thirteen metres", "en-us", "en", "down", Amount(13, "m")),
    ("move backward ten metres", "en-us", "en", "go_back", Amount(10, "m")),
])
def test_a_command_with_its_amount(whisper_score, tmp_path, text, voice, lang, action, amount):
    result, decision = _decide(whisper_score, pcm_of(text, tmp_path, voice), lang)
    assert decision.action == action, decision
    assert decision.amount is not None
    assert (decision.amount.value, decision.amount.unit, decision.amount.height) == (
        amount.value, amount.unit, amount.height)
    assert result.extra["amount_gap"] >= 2.0


@pytest.mark.slow
def test_an_amount_that_sounds_like_another_is_weighed_against_it(whisper_score, tmp_path):
    """'fifteen' is scored against 'fifty': acted on only as 15 and only with a clear gap, never as 50."""
    result, decision = _decide(whisper_score, pcm_of("go forward fifteen metres", tmp_path), "en")
    assert result.extra["amount_rival"] == 50.0
    if decision.accepted:
        assert decision.amount is not None and decision.amount.value == 15
        assert result.extra["amount_gap"] >= 2.0
    else:
        assert "unsure of the amount" in decision.reason


@pytest.mark.slow
@pytest.mark.parametrize("text", ["we moved about ten metres", "turn the page forty five degrees",
                                  "the table is two metres", "go home twenty metres"])
def test_other_speech_that_ends_on_an_amount_is_no_command(whisper_score, tmp_path, text):
    """Scored with its amount, a phrase must still be as likely as what Whisper heard: these are not."""
    result, decision = _decide(whisper_score, pcm_of(text, tmp_path), "en")
    assert decision.action is None, (result.transcript, decision)


@pytest.mark.slow
def test_an_amount_out_of_range_is_refused_not_clipped(whisper_score, tmp_path):
    result, decision = _decide(whisper_score, pcm_of("go back fifty metres", tmp_path), "en")
    assert decision.action is None and "out of range" in decision.reason, decision


@pytest.mark.slow
def test_a_plain_command_still_has_no_amount(whisper_score, tmp_path):
    result, decision = _decide(whisper_score, pcm_of("turn left", tmp_path), "en")
    assert decision.action == "turn_left" and decision.amount is None
    assert "amount_gap" not in result.extra


def test_an_unsure_amount_is_no_action() -> None:
    """The decision's own rule, on the evidence the engine gives: a gap below the threshold is 'say again'."""
    from gcs_voice.asr.base import Hypothesis, Recognition

    def recognition(gap: float) -> Recognition:
        extra = {"margin": 0.0, "class_gap": 3.0, "free_logprob": -0.2, "amount_gap": gap, "amount_rival": 50.0}
        return Recognition((Hypothesis("go forward", confidence=1.0, score=-0.1),), "whisper-score", "en", 1.0,
                           extra, transcript="Go forward 15 meters.")

    unsure = get_matcher("phonetic").decide(recognition(0.5), [EN])
    assert unsure.action is None and "unsure of the amount" in unsure.reason and "50" in unsure.reason
    sure = get_matcher("phonetic").decide(recognition(5.0), [EN])
    assert sure.action == "go_forward" and sure.amount == Amount(15, "m", words="15 meters")
    assert sure.label == "go_forward 15 m"
    other_engine = get_matcher("phonetic").decide(
        Recognition((Hypothesis("go forward", confidence=1.0),), "vosk", "en", 1.0, {},
                    transcript="go forward 15 meters"), [EN])
    assert other_engine.action is None
    # a recogniser that writes what it heard (no separate transcript) and puts an amount in it: never open-ended
    heard_only = get_matcher("levenshtein", max_distance=1.0, min_margin=0.0).decide(
        Recognition((Hypothesis("go left two meters", confidence=1.0),), "vosk", "en", 1.0, {}), [EN])
    assert heard_only.action is None and "cannot weigh amounts" in heard_only.reason


def test_a_spanish_distance_down_after_an_elided_a_is_unsure() -> None:
    """'baja a ocho metros' is heard 'baja ocho metros': a distance after 'baja' is asked again, never flown as
    one; after 'desciende' (no 'a' to run into) it is flown."""
    from gcs_voice.asr.base import Hypothesis, Recognition

    def decide(phrase: str, transcript: str):
        extra = {"margin": 0.0, "class_gap": 3.0, "free_logprob": -0.2, "amount_gap": 6.0, "amount_rival": -8.0}
        return get_matcher("phonetic").decide(
            Recognition((Hypothesis(phrase, confidence=1.0, score=-0.1),), "whisper-score", "es", 1.0, extra,
                        transcript=transcript), [ES])

    elided = decide("baja", "Baja ocho metros.")
    assert elided.action is None and "a ocho metros" in elided.reason
    assert decide("baja", "Baja a ocho metros.").amount == Amount(8, "m", height=True, words="a ocho metros")
    assert decide("desciende", "Desciende ocho metros.").amount == Amount(8, "m", words="ocho metros")


@pytest.mark.slow
def test_a_digit_whisper_did_not_write_is_not_flown_open_ended(whisper_score, real_speech_dir):
    """A real "right" and a real "three" after it (tools.speech.bench_amounts_real's splice, held-out speakers): Whisper
    writes "Right." for some. Flown, that motion runs until "stop" where 3 m was asked; the speech after the
    words it wrote (``speech_after_s``) says there was more, and nothing is done. The same "right" alone flies."""
    import numpy as np

    from tools.speech.bench_amounts_real import spliced, voiced
    from tools.speech.make_corpus import read_wav

    command = real_speech_dir / "en" / "go_right" / "sc_right_1ed557b9_nohash_0.wav"
    digit = real_speech_dir / "en" / "_none" / "sc_three_c9b653a0_nohash_2.wav"
    pcm = lambda x: (np.clip(x, -1, 1) * 32767).astype("<i2").tobytes()  # noqa: E731
    result, decision = _decide(whisper_score, pcm(spliced(command, digit, np.zeros(1), 0, "clean")), "en")
    assert result.transcript.lower().startswith("right") and not decision.accepted, (result.transcript, decision)
    assert "more speech" in decision.reason and result.extra["speech_after_s"] > 0.4
    alone = np.concatenate([np.zeros(4800, np.float32), voiced(read_wav(command)), np.zeros(4800, np.float32)])
    result, decision = _decide(whisper_score, pcm(alone), "en")
    assert decision.action == "go_right" and decision.amount is None, (result.transcript, decision)
