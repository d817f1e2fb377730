"""Vosk (Kaldi) recogniser: streaming, with a runtime grammar built from the dictionary.

Grammar mode (rhasspy/wyoming-vosk "limited" mode with "Allow Unknown"): the recogniser may only
output dictionary words or the model's unknown token, so out-of-domain speech comes back as unknown
instead of the nearest command. The unknown token differs per model (``[unk]``, ``<UNK>`` for
vosk-model-small-ko-0.22: table in ``engines.toml``, else probed in the model). Vosk silently drops
grammar words missing from the model's vocabulary; we check each word with ``vosk_model_find_word``,
warn naming them, and leave out every phrase that contains one (dropping a word could turn
"turn right" into "right", another command). Free mode decodes with the model's own language model.
Alternatives come from ``SetMaxAlternatives``; their confidence is the posterior among the n-best
(softmax of Vosk's scores). Word confidences (``min_word_confidence``, ``mean_word_confidence`` in
``extra``) come from a second recogniser without alternatives, as Vosk gives them only then.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import logging
import math
from collections.abc import Sequence
from pathlib import Path

from gcs_voice.asr.base import SAMPLE_RATE, Hypothesis, Recognition
from gcs_voice.asr.models import check_vosk_model_dir, find_vosk_model, vosk_model_hint
from gcs_voice.asr.settings import engine_settings
from gcs_voice.domain.dictionary import Dictionary
from gcs_voice.errors import ModelError
from gcs_voice.domain.text import normalize_text

__all__ = ["VoskRecognizer", "VoskStream", "LanguageModel", "unknown_token_for"]

log = logging.getLogger(__name__)
#: Tokens tried, in order, when the model is not in the unknown-token table.
UNKNOWN_CANDIDATES = ("[unk]", "<UNK>", "<unk>")


def unknown_token_for(model_dir: Path, find_word) -> str | None:
    """The model's unknown-word token: from the table by folder name, else the first one the model knows."""
    table = engine_settings("vosk").get("unknown_token", {})
    for name in (model_dir.name, model_dir.parent.name):
        if name in table and find_word(table[name]) >= 0:
            return table[name]
    return next((tok for tok in UNKNOWN_CANDIDATES if find_word(tok) >= 0), None)


class LanguageModel:
    """One loaded Vosk model with the grammar for one dictionary."""

    def __init__(self, dictionary: Dictionary, model_dir: Path, mode: str):
        from vosk import Model, SetLogLevel

        SetLogLevel(-1)  # Kaldi logs go to stderr; what matters is reported by us
        try:
            self.model = Model(str(model_dir))
        except Exception as exc:  # vosk raises a bare Exception("Failed to create a model")
            raise ModelError(f"cannot load the Vosk model in {model_dir}: {exc}") from None
        self.model_dir = model_dir
        self.lang = dictionary.language
        find = self.model.vosk_model_find_word
        self.unknown = unknown_token_for(model_dir, find)
        phrases = [normalize_text(p.text, fold=False) for p in dictionary.phrases]
        self.missing_words: tuple[str, ...] = ()
        self.grammar: list[str] | None = None
        if mode == "grammar":
            spelled = {w: _spelling(w, find) for p in phrases for w in p.split()}
            self.missing_words = tuple(w for w, s in spelled.items() if s is None)
            if self.missing_words:
                log.warning("vosk: words missing from the %s model vocabulary (their phrases are left out "
                            "of the grammar): %s", model_dir.name, ", ".join(self.missing_words))
            usable = [" ".join(spelled[w] for w in p.split()) for p in phrases
                      if all(spelled[w] is not None for w in p.split())]
            if not usable:
                raise ModelError(f"vosk: no phrase of {dictionary.path} is in the vocabulary of {model_dir}")
            self.grammar = list(dict.fromkeys(usable)) + ([self.unknown] if self.unknown else [])
        self._args = (self.model, SAMPLE_RATE) + (
            (json.dumps(self.grammar, ensure_ascii=False),) if self.grammar else ())

    def recognizers(self):
        """Fresh Kaldi recognisers for one utterance, so nothing adapted on earlier utterances (``Reset()``
        keeps the online i-vector/CMVN state) changes this one. About 0.5 ms with a grammar this small."""
        from vosk import KaldiRecognizer

        settings = engine_settings("vosk")
        recognizer = KaldiRecognizer(*self._args)
        recognizer.SetMaxAlternatives(int(settings.get("max_alternatives", 5)))
        recognizer.SetWords(True)
        # Vosk gives per-word confidences (MBR) only without alternatives: a second, parallel
        # recogniser on the same audio provides them (decoding here costs ~50 ms per utterance).
        word_recognizer = None
        if settings.get("word_confidences", True):
            word_recognizer = KaldiRecognizer(*self._args)
            word_recognizer.SetWords(True)
        return recognizer, word_recognizer


def _libc_srand():
    """libc's ``srand``, or None where it cannot be loaded (then dither stays random)."""
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").srand
    except (OSError, AttributeError):
        return None


_SRAND = _libc_srand()


def _seed_dither(seed: int = 0) -> None:
    """Same audio, same answer. Kaldi dithers every frame (``--dither`` defaults to 1.0 and model
    ``mfcc.conf`` files rarely set it) with noise drawn from libc ``rand()``, so the same utterance
    scored 55.9, 53.5, 56.8, 52.2 on four runs and could flip a decision. Reseeding the shared
    generator at each utterance makes the noise, and so the result, depend on the audio alone."""
    if _SRAND is not None:
        _SRAND(seed)


def _spelling(word: str, find_word) -> str | None:
    """The word as the model spells it (models differ in case), or None when it is not in the vocabulary."""
    for candidate in dict.fromkeys((word, word.lower(), word.upper())):
        if find_word(candidate) >= 0:
            return candidate
    return None


class VoskRecognizer:
    """Vosk models, one per dictionary language (a Vosk model knows one language)."""

    name = "vosk"

    def __init__(self, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar"):
        if model is not None and len(dictionaries) > 1:
            raise ModelError("a Vosk model knows one language: give one dictionary with --model")
        self.mode = mode
        self._models: dict[str, LanguageModel] = {}
        for dictionary in dictionaries:
            if model is not None:
                model_dir = check_vosk_model_dir(model)
            else:
                found = find_vosk_model(dictionary.language)
                if found is None:
                    raise ModelError(vosk_model_hint(dictionary.language))
                model_dir = check_vosk_model_dir(found)
            self._models[dictionary.language] = LanguageModel(dictionary, model_dir, mode)
        self.languages = tuple(self._models)
        self.missing_words = tuple(w for m in self._models.values() for w in m.missing_words)

    @classmethod
    def load(cls, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar"):
        return cls(dictionaries, model=model, mode=mode)

    @property
    def language_models(self) -> dict[str, LanguageModel]:
        """Language code -> its loaded model, grammar and unknown token (a copy: what a session can hear)."""
        return dict(self._models)

    def start_stream(self, lang: str | None = None) -> VoskStream:
        if lang in (None, "auto"):
            if len(self._models) > 1:
                raise ModelError("vosk cannot detect the language: give --lang (or use whisper for auto)")
            lang = self.languages[0]
        if lang not in self._models:
            raise ModelError(f"no Vosk model loaded for {lang!r} (loaded: {', '.join(self.languages)})")
        return VoskStream(self, self._models[lang])


class VoskStream:
    """One utterance; PCM goes to Kaldi as it arrives (true streaming)."""

    def __init__(self, recognizer: VoskRecognizer, model: LanguageModel):
        self._name = recognizer.name
        self._model = model
        self._samples = 0
        self._done = False
        self._recognizer, self._word_recognizer = model.recognizers()
        _seed_dither()

    def accept(self, pcm: bytes) -> None:
        if self._done:
            raise RuntimeError("stream already finished")
        if pcm:
            self._samples += len(pcm) // 2
            self._recognizer.AcceptWaveform(pcm)
            if self._word_recognizer is not None:
                self._word_recognizer.AcceptWaveform(pcm)

    def finish(self) -> Recognition:
        if self._done:
            raise RuntimeError("stream already finished")
        self._done = True
        result = json.loads(self._recognizer.FinalResult())
        alternatives = result.get("alternatives") or [
            {"text": result.get("text", ""), "confidence": 0.0, "result": result.get("result", [])}
        ]
        unknown = self._model.unknown
        scores = [float(a.get("confidence", 0.0)) for a in alternatives]
        top = max(scores) if scores else 0.0
        weights = [math.exp(s - top) for s in scores]
        total = sum(weights) or 1.0
        hypotheses: list[Hypothesis] = []
        unknown_words = 0.0
        for i, (alt, score, weight) in enumerate(zip(alternatives, scores, weights)):
            words = alt.get("text", "").split()
            known = [w for w in words if w != unknown]
            if i == 0:
                unknown_words = float(len(words) - len(known))
            text = " ".join(known)
            if text and all(h.text != text for h in hypotheses):
                hypotheses.append(Hypothesis(text, confidence=weight / total, score=score))
        extra = {"unknown_words": unknown_words}
        if len(scores) > 1:
            extra["nbest_margin"] = scores[0] - scores[1]
        if self._word_recognizer is not None:
            words = json.loads(self._word_recognizer.FinalResult()).get("result", [])
            confs = [float(w["conf"]) for w in words if w.get("word") != unknown and "conf" in w]
            if confs:
                extra["min_word_confidence"] = min(confs)
                extra["mean_word_confidence"] = sum(confs) / len(confs)
        return Recognition(tuple(hypotheses), self._name, self._model.lang, self._samples / SAMPLE_RATE, extra)
