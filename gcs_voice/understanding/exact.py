"""The paper's "no phoneme matching" baseline: the normalised transcript must equal a phrase."""

from __future__ import annotations

from gcs_voice.domain.dictionary import Dictionary, Phrase
from gcs_voice.understanding.matcher import Candidate, Matcher

__all__ = ["ExactMatcher"]


class ExactMatcher(Matcher):
    """Distance 0 for an identical phrase (after normalisation and skip words), 1 otherwise."""

    name = "exact"

    def distance(self, heard: str, phrase: Phrase, dictionary: Dictionary) -> float:
        return 0.0 if heard == phrase.match_key else 1.0

    def not_a_command_reason(self, best: Candidate, max_distance: float) -> str:
        return f"'{best.text}' is not a command (no phrase matches it exactly)"
