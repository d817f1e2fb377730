"""Recogniser engines by name, imported only when used (Gymnasium-style ``"module:Class"`` strings).

``gcs-voice --help`` therefore never loads CTranslate2, Kaldi or PocketSphinx. Adding an engine is
one module plus one line in :data:`ENGINES`.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Sequence

from gcs_voice.asr.base import Recognizer
from gcs_voice.domain.dictionary import Dictionary
from gcs_voice.errors import GcsVoiceError, ModelError

__all__ = ["ENGINES", "ENGINE_PACKAGES", "MODES", "UnknownEngineError", "load_recognizer",
           "available_engines", "default_engine", "default_mode"]

#: engine name -> "module:Class"; the class has ``load(dictionaries, model, mode) -> Recognizer``.
ENGINES: dict[str, str] = {
    "vosk": "gcs_voice.asr.vosk_engine:VoskRecognizer",
    "whisper": "gcs_voice.asr.whisper_engine:WhisperRecognizer",
    "sphinx": "gcs_voice.asr.sphinx_engine:SphinxRecognizer",
}
#: The Python package each engine needs.
ENGINE_PACKAGES: dict[str, str] = {"vosk": "vosk", "whisper": "faster_whisper", "sphinx": "pocketsphinx"}
#: "grammar": decode only dictionary words (plus an unknown/garbage path); "free": open vocabulary.
#: "score" (Whisper only): every dictionary phrase scored by the decoder, free decoding as evidence.
MODES = ("grammar", "free", "score")


class UnknownEngineError(GcsVoiceError):
    """The user named an engine that is not registered."""


def _engine_class(engine: str):
    try:
        target = ENGINES[engine]
    except KeyError:
        raise UnknownEngineError(f"unknown engine {engine!r} (known: {', '.join(ENGINES)})") from None
    package = ENGINE_PACKAGES[engine]
    if importlib.util.find_spec(package) is None:
        raise ModelError(f"engine {engine!r} needs the Python package {package!r}: pip install {package}")
    module_name, class_name = target.split(":")
    return getattr(importlib.import_module(module_name), class_name)


def default_mode(engine: str) -> str:
    """The engine's best mode on the accuracy benchmark (``default_mode`` in asr/engines.toml)."""
    from gcs_voice.asr.settings import engine_settings

    return str(engine_settings(engine).get("default_mode", "grammar")) if engine in ENGINES else "grammar"


def load_recognizer(
    engine: str, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str | None = None
) -> Recognizer:
    """Load ``engine`` once for these dictionaries; ``model`` is a path (or a Whisper size name).

    ``mode`` None = the engine's :func:`default_mode`.
    """
    if mode is None:
        mode = default_mode(engine)
    if mode not in MODES:
        raise GcsVoiceError(f"unknown recognition mode {mode!r} (known: {', '.join(MODES)})")
    if mode == "score" and engine != "whisper":
        raise GcsVoiceError(f"mode 'score' needs the whisper engine, not {engine!r}")
    if not dictionaries:
        raise GcsVoiceError("a recogniser needs at least one dictionary")
    return _engine_class(engine).load(list(dictionaries), model=model, mode=mode)


def available_engines() -> dict[str, str | None]:
    """Engine name -> None when its package is installed, else the reason it cannot run."""
    out: dict[str, str | None] = {}
    for name, package in ENGINE_PACKAGES.items():
        out[name] = None if importlib.util.find_spec(package) else f"Python package {package!r} not installed"
    return out


def default_engine(lang: str) -> str:
    """Vosk when a model for ``lang`` is found; else Whisper when a model is found; else Sphinx (English).

    The order is the accuracy benchmark's (docs/bench/accuracy.md): Whisper base hears far more
    commands right than PocketSphinx (real voices 66/75 vs 33/75) at ~1 s per command instead of
    ~0.1 s; PocketSphinx needs nothing beyond pip. ``lang`` "auto" needs a multilingual engine: Whisper.
    """
    from gcs_voice.asr import models
    from gcs_voice.asr.settings import engine_settings

    if lang != "auto" and models.find_vosk_model(lang) is not None:
        return "vosk"
    if models.find_whisper_model(None, engine_settings("whisper").get("model_dirs")) is not None:
        return "whisper"
    if lang == "en":
        return "sphinx"
    if lang == "auto":
        raise ModelError("--lang auto needs a Whisper model: set GCS_VOICE_WHISPER_MODEL or pass "
                         "--engine whisper --model PATH")
    raise ModelError(models.vosk_model_hint(lang) + "; or use --engine whisper --model PATH")
