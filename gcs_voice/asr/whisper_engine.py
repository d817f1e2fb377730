"""Whisper (faster-whisper / CTranslate2, CPU int8): multilingual, free decoding biased to the domain.

Short commands make Whisper hallucinate (repetition loops, invented sentences on noise), so each
utterance is decoded in ONE 30 s window with: a few new tokens at most (``max_new_tokens``), no
previous-text conditioning, no timestamps, the dictionary phrases as the prompt, the language forced
when known. Whisper has no grammar: ``mode="grammar"`` means the prompt bias, ``"free"`` no prompt,
``"score"`` scores every dictionary phrase under the decoder (see :mod:`whisper_score`) and
reports itself as engine ``whisper-score`` (its own rejection thresholds).
We call CTranslate2's ``generate`` ourselves (as faster-whisper's
``generate_with_fallback`` does) to get the beam's n-best list, which ``transcribe`` hides.
``--lang auto`` picks, per utterance, the most probable of the loaded dictionaries' languages.
Rejection evidence in ``Recognition.extra``: ``no_speech_prob``, ``avg_logprob``,
``compression_ratio``, ``language_probability``, ``temperature``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from gcs_voice.asr.base import SAMPLE_RATE, BufferedStream, Hypothesis, Recognition
from gcs_voice.asr.models import find_whisper_model, whisper_model_hint
from gcs_voice.asr.settings import engine_settings
from gcs_voice.asr.whisper_score import (canonical_tokens, generation_length, phrase_forms, score_utterance,
                                         trim_silence)
from gcs_voice.domain.dictionary import Dictionary
from gcs_voice.errors import ModelError
from gcs_voice.domain.text import normalize_text

__all__ = ["WhisperRecognizer", "WhisperStream"]


class WhisperRecognizer:
    """One faster-whisper model for all the dictionaries' languages."""

    name = "whisper"

    def __init__(self, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar"):
        from faster_whisper import WhisperModel

        self.settings = engine_settings("whisper")
        self.mode = mode
        if mode == "score":
            self.name = "whisper-score"
        resolved = find_whisper_model(model, self.settings.get("model_dirs"))
        if resolved is None:
            raise ModelError(whisper_model_hint("base"))
        try:
            self.model = WhisperModel(
                resolved,
                device=self.settings.get("device", "cpu"),
                compute_type=self.settings.get("compute_type", "int8"),
                cpu_threads=int(self.settings.get("cpu_threads", 2)),
                local_files_only=True,  # never download at run time
            )
        except Exception as exc:  # huggingface_hub / ctranslate2 errors: not found, corrupt
            if model is not None and not any(sep in model for sep in "/\\"):
                raise ModelError(whisper_model_hint(model)) from None
            raise ModelError(f"cannot load the Whisper model {resolved}: {str(exc).splitlines()[0]}") from None
        self.dictionaries = {d.language: d for d in dictionaries}
        self.languages = tuple(self.dictionaries)
        if not self.model.model.is_multilingual and set(self.languages) - {"en"}:
            raise ModelError(f"Whisper model {resolved} is English-only; it cannot do {', '.join(self.languages)}")
        self._prompts: dict[str, list[int]] = {}
        self._forms: dict = {}  # language -> whisper_score.PhraseForms
        self._tokenizers: dict = {}
        from threadpoolctl import ThreadpoolController

        self._threadpools = ThreadpoolController()
        #: the domain ear (gcs_voice/asr/ear.py): scoring mode only, and only on the Whisper model it was trained on
        self.ear = self._load_ear(resolved) if mode == "score" and self.settings.get("ear", True) else None
        #: the ear for what is heard over the bridge's own voice (None: ``hear(over_voice=True)`` uses ``ear``)
        self.ear_over_voice = self._load_ear(resolved, over_voice=True) if self.ear is not None else None

    @staticmethod
    def _load_ear(resolved: str, over_voice: bool = False):
        from pathlib import Path

        from gcs_voice.asr.ear import EAR_OVER_VOICE_PATH, EAR_PATH, DomainEar

        ear = DomainEar.load(EAR_OVER_VOICE_PATH if over_voice else EAR_PATH)
        if ear is None:
            return None
        trained_on = ear.meta.get("model_bin_size")
        model_bin = Path(resolved) / "model.bin"
        if trained_on is not None and model_bin.is_file() and model_bin.stat().st_size != int(trained_on):
            return None  # another Whisper model: its encoder speaks another language than the ear learnt
        return ear

    def hear(self, audio: np.ndarray, over_voice: bool = False) -> dict[str, float]:
        """The domain ear's class probabilities for one utterance ({} without an ear): the utterance
        encoded alone, not padded to a window (tens of milliseconds for a command). ``over_voice``: heard while the
        bridge spoke (what the echo canceller left of it), judged by the ear that learnt the bridge's voice."""
        ear = (self.ear_over_voice or self.ear) if over_voice else self.ear
        if ear is None:
            return {}
        from gcs_voice.asr.ear import encoder_input, pool_frames

        encoded = np.asarray(self.model.encode(encoder_input(audio, self.log_mel)))
        if not ear.fits(encoded.shape[-1]):
            return {}
        return ear.evidence(pool_frames(encoded))

    def log_mel(self, audio: np.ndarray, window: int | None = None) -> np.ndarray:
        """Whisper's log-mel features of ``audio`` (zero-padded to ``window`` samples when given), with
        ONE BLAS thread: the mel filter product is the feature extractor's only BLAS call, and OpenBLAS's
        workers, left spinning after it, took both cores from the encoder that runs next (which then took
        about 155 ms per utterance instead of 95 on 2 cores: docs/bench/real_timing.md)."""
        with self._threadpools.limit(limits=1, user_api="blas"):
            if window is None:
                return self.model.feature_extractor(audio)
            return _log_mel_padded(self.model.feature_extractor, audio, window)

    @classmethod
    def load(cls, dictionaries: Sequence[Dictionary], model: str | None = None, mode: str = "grammar"):
        return cls(dictionaries, model=model, mode=mode)

    def start_stream(self, lang: str | None = None) -> WhisperStream:
        """``lang`` forces the language; None or "auto" detects it per utterance among the loaded ones."""
        if lang in (None, "auto"):
            fixed = self.languages[0] if len(self.languages) == 1 else None
        elif lang in self.dictionaries:
            fixed = lang
        else:
            raise ModelError(f"no dictionary loaded for {lang!r} (loaded: {', '.join(self.languages)})")
        return WhisperStream(self, fixed)

    # -- decoding ---------------------------------------------------------------------------------
    def tokenizer(self, lang: str):
        """Whisper's tokenizer set for ``lang`` (made once per language)."""
        from faster_whisper.tokenizer import Tokenizer

        if lang not in self._tokenizers:
            self._tokenizers[lang] = Tokenizer(self.model.hf_tokenizer, self.model.model.is_multilingual,
                                               task="transcribe", language=lang)
        return self._tokenizers[lang]

    def _prompt(self, lang: str) -> list[int]:
        """The dictionary's words as the previous-text prompt (domain bias), then the task tokens.

        Words, not whole phrases: the full phrase list is long (slower) and Whisper then tends to
        recite it ("turn right, go back,") on silence.
        """
        if lang not in self._prompts:
            tokenizer = self.tokenizer(lang)
            previous: list[int] = []
            if self.mode == "grammar" and self.settings.get("prompt_with_dictionary", True):
                words = ", ".join(self.dictionaries[lang].vocabulary()) + "."
                previous = canonical_tokens(tokenizer, " " + words)
            self._prompts[lang] = self.model.get_prompt(tokenizer, previous, without_timestamps=True)
        return self._prompts[lang]

    def detect(self, encoder_output, fixed: str | None) -> tuple[str, float, float]:
        """(language, its probability among all, probability mass of the loaded languages)."""
        results = self.model.model.detect_language(encoder_output)[0]
        probs = {token[2:-2]: float(p) for token, p in results}
        if fixed is not None:
            return fixed, probs.get(fixed, 0.0), probs.get(fixed, 0.0)
        lang = max(self.languages, key=lambda code: probs.get(code, 0.0))
        return lang, probs.get(lang, 0.0), sum(probs.get(code, 0.0) for code in self.languages)

    def decode(self, pcm: bytes, fixed_lang: str | None, between_stages: Callable[[], None] | None = None) -> Recognition:
        """Recognise one utterance; ``between_stages`` is called after the encoder and after the free pass
        (scoring mode), where it may raise to give up (:meth:`BufferedStream.check_abandon`)."""
        from faster_whisper.audio import pad_or_trim
        from faster_whisper.transcribe import get_compression_ratio

        audio = np.frombuffer(pcm, "<i2").astype(np.float32) / 32768.0
        audio_s = audio.size / SAMPLE_RATE
        if audio.size < SAMPLE_RATE // 10:  # under 0.1 s: nothing to decode
            return Recognition((), self.name, fixed_lang, audio_s, {})
        if self.mode == "score":
            return self._decode_scored(audio, fixed_lang, audio_s, between_stages)
        features = self.log_mel(audio)
        encoder_output = self.model.encode(pad_or_trim(features))
        lang, lang_prob, known_mass = self.detect(encoder_output, fixed_lang)
        prompt = self._prompt(lang)
        tokenizer = self.tokenizer(lang)
        s = self.settings
        n_best = max(1, int(s.get("beam_size", 5)))
        max_length = generation_length(len(prompt), int(s.get("max_new_tokens", 16)))
        chosen = None
        for temperature in s.get("temperature", [0.0]):
            if temperature > 0:
                import ctranslate2

                ctranslate2.set_random_seed(int(s.get("sampling_seed", 0)))  # same audio, same answer
                kwargs = {"beam_size": 1, "num_hypotheses": n_best, "sampling_topk": 0,
                          "sampling_temperature": float(temperature)}
            else:
                kwargs = {"beam_size": n_best, "num_hypotheses": n_best}
            result = self.model.model.generate(
                encoder_output, [prompt], max_length=max_length, return_scores=True,
                return_no_speech_prob=True, suppress_blank=True, suppress_tokens=[-1], **kwargs,
            )[0]
            candidates = []
            for tokens, score in zip(result.sequences_ids, result.scores):
                text = tokenizer.decode(tokens).strip()
                avg_logprob = score * len(tokens) / (len(tokens) + 1)  # as faster-whisper recovers it
                candidates.append((text, avg_logprob, get_compression_ratio(text) if text else 0.0))
            candidates.sort(key=lambda c: c[1], reverse=True)
            chosen = (candidates, float(result.no_speech_prob), float(temperature))
            best = candidates[0]
            if best[2] <= s.get("compression_ratio_threshold", 2.4) and best[1] >= s.get("log_prob_threshold", -1.0):
                break
            if float(result.no_speech_prob) > s.get("no_speech_threshold", 0.6):
                break  # silence: a fallback would only invent words
        candidates, no_speech_prob, temperature = chosen
        hypotheses: list[Hypothesis] = []
        seen: set[str] = set()
        for text, avg_logprob, _ in candidates:
            key = normalize_text(text)
            if key and key not in seen:  # "stop", "stop." and "Stop," are one hypothesis
                seen.add(key)
                hypotheses.append(Hypothesis(text, confidence=math.exp(avg_logprob), score=avg_logprob))
        best = candidates[0]
        extra = {
            "no_speech_prob": no_speech_prob,
            "avg_logprob": best[1],
            "compression_ratio": best[2],
            "language_probability": lang_prob,
            "dictionary_language_mass": known_mass,
            "temperature": temperature,
        }
        return Recognition(tuple(hypotheses), self.name, lang, audio_s, extra)

    # -- mode "score" -----------------------------------------------------------------------------
    def encode_short(self, audio: np.ndarray):
        """Encoder output of the utterance, trimmed of leading/trailing silence, plus ``score_pad_s`` of
        silence (not a 30 s window), its mel frame count, and the audio encoded: what scoring mode judges
        phrases on."""
        s = self.settings
        if s.get("score_trim", True):
            audio = trim_silence(audio)
        # Whisper was trained on 30 s windows: a window much shorter than that makes it mishear short
        # words ("Up" -> "Ah"); score_window_s is the accuracy/time trade-off (docs/bench/real.md).
        audio = audio[: 28 * SAMPLE_RATE]
        window = max(audio.size + int(float(s.get("score_pad_s", 0.3)) * SAMPLE_RATE),
                     int(float(s.get("score_window_s", 0.0)) * SAMPLE_RATE))
        features = self.log_mel(audio.astype(np.float32), window)
        encoded = self.model.encode(features)
        # The decoder's cost grows with every encoder position it attends to, once per scored phrase:
        # keep the utterance and score_crop_s after it (2 mel frames per position), not the silent rest
        # of the window, which only gave the encoder its context.
        crop_s = float(s.get("score_crop_s", 0.0))
        if crop_s > 0:
            keep = int(math.ceil((audio.size / SAMPLE_RATE + crop_s) * 50))
            array = np.asarray(encoded)
            if keep < array.shape[1]:
                import ctranslate2

                encoded = ctranslate2.StorageView.from_array(np.ascontiguousarray(array[:, :keep]))
                return encoded, 2 * keep, audio
        return encoded, features.shape[-1], audio

    def phrase_forms(self, lang: str):
        """The dictionary's phrases tokenised as Whisper writes them (once per language)."""
        if lang not in self._forms:
            self._forms[lang] = phrase_forms(self.tokenizer(lang), self.dictionaries[lang])
        return self._forms[lang]

    def _decode_scored(self, audio: np.ndarray, fixed_lang: str | None, audio_s: float,
                       between_stages: Callable[[], None] | None = None) -> Recognition:
        """Phrases judged against Whisper's own transcript on one short encoder pass (:mod:`whisper_score`)."""
        s = self.settings
        encoded, frames, spoken = self.encode_short(audio)
        if between_stages is not None:
            between_stages()  # the decoder passes cost about as much as the encoder: skip them if unwanted
        candidates = [fixed_lang] if fixed_lang is not None else list(self.languages)
        scored = {code: score_utterance(self.model.model, self.tokenizer(code), self.phrase_forms(code), encoded,
                                        frames, int(s.get("score_extra_tokens", 3)), int(s.get("score_top_k", 8)),
                                        str(s.get("score_rank_by", "mean")), str(s.get("score_context", "")),
                                        between_stages)
                  for code in candidates}
        # --lang auto: the best phrase over the loaded languages picks the language (Whisper's language
        # detection on a short window calls espeak-ng Spanish English).
        lang = max(candidates, key=lambda code: scored[code].best[1] if scored[code].best else -math.inf)
        result = scored[lang]
        extra = {
            "no_speech_prob": result.no_speech_prob,
            "free_logprob": result.free_logprob if math.isfinite(result.free_logprob) else -99.0,
            # the best phrase per token (what the margin compares) and its rank score (score_rank_by)
            "phrase_score": max(result.best_per_token, -99.0),
            "phrase_rank_score": result.best[1] if result.best else -99.0,
            "margin": max(result.margin, -99.0),
            "class_gap": min(result.class_gap, 99.0),
            "transcript_cut": float(result.cut),  # the speech went on past the free pass: more than a command
        }
        if result.spoken_s is not None and result.amount_gap is None:
            # Speech after the words Whisper wrote (where it aligned them): words it did not write, such as the
            # digit of "right eight" heard "Right." (the matcher does not fly a motion open-ended on that)
            from gcs_voice.audio.voiced import speech_after

            extra["speech_after_s"] = speech_after(spoken, result.spoken_s[1])
        if result.amount_gap is not None:  # an amount was said: how surely, against the amounts that sound alike
            extra["amount_gap"] = max(min(result.amount_gap, 99.0), -99.0)
            extra["amount_rival"] = float(result.amount_rival)
        if fixed_lang is None:
            _, extra["language_probability"], extra["dictionary_language_mass"] = self.detect(encoded, lang)
        extra.update(self.hear(audio))
        hypotheses = tuple(Hypothesis(phrase.text, confidence=math.exp(min(0.0, score)), score=score)
                           for phrase, score in result.ranked[: int(s.get("score_alternatives", 5))])
        return Recognition(hypotheses, self.name, lang, audio_s, extra, transcript=result.heard_text)


def _log_mel_padded(extractor, audio: np.ndarray, window: int) -> np.ndarray:
    """Whisper's log-mel of ``audio`` followed by zeros up to ``window`` samples, computed on the audio only.

    ``extractor(zero-padded window)[:, :-1]`` to float32 rounding (bit for bit where the FFT of the shorter
    part rounds alike; within 1e-7 elsewhere): every frame lying wholly in the zeros comes out
    of Whisper's normalisation as one constant (log10 of its 1e-10 floor, clamped to 8 below the loudest
    frame, which silence cannot raise), so the frames after the audio's are copies of the last frame
    computed, which lies in the zeros too (most of an 8 s window is silence after a one-second command).
    """
    hop = extractor.hop_length
    frames = window // hop  # what extractor(window samples)[:, :-1] gives
    tail = audio.size + 2 * extractor.n_fft  # the audio and zeros enough that the last frames lie wholly in them
    if tail >= window:
        part = np.zeros(window, dtype=np.float32)
        part[: audio.size] = audio
        return extractor(part)[:, :-1]
    part = np.zeros(tail - tail % hop, dtype=np.float32)
    part[: audio.size] = audio
    head = extractor(part)[:, :-1]
    out = np.empty((head.shape[0], frames), dtype=head.dtype)
    out[:, : head.shape[1]] = head
    out[:, head.shape[1]:] = head[:, -1:]
    return out


class WhisperStream(BufferedStream):
    """Whisper decodes whole utterances: PCM is buffered and decoded at ``finish``."""

    def __init__(self, recognizer: WhisperRecognizer, lang: str | None):
        super().__init__()
        self._rec = recognizer
        self._lang = lang

    def finish(self) -> Recognition:
        max_samples = 30 * SAMPLE_RATE  # one Whisper window; a command is far shorter
        return self._rec.decode(self._take()[: max_samples * 2], self._lang, self.check_abandon)
