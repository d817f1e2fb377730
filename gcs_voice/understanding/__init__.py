"""Matchers: turn what a recogniser heard into one action class, or *no action* with the reason.

Matchers are registered by name as lazy ``"module:Class"`` strings (as Gymnasium registers
environments), so importing this package loads nothing heavy. ``get_matcher(name, **options)``
builds one; options override the rejection thresholds read from ``thresholds.toml``.
"""

from __future__ import annotations

import importlib

from gcs_voice.errors import GcsVoiceError
from gcs_voice.understanding.matcher import Matcher

__all__ = ["MATCHERS", "DEFAULT_MATCHER", "Matcher", "get_matcher", "UnknownMatcherError"]

#: name -> "module:Class"; the class is imported only when the matcher is asked for.
MATCHERS: dict[str, str] = {
    "exact": "gcs_voice.understanding.exact:ExactMatcher",
    "levenshtein": "gcs_voice.understanding.levenshtein:LevenshteinMatcher",
    "phonetic": "gcs_voice.understanding.phonetic:PhoneticMatcher",
}

#: The matcher used when none is named (chosen by tools/speech/bench_accuracy.py, see docs/bench/accuracy.md).
DEFAULT_MATCHER = "phonetic"


class UnknownMatcherError(GcsVoiceError):
    """The user named a matcher that is not registered."""


def get_matcher(name: str, **options: object) -> Matcher:
    """Build the matcher registered as ``name``; ``options`` override its thresholds (see thresholds.toml)."""
    try:
        target = MATCHERS[name]
    except KeyError:
        raise UnknownMatcherError(
            f"unknown matcher {name!r} (known: {', '.join(MATCHERS)})"
        ) from None
    module_name, class_name = target.split(":")
    cls = getattr(importlib.import_module(module_name), class_name)
    return cls(**options)
