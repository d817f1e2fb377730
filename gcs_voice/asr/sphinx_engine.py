"""PocketSphinx 5 (CMU US English model inside its wheel): needs nothing but pip.

Grammar mode decodes a JSGF grammar ``<command> | <garbage> [<garbage>] [<garbage>]``: the command
branch lists the dictionary phrases, the garbage branch a few short common words (``engines.toml``),
so out-of-domain speech is absorbed by garbage instead of being forced into the nearest command.
When garbage wins the recognition has no hypotheses and ``extra["out_of_grammar"] = 1``. Free mode
decodes with the bundled n-gram language model. Confidence = the smallest word posterior of the best
path (lattice posterior; 1 = no competing path). English only.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from gcs_voice.asr.base import SAMPLE_RATE, BufferedStream, Hypothesis, Recognition
from gcs_voice.asr.models import sphinx_model_dir
from gcs_voice.asr.settings import engine_settings
from gcs_voice.audio.voiced import speech_beyond
from gcs_voice.domain.dictionary import Dictionary
from gcs_voice.errors import ModelError
from gcs_voice.domain.text import normalize_text

__all__ = ["SphinxRecognizer", "SphinxStream"]

log = logging.getLogger(__name__)
LANGUAGES = ("en",)
#: Frames per second of PocketSphinx's default front end (10 ms shift).
FRAMES_PER_S = 100


def _jsgf_token(word: str) -> str:
    return word if word.replace("'", "").isalnum() else f'"{word}"'


class SphinxRecognizer:
    """One PocketSphinx decoder with a grammar search (and a free search in free mode)."""

    name = "sphinx"
    languages = LANGUAGES

    def __init__(self, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar",
                 settings: dict | None = None):
        """``settings`` overrides ``[sphinx]`` of engines.toml (tools/speech/bench_sphinx_real.py sweeps them)."""
        others = sorted({d.language for d in dictionaries} - set(LANGUAGES))
        if others:
            raise ModelError(f"the sphinx engine recognises English only, not {', '.join(others)}: "
                             f"use --engine vosk or --engine whisper for that language")
        from pocketsphinx import Config, Decoder

        self.mode = mode
        self.settings = {**engine_settings("sphinx"), **(settings or {})}
        model_dir = sphinx_model_dir(model)
        config = Config(hmm=str(model_dir / "en-us"), dict=str(model_dir / "cmudict-en-us.dict"),
                        lm=None, loglevel="FATAL", beam=float(self.settings.get("beam", 1e-48)),
                        wbeam=float(self.settings.get("wbeam", 7e-29)))
        try:
            self.decoder = Decoder(config)
        except Exception as exc:  # pocketsphinx raises RuntimeError with no detail
            raise ModelError(f"cannot load the PocketSphinx model in {model_dir}: {exc}") from None
        self.phrases = [normalize_text(p.text, fold=False) for d in dictionaries for p in d.phrases]
        #: words people say near a drone that sound like commands ("four", "seven"): garbage, when asked for
        self.not_commands = [normalize_text(w, fold=False) for d in dictionaries for w in d.not_commands]
        self.missing_words = tuple(sorted({w for p in self.phrases for w in p.split()
                                           if self.decoder.lookup_word(w) is None}))
        if self.missing_words:
            log.warning("sphinx: dictionary words missing from the pronunciation dictionary "
                        "(phrases with them cannot be recognised): %s", ", ".join(self.missing_words))
        #: the JSGF grammar the decoder searches (grammar mode; None in free mode): what can be heard at all
        self.jsgf: str | None = None
        if mode == "free":
            lm = model_dir / "en-us.lm.bin"
            if not lm.is_file():
                raise ModelError(f"free decoding needs {lm}")
            self.decoder.add_lm_file("free", str(lm))
            self.search = "free"
        else:
            self.jsgf = self._grammar()
            self.decoder.add_jsgf_string("grammar", self.jsgf)
            self.search = "grammar"
        self.decoder.activate_search(self.search)
        # Every utterance starts from the model's initial cepstral mean and fresh noise statistics
        # (``start_stream``): otherwise both carry over and the previous utterance changes the next
        # result (measured: "stop" after "go up" heard as "go back"; the same "up" three times gave
        # posteriors 0.97, 0.79, 0.79 while only the CMN was reset, because remove_noise kept its
        # noise estimate).
        self.initial_cmn = self.decoder.get_cmn()
        self._open: SphinxStream | None = None

    @classmethod
    def load(cls, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar"):
        return cls(dictionaries, model=model, mode=mode)

    def _grammar(self) -> str:
        vocabulary = {w for p in self.phrases for w in p.split()}
        usable = [p for p in dict.fromkeys(self.phrases) if not set(p.split()) & set(self.missing_words)]
        if not usable:
            raise ModelError("sphinx: no dictionary phrase can be pronounced with the English model")
        words = list(self.settings["garbage_words"])
        if self.settings.get("garbage_not_commands", False):
            kept_out = set(self.settings.get("garbage_not_commands_except", ()))
            words += [w for w in self.not_commands if " " not in w and w not in kept_out]
        self.garbage = tuple(w for w in dict.fromkeys(words)
                             if w not in vocabulary and self.decoder.lookup_word(w) is not None)
        commands = " | ".join(" ".join(_jsgf_token(w) for w in p.split()) for p in usable)
        lines = ["#JSGF V1.0;", "grammar gcsvoice;", f"<command> = {commands};"]
        if self.garbage:
            n = max(1, int(self.settings.get("garbage_max_words", 3)))
            weight = float(self.settings.get("garbage_weight", 0.001))
            lines.append(f"<garbage> = {' | '.join(self.garbage)};")
            loop = " ".join(["<garbage>"] + ["[<garbage>]"] * (n - 1))
            lines.append(f"public <utterance> = /1.0/ <command> | /{weight:g}/ {loop};")
        else:
            lines.append("public <utterance> = <command>;")
        return "\n".join(lines) + "\n"

    def start_stream(self, lang: str | None = None) -> SphinxStream:
        if lang not in (None, "en"):
            raise ModelError(f"the sphinx engine recognises English only, not {lang!r}")
        if self._open is not None:
            self._open.abandon()
        self._open = SphinxStream(self)
        return self._open


class SphinxStream(BufferedStream):
    """One utterance. PCM is buffered and decoded at ``finish`` as one whole utterance, because
    PocketSphinx's live cepstral-mean normalisation misrecognises the first second of a stream
    (measured: "go up", "turn left" lost to garbage when streamed, found when decoded whole)."""

    def __init__(self, recognizer: SphinxRecognizer):
        super().__init__()
        self._rec = recognizer

    def abandon(self) -> None:
        self._done = True

    def finish(self) -> Recognition:
        pcm = self._take()
        rec, decoder = self._rec, self._rec.decoder
        rec._open = None
        audio_s = len(pcm) / 2 / SAMPLE_RATE
        pcm = _dither(pcm, int(rec.settings.get("dither_lsb", 0)))
        decoder.start_stream()  # resets the front end's noise estimate (remove_noise)
        decoder.set_cmn(rec.initial_cmn)
        decoder.start_utt()
        if len(pcm) >= 2:
            decoder.process_raw(pcm[: len(pcm) // 2 * 2], False, True)
        decoder.end_utt()
        hyp = decoder.hyp()
        words = [s for s in decoder.seg() if not s.word.startswith(("<", "["))] if hyp else []
        text = " ".join(_base_word(s.word) for s in words)
        extra: dict[str, float] = {"frames": float(decoder.n_frames())}
        if not text:
            return Recognition((), rec.name, "en", audio_s, extra)
        posterior = min(1.0, max(0.0, min(float(s.prob) for s in words)))
        extra["posterior"] = posterior
        if rec.search == "grammar" and set(text.split()) & set(rec.garbage):
            extra["out_of_grammar"] = 1.0
            return Recognition((), rec.name, "en", audio_s, extra)
        extra["out_of_grammar"] = 0.0
        extra["speech_beyond_s"] = speech_beyond(pcm, words[0].start_frame / 100.0,
                                                 (words[-1].end_frame + 1) / 100.0,
                                                 float(rec.settings.get("beyond_pad_s", 0.25)),
                                                 int(rec.settings.get("beyond_vad_mode", 3)))
        hypotheses = [Hypothesis(text, confidence=posterior, score=float(hyp.score))]
        limit = int(rec.settings.get("max_alternatives", 5))
        for alt in _nbest(decoder, limit * 4):
            alt_text = " ".join(_base_word(w) for w in alt.hypstr.split() if not w.startswith(("<", "[")))
            if rec.search == "grammar" and set(alt_text.split()) & set(rec.garbage):
                continue
            if alt_text and all(h.text != alt_text for h in hypotheses):
                hypotheses.append(Hypothesis(alt_text, confidence=None, score=float(alt.score)))
            if len(hypotheses) >= limit:
                break
        return Recognition(tuple(hypotheses), rec.name, "en", audio_s, extra)


def _dither(pcm: bytes, lsb: int, min_run: int = SAMPLE_RATE // 100) -> bytes:
    """Fill digital silence (runs of at least ``min_run`` exact zeros: espeak-ng, zero padding, a muted
    microphone) with seeded noise of +-``lsb``. Such silence throws PocketSphinx's noise removal and
    cepstral mean off: espeak-ng "stop" at 150 wpm (23 % of samples exactly 0) went to the garbage
    branch; filled, it is "stop" at posterior 1.0. Audio with its own noise is left as it is, and the
    seed is fixed, so the same utterance still gives the same answer."""
    samples = np.frombuffer(pcm[: len(pcm) // 2 * 2], "<i2")
    if lsb <= 0 or samples.size < min_run:
        return pcm
    edges = np.flatnonzero(np.diff(np.concatenate(([0], (samples == 0).astype(np.int8), [0]))))
    starts, ends = edges[0::2], edges[1::2]
    long_runs = [(a, b) for a, b in zip(starts, ends) if b - a >= min_run]
    if not long_runs:
        return pcm
    out = samples.copy()
    noise = np.random.default_rng(0).integers(-lsb, lsb + 1, samples.size).astype("<i2")
    for a, b in long_runs:
        out[a:b] = noise[a:b]
    return out.tobytes()


def _base_word(word: str) -> str:
    """``right(2)`` (an alternative pronunciation) -> ``right``."""
    return word.split("(", 1)[0]


def _nbest(decoder, limit: int):
    out = []
    try:
        for i, item in enumerate(decoder.nbest()):
            if i >= limit or item is None:
                break
            out.append(item)
    except (AttributeError, RuntimeError):  # no lattice for this utterance
        pass
    return out
