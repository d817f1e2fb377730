"""The paper's matcher: character edit distance to every phrase, the nearest wins.

Unlike the paper, the distance is normalised by the longer string (so one threshold fits short and
long phrases) and a too-distant nearest phrase is rejected instead of executed.
"""

from __future__ import annotations

from rapidfuzz.distance import Levenshtein

from gcs_voice.domain.dictionary import Dictionary, Phrase
from gcs_voice.understanding.matcher import Matcher

__all__ = ["LevenshteinMatcher", "levenshtein_distance"]


def levenshtein_distance(a: str, b: str) -> int:
    """Plain character edit distance (insert, delete, substitute all cost 1), as in the paper."""
    return Levenshtein.distance(a, b)


class LevenshteinMatcher(Matcher):
    """Normalised character edit distance between the heard text and each phrase."""

    name = "levenshtein"

    def distance(self, heard: str, phrase: Phrase, dictionary: Dictionary) -> float:
        return Levenshtein.normalized_distance(heard, phrase.match_key)
