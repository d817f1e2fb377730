"""Recogniser settings live in ``engines.toml`` beside this module: one table per engine."""

from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path
from typing import Any

from gcs_voice.errors import ModelError

__all__ = ["SETTINGS_PATH", "engine_settings"]

SETTINGS_PATH = Path(__file__).resolve().parent / "engines.toml"


@lru_cache(maxsize=1)
def _load(path: Path = SETTINGS_PATH) -> dict[str, Any]:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ModelError(f"{path}: cannot read recogniser settings: {exc}") from None


def engine_settings(engine: str) -> dict[str, Any]:
    """The ``[engine]`` table (a copy: callers may change it)."""
    return dict(_load().get(engine, {}))
