"""The bridge's own sounds as 16 kHz mono PCM: tones from notes, and words spoken by espeak-ng.

Words come from the ``espeak-ng`` command (offline, a few tens of milliseconds a phrase, in its own
process: no lock shared with the phonetic matcher's in-process library), cached per phrase so a cue
said before costs nothing. Missing espeak-ng is an AudioError, so that a session can fall back to tones.
"""

from __future__ import annotations

import io
import shutil
import subprocess
import threading
import wave
from collections.abc import Sequence

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.sources import pcm_bytes, resample
from gcs_voice.errors import AudioError

__all__ = ["tone", "Speech"]


def tone(notes: Sequence[Sequence[float]], amplitude: float, fade_s: float) -> bytes:
    """Notes ``[(frequency_hz, seconds), ...]`` one after another (0 Hz: a pause), each faded in and out."""
    parts = []
    for frequency, seconds in notes:
        n = max(1, round(float(seconds) * SAMPLE_RATE))
        t = np.arange(n) / SAMPLE_RATE
        x = np.sin(2 * np.pi * float(frequency) * t) * amplitude if frequency > 0 else np.zeros(n)
        ramp = min(n // 2, round(fade_s * SAMPLE_RATE))
        if ramp and frequency > 0:
            envelope = np.ones(n)
            envelope[:ramp] = np.linspace(0.0, 1.0, ramp)
            envelope[n - ramp:] = np.linspace(1.0, 0.0, ramp)
            x = x * envelope
        parts.append(x)
    return pcm_bytes(np.concatenate(parts)) if parts else b""


class Speech:
    """Text -> PCM in one espeak-ng voice, cached."""

    def __init__(self, voice: str, speed_wpm: int) -> None:
        self.exe = shutil.which("espeak-ng")
        if self.exe is None:
            raise AudioError("espeak-ng is not installed: feedback is tones only (apt install espeak-ng)")
        self.voice = voice
        self.speed_wpm = speed_wpm
        self._cache: dict[str, bytes] = {}
        self._lock = threading.Lock()

    def say(self, text: str) -> bytes:
        """The words as PCM (b"" for no words); AudioError when espeak-ng fails."""
        if not text.strip():
            return b""
        with self._lock:
            cached = self._cache.get(text)
        if cached is not None:
            return cached
        try:
            # close_fds=False lets Python spawn it with posix_spawn (no fork of a process holding a Whisper model)
            done = subprocess.run([self.exe, "-v", self.voice, "-s", str(self.speed_wpm), "--stdout", text],
                                  capture_output=True, timeout=10.0, check=False, close_fds=False)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise AudioError(f"espeak-ng failed: {exc}") from None
        if done.returncode != 0 or not done.stdout:
            raise AudioError(f"espeak-ng failed for voice {self.voice!r}: "
                             f"{done.stderr.decode(errors='replace').strip() or 'no audio'}")
        pcm = _wav_pcm(done.stdout)
        with self._lock:
            self._cache[text] = pcm
        return pcm


def _wav_pcm(data: bytes) -> bytes:
    """espeak-ng's WAV (22.05 kHz mono int16; its header's length is unset on a pipe) as 16 kHz PCM."""
    try:
        with wave.open(io.BytesIO(data)) as w:
            rate, width, channels = w.getframerate(), w.getsampwidth(), w.getnchannels()
    except (wave.Error, EOFError) as exc:
        raise AudioError(f"espeak-ng gave no WAV: {exc}") from None
    if width != 2 or channels != 1:
        raise AudioError(f"espeak-ng gave {channels} channels of {8 * width} bit, not mono 16 bit")
    raw = data[44:]  # the data chunk of espeak-ng's fixed 44-byte header (its size field says 0x7fffffff)
    samples = np.frombuffer(raw[: len(raw) // 2 * 2], "<i2").astype(np.float32) / 32768.0
    return pcm_bytes(resample(samples, rate, SAMPLE_RATE))
