"""How much speech lies outside the words a recogniser placed in an utterance.

A recogniser that writes fewer words than were said leaves speech unexplained: PocketSphinx's grammar forced
"go up" onto a 9 s sentence; Whisper wrote "Right." for "right eight". A voice-activity detector says which
frames hold speech; what lies beyond the placed words, past a pad for the words' edges, was said and not
written.
"""

from __future__ import annotations

import numpy as np

SAMPLE_RATE = 16_000

__all__ = ["speech_beyond", "speech_after"]


def speech_beyond(pcm: bytes, start_s: float, end_s: float, pad_s: float = 0.25, vad_mode: int = 3) -> float:
    """Seconds of speech more than ``pad_s`` before ``start_s`` or after ``end_s`` (16 kHz mono s16le), by
    PocketSphinx's detector (WebRTC's): the PocketSphinx engine's own, light and always there."""
    from pocketsphinx import Vad

    vad = Vad(vad_mode, SAMPLE_RATE)
    size = vad.frame_bytes
    start, end = start_s - pad_s, end_s + pad_s
    window_s = size / 2 / SAMPLE_RATE
    beyond = 0.0
    for i in range(0, len(pcm) - size + 1, size):
        middle = (i / 2) / SAMPLE_RATE + window_s / 2
        if (middle < start or middle > end) and vad.is_speech(pcm[i:i + size]):
            beyond += window_s
    return round(beyond, 3)


def speech_after(audio: np.ndarray, end_s: float, pad_s: float = 0.15, threshold: float = 0.5) -> float:
    """Seconds of speech more than ``pad_s`` after ``end_s`` (float samples in [-1, 1], 16 kHz), by the Silero
    network from a fresh state, P(speech) >= ``threshold``: it holds in noise, where WebRTC's detector took a
    kitchen's clatter after real single commands for speech (on the dev speakers at 12 dB, a limit of 0.3 s
    cost 13 of 146 commands with it, 2 with Silero)."""
    from gcs_voice.audio.vad import SILERO_WINDOW, SileroVad

    vad = SileroVad()
    window_s = SILERO_WINDOW / SAMPLE_RATE
    after = 0.0
    x = np.asarray(audio, np.float32)
    for i in range(0, x.size - SILERO_WINDOW + 1, SILERO_WINDOW):
        p = vad.probability(x[i:i + SILERO_WINDOW])
        if i / SAMPLE_RATE + window_s / 2 > end_s + pad_s and p >= threshold:
            after += window_s
    return round(after, 3)
