"""One text normalisation, used on dictionary phrases and on transcripts alike.

Matching compares normalised strings only, so both sides must go through the same function:
lower case, Unicode NFC, punctuation removed, white space collapsed and, for matching, accents
folded ("elévate" == "elevate", "atrás" == "atras"), because recognisers differ in whether they
write them.
"""

from __future__ import annotations

import re
import unicodedata

__all__ = ["normalize_text", "fold_accents"]

_PUNCT = re.compile(r"[^\w\s'-]+", re.UNICODE)
_SPACE = re.compile(r"[\s_-]+", re.UNICODE)


def fold_accents(text: str) -> str:
    """Remove combining accents (á -> a, ñ -> n) so that accent-less transcripts still match."""
    decomposed = unicodedata.normalize("NFD", text)
    return unicodedata.normalize("NFC", "".join(c for c in decomposed if not unicodedata.combining(c)))


def normalize_text(text: str, *, fold: bool = True) -> str:
    """Lower-case, strip punctuation and extra spaces; with ``fold`` also drop accents."""
    text = unicodedata.normalize("NFC", text).lower().replace("\u2019", "'")
    text = _PUNCT.sub(" ", text)
    text = text.replace("'", "")
    text = _SPACE.sub(" ", text).strip()
    return fold_accents(text) if fold else text
