"""Rejection thresholds are data: ``thresholds.toml`` beside this module, per matcher and per engine.

Resolution order (later wins): ``[<matcher>]``, then ``[<matcher>.engine.<engine>]``, then the
options given to ``get_matcher``. Engine evidence (Whisper's ``no_speech_prob``...) lives under
``[evidence.<engine>]`` because it does not depend on the matcher; ``[evidence.<engine>.lang.<lang>]`` for one language.
"""

from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path
from typing import Any

from gcs_voice.errors import GcsVoiceError

__all__ = ["THRESHOLDS_PATH", "ThresholdsError", "load_thresholds", "matcher_thresholds", "evidence_limits",
           "transcript_limits", "ear_limits"]

THRESHOLDS_PATH = Path(__file__).resolve().parent / "thresholds.toml"


class ThresholdsError(GcsVoiceError):
    """The thresholds file is missing or malformed."""


@lru_cache(maxsize=8)
def load_thresholds(path: Path = THRESHOLDS_PATH) -> dict[str, Any]:
    """The whole thresholds table (cached; the file is read once per process)."""
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ThresholdsError(f"{path}: cannot read thresholds: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ThresholdsError(f"{path}: invalid TOML: {exc}") from None


def _numbers(table: dict[str, Any], where: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for key, value in table.items():
        if key in ("engine", "lang"):
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ThresholdsError(f"{THRESHOLDS_PATH}: [{where}] {key} must be a number")
        out[key] = float(value)
    return out


def matcher_thresholds(matcher: str, engine: str | None, path: Path = THRESHOLDS_PATH) -> dict[str, float]:
    """Thresholds for one matcher, with the engine's overrides applied."""
    table = load_thresholds(path).get(matcher, {})
    merged = _numbers(table, matcher)
    if engine:
        merged.update(_numbers(table.get("engine", {}).get(engine, {}), f"{matcher}.engine.{engine}"))
    return merged


def evidence_limits(engine: str | None, path: Path = THRESHOLDS_PATH, lang: str | None = None) -> dict[str, float]:
    """Limits on engine evidence (``Recognition.extra``) for one engine; empty when none are set.

    ``[evidence.<engine>.lang.<lang>]`` overrides them for one language: limits chosen on one language's
    speech need not hold for another's.
    """
    if not engine:
        return {}
    table = load_thresholds(path).get("evidence", {}).get(engine, {})
    limits = _numbers(table, f"evidence.{engine}")
    if lang:
        limits.update(_numbers(table.get("lang", {}).get(lang, {}), f"evidence.{engine}.lang.{lang}"))
    return limits


def transcript_limits(engine: str | None, path: Path = THRESHOLDS_PATH, lang: str | None = None) -> dict[str, float]:
    """Limits on the engine's own transcript (``Recognition.transcript``); empty when none are set.
    ``[transcript.<engine>.lang.<lang>]`` overrides them for one language, as for the evidence."""
    if not engine:
        return {}
    table = load_thresholds(path).get("transcript", {}).get(engine, {})
    limits = _numbers(table, f"transcript.{engine}")
    if lang:
        limits.update(_numbers(table.get("lang", {}).get(lang, {}), f"transcript.{engine}.lang.{lang}"))
    return limits


def ear_limits(engine: str | None, path: Path = THRESHOLDS_PATH, lang: str | None = None) -> dict[str, float]:
    """How the domain ear's evidence weighs in the decision (``[ear.<engine>]``, ``[ear.<engine>.lang.<lang>]``):
    ``vouch``, ``veto``; empty when the engine's decisions take no ear."""
    if not engine:
        return {}
    table = load_thresholds(path).get("ear", {}).get(engine, {})
    limits = _numbers(table, f"ear.{engine}")
    if lang:
        limits.update(_numbers(table.get("lang", {}).get(lang, {}), f"ear.{engine}.lang.{lang}"))
    return limits
