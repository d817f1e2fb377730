"""PocketSphinx engine: dictionary commands from espeak-ng and real recordings; out-of-domain speech
goes to the garbage branch instead of being forced into a command; English only."""

from __future__ import annotations

import logging

import pytest

from gcs_voice.asr.registry import load_recognizer
from gcs_voice.domain.dictionary import load_dictionary, load_language
from gcs_voice.errors import ModelError
from gcs_voice.domain.text import normalize_text
from tests.asr_speech import pcm_of

pytest.importorskip("pocketsphinx")
EN = load_language("en")


@pytest.fixture(scope="module")
def grammar():
    return load_recognizer("sphinx", [EN])


def _recognise(recognizer, pcm):
    stream = recognizer.start_stream("en")
    stream.accept(pcm)
    return stream.finish()


@pytest.mark.parametrize("said", ["go up", "turn left", "turn right", "stop", "go forward", "land"])
def test_commands_are_heard(grammar, tmp_path, said):
    result = _recognise(grammar, pcm_of(said, tmp_path))
    assert normalize_text(result.text) == said
    assert result.extra["out_of_grammar"] == 0.0
    assert 0.0 <= result.best.confidence <= 1.0


@pytest.mark.parametrize("said", ["what time is it", "hello how are you", "open the door", "banana"])
def test_out_of_domain_speech_is_not_forced_into_a_command(grammar, tmp_path, said):
    result = _recognise(grammar, pcm_of(said, tmp_path))
    assert result.hypotheses == ()
    assert result.extra["out_of_grammar"] == 1.0


def test_words_that_sound_like_commands_are_garbage(grammar, tmp_path):
    """The dictionary's not_commands join the garbage branch (engines.toml garbage_not_commands): "four" was
    flown forward; real single words like it were PocketSphinx's most frequent false actions."""
    from gcs_voice.asr.sphinx_engine import SphinxRecognizer
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    four = pcm_of("four", tmp_path)
    assert "four" in grammar.garbage
    assert get_matcher(DEFAULT_MATCHER).decide(_recognise(grammar, four), [EN]).action is None
    without = SphinxRecognizer([EN], settings={"garbage_not_commands": False})
    assert get_matcher(DEFAULT_MATCHER).decide(_recognise(without, four), [EN]).action == "go_forward"


@pytest.mark.parametrize("wpm", [120, pytest.param(150, marks=pytest.mark.xfail(strict=True, reason=(
    "open (issue 10 item 8): exact digital silence sends it to garbage; dither_lsb = 1 fixes it but loses "
    "zero-padded 'turn right' / 'move forward', so the dither ships off"))), 175])
def test_stop_in_exact_digital_silence_is_heard(grammar, tmp_path, wpm):
    """espeak-ng's own WAV (22.05 kHz, exact zeros around the word, no sox dither), as the PX4 flight
    of issue 10 item 8 fed it: "stop" at 150 wpm goes to the garbage branch and the vehicle never
    stopped. Cause: the digital silence (23 % of the samples are exactly 0); the engine's seeded 1-LSB
    fill of zero runs (engines.toml dither_lsb = 1) makes it "stop" at posterior 1.0."""
    import subprocess

    from gcs_voice.audio.sources import read_wav
    from tests.asr_speech import need

    need("espeak-ng")
    wav = tmp_path / f"stop_{wpm}.wav"
    subprocess.run(["espeak-ng", "-v", "en-us", "-s", str(wpm), "-w", str(wav), "stop"], check=True)
    result = _recognise(grammar, read_wav(wav))
    assert result.text == "stop" and result.extra["out_of_grammar"] == 0.0, result


def test_filling_digital_silence_hears_the_150_wpm_stop(tmp_path):
    """The fix that exists (off by default, see engines.toml dither_lsb): same answer twice, "stop"."""
    import subprocess

    from gcs_voice.asr.sphinx_engine import SphinxRecognizer
    from gcs_voice.audio.sources import read_wav
    from tests.asr_speech import need

    need("espeak-ng")
    wav = tmp_path / "stop_150.wav"
    subprocess.run(["espeak-ng", "-v", "en-us", "-s", "150", "-w", str(wav), "stop"], check=True)
    filled = SphinxRecognizer([EN], settings={"dither_lsb": 1})
    first, again = _recognise(filled, read_wav(wav)), _recognise(filled, read_wav(wav))
    assert first.text == "stop" and first == again, first


@pytest.mark.slow
def test_real_recordings(grammar, real_speech_dir):
    """The held-out speakers of ../shared/speech (test split of tools.speech.real_speech, never tuned on) with
    the shipped settings and the default matcher: the rates measured by tools/speech/bench_sphinx_real.py
    (docs/bench/sphinx_real.md). PocketSphinx does NOT meet the 2 % bound on non-commands (no setting
    did, on dev): this pins the measured rates so a change that acts on more other speech or gets
    fewer commands fails, and the bound can only tighten."""
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from tools.speech.bench_sphinx_real import english

    rows = [r for r in english(real_speech_dir) if r.split == "test"]
    matcher = get_matcher(DEFAULT_MATCHER)
    commands = [r for r in rows if r.kind == "command"]
    others = [r for r in rows if r.kind != "command"]
    actions = {r.path: matcher.decide(_recognise(grammar, read_wav(r.path)), [EN]).action for r in rows}
    right = sum(actions[r.path] == r.action for r in commands)
    wrong = [(r.path, actions[r.path]) for r in commands if actions[r.path] not in (None, r.action)]
    acted = [(r.path, actions[r.path]) for r in others if actions[r.path] is not None]
    # measured (docs/bench/sphinx_real.md, phonetic): 72/128 right, 0 wrong, 2/110 non-commands acted on
    # (3/110 before session 18 bounded the speech around the command; 87, 0 and 14 before session 14 added the
    # dictionary's not_commands to the garbage words)
    assert len(commands) == 128 and len(others) == 110
    assert right >= 72, f"{right}/{len(commands)} commands right"
    assert len(wrong) <= 0, wrong
    assert len(acted) <= 2, acted


#: real spoken sentences (Picovoice speech-to-intent set, ../shared/speech) in which the grammar finds a command
#: and reads the rest of the speech as silence
SENTENCES_WITH_A_FORCED_COMMAND = {
    "en/_sentences/pv_df868bf4-3a55-46fb-88a6-1ec2e46c0d14.wav": "go left",  # 6.5 s
    "en/_sentences/pv_b20e2145-1cc2-4656-bf51-d4287a21a56a.wav": "decrease altitude",  # 12.1 s
}


@pytest.mark.parametrize("path", sorted(SENTENCES_WITH_A_FORCED_COMMAND))
def test_speech_around_the_command_is_no_action(grammar, real_speech_dir, path):
    """A command the grammar placed inside longer real speech is no action: the speech said more than a command
    (``[evidence.sphinx] max_speech_beyond_s``)."""
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    result = _recognise(grammar, read_wav(real_speech_dir / path))
    assert normalize_text(result.text) == SENTENCES_WITH_A_FORCED_COMMAND[path]  # what the grammar forced
    assert result.extra["speech_beyond_s"] > 1.5
    decision = get_matcher(DEFAULT_MATCHER).decide(result, [EN])
    assert decision.action is None
    assert "the speech went on" in decision.reason and decision.went_on


def test_a_command_with_a_filler_word_is_still_heard(grammar, tmp_path):
    """The speech bound leaves room for a word around the command ("turn left please")."""
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    result = _recognise(grammar, pcm_of("turn left please", tmp_path))
    assert normalize_text(result.text) == "turn left"
    assert 0.0 < result.extra["speech_beyond_s"] <= 1.5
    assert get_matcher(DEFAULT_MATCHER).decide(result, [EN]).action == "turn_left"


def test_free_mode_gives_open_vocabulary_alternatives(tmp_path):
    free = load_recognizer("sphinx", [EN], mode="free")
    result = _recognise(free, pcm_of("open the door", tmp_path))
    assert len(result.hypotheses) > 1
    assert normalize_text(result.text) == "open the door"
    assert "out_of_grammar" in result.extra


def test_english_only():
    with pytest.raises(ModelError, match="English only"):
        load_recognizer("sphinx", [load_language("es")])


def test_words_without_pronunciation_are_named(tmp_path, caplog):
    path = tmp_path / "odd.toml"
    path.write_text('language = "en"\n[phrases]\nup = ["go up", "zorblax up"]\nstop = ["stop"]\n', encoding="utf-8")
    with caplog.at_level(logging.WARNING, logger="gcs_voice.asr.sphinx_engine"):
        recognizer = load_recognizer("sphinx", [load_dictionary(path)])
    assert recognizer.missing_words == ("zorblax",)
    assert "zorblax" in caplog.text
    assert "zorblax" not in recognizer.jsgf


def test_bad_model_path(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        load_recognizer("sphinx", [EN], model=str(tmp_path / "nope"))
