"""End of utterance: an energy voice-activity detector with a noise floor and a hangover.

``segment_utterances(chunks)`` takes any chunk stream (WAV, stdin, microphone: see
``gcs_voice.audio.sources``) and yields each spoken utterance with its start and end time, for the
``recognize`` command and the live bridge alike. Thresholds are data (``vad.toml``).
"""

from __future__ import annotations

import tomllib
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.sources import AudioChunk

__all__ = ["Utterance", "VadSettings", "load_vad_settings", "segment_utterances", "frame_dbfs"]

VAD_SETTINGS_PATH = Path(__file__).resolve().parent / "vad.toml"


@dataclass(frozen=True)
class Utterance:
    """One spoken utterance: 16 kHz mono s16le PCM and where it was in the source, in seconds."""

    pcm: bytes
    start_s: float
    end_s: float

    @property
    def duration_s(self) -> float:
        return len(self.pcm) / 2 / SAMPLE_RATE


@dataclass(frozen=True)
class VadSettings:
    frame_s: float = 0.02
    min_speech_dbfs: float = -45.0
    noise_margin_db: float = 12.0
    noise_adapt: float = 0.05
    start_s: float = 0.06
    hangover_s: float = 0.45
    pre_roll_s: float = 0.25
    min_utterance_s: float = 0.15
    max_utterance_s: float = 8.0


def load_vad_settings(path: Path = VAD_SETTINGS_PATH, **overrides: float) -> VadSettings:
    with open(path, "rb") as f:
        values = {k: float(v) for k, v in tomllib.load(f).items()}
    values.update(overrides)
    return VadSettings(**values)


def frame_dbfs(pcm: bytes) -> float:
    """RMS level of s16le PCM in dB relative to full scale (-120 for silence)."""
    x = np.frombuffer(pcm, "<i2").astype(np.float64) / 32768.0
    rms = float(np.sqrt(np.mean(x * x))) if x.size else 0.0
    return 20.0 * np.log10(max(rms, 1e-6))


def segment_utterances(chunks: Iterable[AudioChunk], settings: VadSettings | None = None) -> Iterator[Utterance]:
    """Yield utterances as soon as their end is heard (after ``hangover_s`` of silence)."""
    s = settings or load_vad_settings()
    frame_bytes = int(SAMPLE_RATE * s.frame_s) * 2
    pre_roll: deque[bytes] = deque(maxlen=max(1, int(s.pre_roll_s / s.frame_s)))
    start_frames = max(1, round(s.start_s / s.frame_s))
    hang_frames = max(1, round(s.hangover_s / s.frame_s))
    max_frames = max(1, int(s.max_utterance_s / s.frame_s))
    noise_dbfs = None
    speech: list[bytes] = []  # frames of the current utterance (None when not in one)
    in_utt, voiced_run, silent_run, start_s = False, 0, 0, 0.0
    pending = b""
    t_frames = 0  # frames seen so far

    def emit(frames: list[bytes], start: float) -> Utterance | None:
        pcm = b"".join(frames)
        if len(pcm) / 2 / SAMPLE_RATE < s.min_utterance_s:
            return None
        return Utterance(pcm, start, start + len(pcm) / 2 / SAMPLE_RATE)

    for chunk in chunks:
        pending += chunk.pcm
        while len(pending) >= frame_bytes:
            frame, pending = pending[:frame_bytes], pending[frame_bytes:]
            level = frame_dbfs(frame)
            if noise_dbfs is None:
                noise_dbfs = min(level, s.min_speech_dbfs)
            voiced = level > max(s.min_speech_dbfs, noise_dbfs + s.noise_margin_db)
            if not voiced:
                noise_dbfs += s.noise_adapt * (level - noise_dbfs)
            t_s = t_frames * s.frame_s
            t_frames += 1
            if not in_utt:
                pre_roll.append(frame)
                voiced_run = voiced_run + 1 if voiced else 0
                if voiced_run >= start_frames:
                    in_utt, silent_run = True, 0
                    speech = list(pre_roll)
                    start_s = max(0.0, t_s + s.frame_s - len(speech) * s.frame_s)
                    pre_roll.clear()
                continue
            speech.append(frame)
            silent_run = 0 if voiced else silent_run + 1
            if silent_run >= hang_frames or len(speech) >= max_frames:
                keep = speech[: len(speech) - silent_run + min(silent_run, hang_frames // 2)]
                utt = emit(keep, start_s)
                if utt:
                    yield utt
                in_utt, voiced_run, speech = False, 0, []
    if in_utt and speech:
        utt = emit(speech + ([pending] if pending else []), start_s)
        if utt:
            yield utt
