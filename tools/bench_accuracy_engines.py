"""Which recognisers the accuracy benchmark runs, and how they are loaded (the voice-asr registry).

Engine options live here, in one table, so that the cache file records exactly what was measured.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
WHISPER_MODEL = REPO.parent / "shared" / "models" / "faster-whisper-base"

#: engine -> options given to the registry (recorded in the cache next to the recognitions).
OPTIONS: dict[str, dict[str, object]] = {
    "sphinx": {},
    "whisper": {"model": str(WHISPER_MODEL)},
    "vosk": {},
}


def config(engine: str) -> dict[str, object]:
    return {"engine": engine, **OPTIONS.get(engine, {})}


def supports(engine: str, lang: str) -> bool:
    """Whether this engine has a model for ``lang`` on this machine (sphinx: English only here)."""
    if engine == "sphinx":
        return lang == "en"
    if engine == "whisper":
        return WHISPER_MODEL.is_dir()
    if engine == "vosk":
        return _vosk_has(lang)
    return False


def _vosk_has(lang: str) -> bool:
    try:
        from gcs_voice.asr import vosk_engine  # type: ignore[attr-defined]
    except ImportError:
        return False
    finder = getattr(vosk_engine, "find_model", None)
    if finder is None:
        return False
    try:
        return finder(lang) is not None
    except Exception:  # noqa: BLE001 - "no model" comes in many shapes; the benchmark only skips
        return False


def load(engine: str, lang: str):
    """A loaded Recognizer for ``engine`` (voice-asr registry), ready for ``start_stream(lang)``."""
    from gcs_voice import asr

    getter = getattr(asr, "get_recognizer", None)
    if getter is None or importlib.util.find_spec("gcs_voice.asr") is None:
        raise SystemExit("bench_accuracy: gcs_voice.asr has no engine registry yet (merge voice-asr)")
    return getter(engine, languages=(lang,), **OPTIONS.get(engine, {}))
