"""Real audio through a real engine into every matcher: espeak-ng speech -> PocketSphinx -> decision."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import MATCHERS, get_matcher


from tools.speech import make_corpus

pytestmark = pytest.mark.slow
EN = load_language("en")
VOICE = "en-us+m3"  # a voice PocketSphinx's US model hears reliably (see docs/bench/accuracy.md)


def _pcm(text: str) -> bytes:
    speech = make_corpus.synthesise(text, VOICE, 150, 50)
    speech = speech / np.abs(speech).max() * 0.8
    padded = np.concatenate([np.zeros(4000, np.float32), speech, np.zeros(5600, np.float32)])
    return (padded * 32767).astype("<i2").tobytes()


@pytest.fixture(scope="module")
def heard() -> dict[str, object]:
    if subprocess.run(["espeak-ng", "--version"], capture_output=True).returncode != 0:
        pytest.fail("espeak-ng is required")
    from gcs_voice.asr.registry import load_recognizer

    recognizer = load_recognizer("sphinx", [EN])
    out = {}
    for text in ("go right", "turn right", "move forward", "thank you very much", "the right answer"):
        stream = recognizer.start_stream("en")
        stream.accept(_pcm(text))
        out[text] = stream.finish()
    return out


@pytest.mark.parametrize("name", list(MATCHERS))
@pytest.mark.parametrize(("text", "action"), [("turn right", "turn_right"), ("move forward", "go_forward")])
def test_spoken_command_is_decided(heard, name: str, text: str, action: str) -> None:
    d = get_matcher(name).decide(heard[text], [EN])
    assert d.action == action, f"{text!r} heard as {heard[text].text!r}: {d.reason}"


@pytest.mark.parametrize("name", list(MATCHERS))
def test_unsure_command_is_right_or_nothing(heard, name: str) -> None:
    # Sphinx hears "go right" with a low posterior: the tuned min_confidence may reject it, but it
    # must never become another class.
    d = get_matcher(name).decide(heard["go right"], [EN])
    assert d.action in (None, "go_right"), d
    assert get_matcher(name, min_confidence=0).decide(heard["go right"], [EN]).action == "go_right"


@pytest.mark.parametrize("name", list(MATCHERS))
@pytest.mark.parametrize("text", ["thank you very much", "the right answer"])
def test_spoken_non_command_is_not_acted_on(heard, name: str, text: str) -> None:
    d = get_matcher(name).decide(heard[text], [EN])
    assert d.action is None, f"{text!r} heard as {heard[text].text!r} became {d.action}"
    assert d.reason
