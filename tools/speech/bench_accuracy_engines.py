"""Which recognisers the accuracy benchmark runs, and how they are loaded (the voice-asr registry).

A benchmark engine label is an (engine, mode) pair: "sphinx" = PocketSphinx with the dictionary
grammar plus garbage words, "sphinx-free" = its open n-gram LM, "whisper" = faster-whisper base.
Options live in this one table so that the cache records exactly what was measured.
"""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
WHISPER_MODEL = REPO.parent / "shared" / "models" / "faster-whisper-base"

#: label -> registry arguments (engine, model, mode).
ENGINES: dict[str, dict[str, str | None]] = {
    "sphinx": {"engine": "sphinx", "model": None, "mode": "grammar"},
    "sphinx-free": {"engine": "sphinx", "model": None, "mode": "free"},
    "whisper": {"engine": "whisper", "model": str(WHISPER_MODEL), "mode": "grammar"},
    "whisper-free": {"engine": "whisper", "model": str(WHISPER_MODEL), "mode": "free"},
    "whisper-score": {"engine": "whisper", "model": str(WHISPER_MODEL), "mode": "score"},
    "vosk": {"engine": "vosk", "model": None, "mode": "grammar"},
}


def config(label: str) -> dict[str, str | None]:
    return dict(ENGINES[label])


def supports(label: str, lang: str) -> bool:
    """Whether this engine has a model for ``lang`` here (sphinx: English only; vosk: a found model)."""
    engine = ENGINES[label]["engine"]
    if engine == "sphinx":
        return lang == "en"
    if engine == "whisper":
        return WHISPER_MODEL.is_dir()
    if engine == "vosk":
        from gcs_voice.asr import models

        return models.find_vosk_model(lang) is not None
    return False


def load(label: str, lang: str):
    """A loaded Recognizer for one language, ready for ``start_stream(lang)``."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language

    c = ENGINES[label]
    return load_recognizer(c["engine"], [load_language(lang)], model=c["model"], mode=c["mode"])
