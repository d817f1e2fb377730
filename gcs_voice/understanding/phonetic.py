"""Phonetic matcher: compare how the heard text and each phrase *sound*, over the n-best list.

Both sides are turned into IPA phoneme tokens by espeak-ng in the dictionary's language, so
spelling differences that sound alike ("go rite", "turn write", "vaja") cost little. The distance is
an edit distance over phoneme tokens where substituting a phoneme by a similar one (same place and
manner: t/d, s/z, ɹ/l/ɾ, ʌ/ɑ...) costs half: the mean of the exact-token and the phoneme-class
distances, normalised by the longer sequence. All n-best alternatives are scored (lower ranks pay
``alt_penalty`` each), and the base class's rejection rules apply unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence

from rapidfuzz.distance import LCSseq, Levenshtein

from gcs_voice.domain.dictionary import Dictionary, Phrase
from gcs_voice.understanding.matcher import Matcher
from gcs_voice.understanding.phonemes import ESPEAK_VOICE, phoneme_tokens

__all__ = ["PhoneticMatcher", "phonetic_distance"]

#: phoneme -> class of similar sounds (substitution within a class costs half).
_CLASSES: dict[str, tuple[str, ...]] = {
    "P": ("p", "b"), "T": ("t", "d", "ɾ̃"), "K": ("k", "ɡ", "g", "q"),
    "F": ("f", "v", "β"), "TH": ("θ", "ð"), "S": ("s", "z"), "SH": ("ʃ", "ʒ"), "H": ("x", "h", "χ", "ɣ"),
    "CH": ("tʃ", "dʒ", "ʝ"), "N": ("m", "n", "ŋ", "ɲ"), "L": ("l", "ɹ", "r", "ɾ", "ɫ", "ʎ"),
    "Y": ("j",), "W": ("w",),
    "I": ("i", "ɪ", "y", "ɪə", "ᵻ"), "E": ("e", "ɛ", "eɪ", "æ", "eə"), "A": ("a", "ə", "ɐ", "ʌ", "ɑ", "ɒ"),
    "ER": ("ɜ", "ɚ", "ɝ"), "O": ("o", "ɔ", "oʊ", "əʊ"), "U": ("u", "ʊ", "ʊə"),
    "AI": ("aɪ",), "AU": ("aʊ",), "OI": ("ɔɪ",),
}
_CLASS_OF = {ph: cls for cls, members in _CLASSES.items() for ph in members}
_CODE: dict[str, str] = {}


def _code(symbol: str) -> str:
    """One private-use character per phoneme or class, so rapidfuzz can compare strings."""
    if symbol not in _CODE:
        _CODE[symbol] = chr(0xE000 + len(_CODE))
    return _CODE[symbol]


def _encode(tokens: Sequence[str]) -> tuple[str, str]:
    exact = "".join(_code(t) for t in tokens)
    classes = "".join(_code("#" + _CLASS_OF.get(t, t)) for t in tokens)
    return exact, classes


def phonetic_distance(a: Sequence[str], b: Sequence[str]) -> float:
    """Normalised weighted edit distance between two phoneme-token sequences, in [0, 1]."""
    if not a and not b:
        return 0.0
    (ea, ca), (eb, cb) = _encode(a), _encode(b)
    weighted = (Levenshtein.distance(ea, eb) + Levenshtein.distance(ca, cb)) / 2
    return min(1.0, weighted / max(len(a), len(b)))


class PhoneticMatcher(Matcher):
    """Weighted phoneme edit distance, n-best aware."""

    name = "phonetic"
    default_alternatives = 5

    def __init__(self, **options: object) -> None:
        super().__init__(**options)
        self._phrase_codes: dict[tuple[str, str], tuple[str, str, int]] = {}

    @staticmethod
    def voice(dictionary: Dictionary) -> str:
        return ESPEAK_VOICE.get(dictionary.language, dictionary.language)

    def prepare(self, dictionaries: Sequence[Dictionary]) -> None:
        for d in dictionaries:
            voice = self.voice(d)
            for p in d.phrases:
                if (voice, p.match_key) not in self._phrase_codes:
                    tokens = phoneme_tokens(p.match_key, voice)
                    self._phrase_codes[(voice, p.match_key)] = (*_encode(tokens), len(tokens))

    def word_distance(self, a: str, b: str, dictionary: Dictionary) -> float:
        voice = self.voice(dictionary)
        return phonetic_distance(phoneme_tokens(a, voice), phoneme_tokens(b, voice))

    def shared(self, heard: str, phrase: str, dictionary: Dictionary) -> float:
        """The fraction of the phrase's phonemes found in what was heard, in order, a similar sound counting
        (same class: "esquirla" has i-s-k-ɾ-a of "izquierda"; "a" has 1 of the 9 sounds of "a la derecha")."""
        voice = self.voice(dictionary)
        wanted = phoneme_tokens(phrase, voice)
        if not wanted:
            return 1.0
        return LCSseq.similarity(_encode(phoneme_tokens(heard, voice))[1], _encode(wanted)[1]) / len(wanted)

    def distance(self, heard: str, phrase: Phrase, dictionary: Dictionary) -> float:
        voice = self.voice(dictionary)
        heard_tokens = phoneme_tokens(heard, voice)
        eh, ch = _encode(heard_tokens)
        ep, cp, n = self._phrase_codes[(voice, phrase.match_key)]
        longest = max(len(heard_tokens), n)
        if longest == 0:
            return 0.0
        weighted = (Levenshtein.distance(eh, ep) + Levenshtein.distance(ch, cp)) / 2
        return min(1.0, weighted / longest)
