"""Whisper as a closed-set classifier: every dictionary phrase scored under Whisper's own decoder.

Free decoding on short commands lists dictionary words or loops; forcing each phrase instead
(teacher forcing, CTranslate2 ``Whisper.align``, the call faster-whisper uses for word
probabilities) asks "how probable is *this* transcript of this audio?" for all phrases in one
encoder pass. A phrase is written the way Whisper transcribes it (capital first letter, final
period: ``align`` masks end-of-text, and the period is what stops "Go." from winning over "Go up.").

Three things make the scores comparable across phrases (measured on the dev split, docs/bench/accuracy.md):
- the encoder sees the utterance plus a short silence, not a 30 s window (accuracy
  and time against the 30 s window: docs/bench/accuracy.md, paired and Timing tables);
- a phrase's score is its mean token log-probability *minus* ``prior_weight`` x the same on silence:
  how much the audio raises the phrase, not how common the phrase is ("Go ahead." was winning on
  anything unclear);
- phrases are tokenised the way the model emits them (:func:`canonical_tokens`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_voice.domain.dictionary import Dictionary, Phrase

__all__ = ["PhraseScore", "canonical_tokens", "phrase_tokens", "phrase_logprobs", "score_phrases",
           "class_posteriors", "class_gap", "collapse_repeats"]

_SPACE = "\u0120"  # byte-level BPE's space marker ("Ġ")


@dataclass(frozen=True)
class PhraseScore:
    """One phrase's score: mean token log-probability on the audio minus the weighted prior."""

    phrase: Phrase
    dictionary: Dictionary
    logprob: float


def canonical_tokens(tokenizer, text: str) -> list[int]:
    """Token ids of ``text`` as Whisper itself would emit them.

    faster-whisper-base's ``tokenizer.json`` lacks the BPE merge of a space with "t", so " to" and
    " the" encode as [" ", "to"] and [" ", "the"]: token pairs the model never produces, scored far
    too low. A lone space token is joined to the next token whenever the joined token exists.
    """
    hf = tokenizer.tokenizer
    ids = list(tokenizer.encode(text))
    space = hf.token_to_id(_SPACE)
    out: list[int] = []
    i = 0
    while i < len(ids):
        if ids[i] == space and i + 1 < len(ids):
            joined = hf.token_to_id(_SPACE + hf.id_to_token(ids[i + 1]))
            if joined is not None:
                out.append(joined)
                i += 2
                continue
        out.append(ids[i])
        i += 1
    return out


def phrase_tokens(tokenizer, phrase: Phrase) -> list[int]:
    """The tokens Whisper would emit for this phrase (" Turn left.")."""
    return canonical_tokens(tokenizer, " " + phrase.text[:1].upper() + phrase.text[1:] + ".")


def phrase_logprobs(model, encoder_output, tokenizer, dictionary: Dictionary, num_frames: int,
                    batch_size: int = 8) -> list[float]:
    """Mean token log-probability of every phrase of ``dictionary`` (its order) on one encoder output.

    ``model`` is the ``ctranslate2.models.Whisper``; the encoder output is repeated, not recomputed,
    ``batch_size`` times per call. On an encoded silence this is the phrases' prior.
    """
    import ctranslate2

    sequences = [phrase_tokens(tokenizer, p) for p in dictionary.phrases]
    encoded = np.asarray(encoder_output)
    start = list(tokenizer.sot_sequence) + [tokenizer.no_timestamps]
    out: list[float] = []
    for lo in range(0, len(sequences), batch_size):
        chunk = sequences[lo : lo + batch_size]
        repeated = ctranslate2.StorageView.from_array(np.ascontiguousarray(np.repeat(encoded, len(chunk), axis=0)))
        for result in model.align(repeated, start, chunk, [num_frames] * len(chunk)):
            probs = np.asarray(result.text_token_probs, dtype=np.float64)
            out.append(float(np.mean(np.log(np.maximum(probs, 1e-12)))))
    return out


def score_phrases(
    model, encoder_output, tokenizer, dictionary: Dictionary, num_frames: int, prior: Sequence[float] | None = None,
    prior_weight: float = 0.0, batch_size: int = 8,
) -> list[PhraseScore]:
    """Every phrase of ``dictionary`` scored on one encoder output, best first.

    ``prior`` is :func:`phrase_logprobs` on an encoded silence (same phrase order).
    """
    raw = phrase_logprobs(model, encoder_output, tokenizer, dictionary, num_frames, batch_size)
    prior = list(prior) if prior is not None else [0.0] * len(raw)
    scores = [PhraseScore(p, dictionary, lp - prior_weight * pr) for p, lp, pr in zip(dictionary.phrases, raw, prior)]
    scores.sort(key=lambda s: s.logprob, reverse=True)
    return scores


def class_posteriors(scores: Sequence[PhraseScore], temperature: float) -> dict[str, float]:
    """Softmax of phrase scores / ``temperature``, summed per action class."""
    if not scores:
        return {}
    top = scores[0].logprob
    weights = [math.exp((s.logprob - top) / temperature) for s in scores]
    total = sum(weights)
    out: dict[str, float] = {}
    for s, w in zip(scores, weights):
        out[s.phrase.action] = out.get(s.phrase.action, 0.0) + w / total
    return out


def class_gap(scores: Sequence[PhraseScore]) -> float:
    """Best phrase score minus the best score of a phrase of another class (inf when there is none)."""
    if not scores:
        return 0.0
    winner = scores[0].phrase.action
    rival = next((s.logprob for s in scores if s.phrase.action != winner), None)
    return math.inf if rival is None else scores[0].logprob - rival


_WORD = re.compile(r"\w+(?:'\w+)?", re.UNICODE)


def collapse_repeats(text: str) -> str:
    """"Down. Down. Down. Do" -> "Down": Whisper repeats itself on a short window; keep one period."""
    words = _WORD.findall(text)
    low = [w.lower() for w in words]
    for period in range(1, len(low) + 1):
        unit = low[:period]
        if all(w == unit[i % period] or (i == len(low) - 1 and unit[i % period].startswith(w))
               for i, w in enumerate(low)):
            return " ".join(words[:period])
    return " ".join(words)
