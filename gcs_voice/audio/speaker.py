"""Sound out, beside the microphone: the speaker, the echo gate, and a loopback room for tests.

The bridge's own cues come out of a speaker next to the microphone it listens with. ``EchoGate`` keeps
when that is so (from the moment a sound starts until it ended plus a tail for the output latency and
the room), and ``gcs_voice.audio.microphone`` feeds the segmenter silence for that time while the stop
spotter still hears everything: half-duplex for commands, full-duplex for "stop".

``EchoRoom`` is the speaker and the microphone of a ``--listen-wav`` session made honest: what a player
plays into it is added, attenuated, delayed and (given a room's impulse response) reverberated, to the recording at the moment it is played, exactly as
a microphone beside the speaker would pick it up. Every player blocks for the sound's length, as a
real speaker takes that long.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Protocol

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.sources import AudioChunk
from gcs_voice.errors import AudioError

__all__ = ["Player", "EchoGate", "SpeakerPlayer", "EchoRoom", "TimedSink", "open_speaker", "pcm_seconds"]


def pcm_seconds(pcm: bytes) -> float:
    """Length of 16 kHz mono s16le PCM in seconds."""
    return len(pcm) / 2 / SAMPLE_RATE


class Player(Protocol):
    """Plays 16 kHz mono s16le PCM and returns when it has been played; calls ``started`` with the UNIX time
    its first sample left, as near as it knows (what the echo canceller aligns its reference by)."""

    name: str

    def play(self, pcm: bytes, started: Callable[[float], None] | None = None) -> None: ...


class EchoGate:
    """When the microphone may be hearing the bridge's own sound (UNIX times), and what that sound was;
    thread-safe."""

    def __init__(self, tail_s: float) -> None:
        self.tail_s = tail_s
        self._spans: list[tuple[float, float]] = []
        #: the sounds themselves, (start UNIX time, float samples): the echo canceller's reference
        self._sounds: list[tuple[float, np.ndarray]] = []
        self._lock = threading.Lock()
        self._pilot_quiet = threading.Condition(self._lock)
        self._pilot_speaking = False

    def pilot_speaking(self, speaking: bool) -> None:
        """The segmenter is (True) or is no longer (False) in an utterance of the pilot's. A sound begun over a
        word cuts the word in two (the microphone goes deaf at once), so the speaker waits for the pilot's turn."""
        with self._lock:
            if speaking != self._pilot_speaking:
                self._pilot_speaking = speaking
                self._pilot_quiet.notify_all()

    def wait_pilot_done(self, timeout_s: float) -> bool:
        """Wait, up to ``timeout_s``, until the pilot is not speaking; whether the pilot is quiet now."""
        with self._lock:
            return self._pilot_quiet.wait_for(lambda: not self._pilot_speaking, timeout_s)

    def hold(self, start_t: float, duration_s: float) -> None:
        """A sound starts at ``start_t`` (call before it does) and lasts ``duration_s``."""
        with self._lock:
            self._spans.append((start_t, start_t + duration_s + self.tail_s))

    def record(self, start_t: float, pcm: bytes) -> None:
        """The sound (16 kHz mono s16le) whose first sample left the player at ``start_t`` (a player's
        ``started``): kept so that its echo can be taken out of the microphone. The deaf time lasts until it has
        ended plus the tail, counted from when it really started: a player's output latency (up to 0.2 s)
        does not shorten the tail that was held for the room."""
        end_t = start_t + pcm_seconds(pcm) + self.tail_s
        with self._lock:
            self._sounds = [s for s in self._sounds if s[0] + s[1].size / SAMPLE_RATE >= start_t - 60.0]
            self._sounds.append((start_t, np.frombuffer(pcm, "<i2").astype(np.float64)))
            held = [i for i, (a, b) in enumerate(self._spans) if a <= start_t <= b]
            if held:
                a, b = self._spans[held[-1]]
                self._spans[held[-1]] = (a, max(b, end_t))
            else:
                self._spans.append((start_t, end_t))

    def played(self, from_t: float, n: int) -> np.ndarray:
        """What the bridge played during the ``n`` samples from UNIX time ``from_t``, sample for sample
        (zeros where it played nothing)."""
        out = np.zeros(n)
        with self._lock:
            sounds = list(self._sounds)
        for start_t, samples in sounds:
            offset = round((from_t - start_t) * SAMPLE_RATE)  # index in the sound of the window's first sample
            lo, hi = max(0, offset), min(samples.size, offset + n)
            if lo < hi:
                out[lo - offset:hi - offset] += samples[lo:hi]
        return out

    def deaf(self, from_t: float, to_t: float) -> bool:
        """Whether audio captured between these times may hold the bridge's own sound."""
        with self._lock:
            self._spans = [s for s in self._spans if s[1] >= from_t - 60.0]  # old spans go (a minute's margin)
            return any(start <= to_t and from_t <= end for start, end in self._spans)


class SpeakerPlayer:
    """The sound card's output through sounddevice (blocking play)."""

    name = "speaker"

    def __init__(self, device: int | str | None = None) -> None:
        import sounddevice as sd

        self._sd = sd
        self.device = device

    def play(self, pcm: bytes, started: Callable[[float], None] | None = None) -> None:
        samples = np.frombuffer(pcm, "<i2")
        if started is not None:  # PortAudio's output latency: the sound leaves that much after the call
            started(time.time() + self._latency_s())
        self._sd.play(samples, SAMPLE_RATE, device=self.device, blocking=True)

    def _latency_s(self) -> float:
        try:
            return float(self._sd.query_devices(self.device, kind="output")["default_high_output_latency"])
        except Exception:  # noqa: BLE001 - a device that does not say: the canceller learns the delay
            return 0.0


def open_speaker(device: int | str | None = None) -> SpeakerPlayer:
    """The output device, or AudioError (one line) when there is no PortAudio or no output device."""
    try:
        import sounddevice as sd
    except (ImportError, OSError) as exc:
        raise AudioError(f"no speaker: {exc} (install libportaudio2)") from None
    try:
        sd.query_devices(device, kind="output")
    except Exception as exc:  # sounddevice raises PortAudioError / ValueError
        raise AudioError(f"no speaker: {str(exc).splitlines()[0]}") from None
    return SpeakerPlayer(device)


class TimedSink:
    """Plays nowhere, in real time: where there is no sound card (a benchmark), a cue is still rendered and
    takes its length, so what feedback costs a session is measured, not skipped."""

    name = "timed sink"

    def play(self, pcm: bytes, started: Callable[[float], None] | None = None) -> None:
        if started is not None:
            started(time.time())
        time.sleep(pcm_seconds(pcm))


class EchoRoom:
    """A speaker beside a microphone: ``play`` adds the sound to ``hear``'s chunks, ``gain`` down and
    ``delay_s`` late, from the moment it is played (a sound played before the recording starts is lost,
    as to a microphone not yet open)."""

    name = "echo room"

    def __init__(self, gain: float, delay_s: float, response: np.ndarray | None = None) -> None:
        self.gain = gain
        self.delay_s = delay_s
        #: the room's impulse response from speaker to microphone (None: the direct path alone)
        self.response = response
        self.t0: float | None = None  # UNIX time of the recording's first sample
        self._pending: list[tuple[int, np.ndarray]] = []  # (first sample index in the recording, samples)
        self._lock = threading.Lock()
        #: every sound played into the recording, as (UNIX time played, seconds): what the tests check against
        self.played: list[tuple[float, float]] = []

    def start(self, t0: float) -> None:
        """The recording's first sample is at UNIX time ``t0`` (``paced_chunks``' ``on_start``)."""
        self.t0 = t0

    def play(self, pcm: bytes, started: Callable[[float], None] | None = None) -> None:
        now = time.time()
        if started is not None:
            started(now)
        self.play_at(pcm, now)
        time.sleep(max(0.0, now + pcm_seconds(pcm) - time.time()))  # a speaker takes the sound's length

    def play_at(self, pcm: bytes, start_t: float) -> None:
        """The sound leaves the speaker at UNIX time ``start_t`` (not yet heard), without waiting for it: a test
        places it exactly within the microphone's blocks, where a thread's start would leave it to the load."""
        samples = np.frombuffer(pcm, "<i2").astype(np.float32) * self.gain
        if self.response is not None:
            samples = np.convolve(samples, self.response).astype(np.float32)
        with self._lock:
            if self.t0 is not None:
                at = round((start_t + self.delay_s - self.t0) * SAMPLE_RATE)
                self._pending.append((at, samples))
                self.played.append((start_t, pcm_seconds(pcm)))

    def hear(self, chunks: Iterable[AudioChunk]) -> Iterator[AudioChunk]:
        """The chunks as the microphone hears them: the recording plus whatever was played into the room."""
        for chunk in chunks:
            first = round(chunk.start_s * SAMPLE_RATE)
            x = np.frombuffer(chunk.pcm, "<i2").astype(np.float32)
            last = first + x.size
            with self._lock:
                pending = list(self._pending)
                self._pending = [(at, s) for at, s in pending if at + s.size > last]
            mixed = False
            for at, s in pending:
                lo, hi = max(first, at), min(last, at + s.size)
                if lo < hi:
                    if not mixed:
                        x, mixed = x.copy(), True
                    x[lo - first:hi - first] += s[lo - at:hi - at]
            yield chunk if not mixed else AudioChunk(np.clip(x, -32768, 32767).astype("<i2").tobytes(),
                                                      chunk.start_s)
