"""Subtract the bridge's own sound from the microphone: an acoustic echo canceller for the stop spotter.

While the bridge speaks, the segmenter is deaf (half-duplex for commands, ``gcs_voice.audio.microphone``) and
only the stop spotter listens, so that a "stop" said over the bridge's voice still stops. The spotter then
hears the pilot's voice mixed with the bridge's own, as loud as the pilot's when the speaker is beside the
microphone. The bridge knows exactly what it played and when (``EchoGate``), so what the room returns of it
can be predicted and taken away, as every hands-free phone and smart speaker does.

The filter is the partitioned-block frequency-domain adaptive filter of Speex's echo canceller (MDF: Soo and
Pang 1990), an NLMS per frequency bin over ``length_s`` of the room's response (the sound card's output
latency, the path from speaker to microphone and the room's reverberation all fall inside it). Its step is
controlled as in Valin 2007 ("On adjusting the learning rate in frequency domain echo cancellation with
double-talk"): it learns in proportion to how much of what is left is echo, so the pilot talking over the
bridge (double talk) does not teach it to cancel the pilot. It keeps what it learned between cues: the room
does not change between two sentences of the bridge. Where nothing was played it returns the microphone
as it is.

A fresh filter knows nothing of the room, and cancels next to nothing of the bridge's first words: what the
spotter heard of the session's first "going down" was the bridge's own voice, and it stopped the vehicle
(python -m tools.listen.bench_feedback_echo, sessions 27 and 28, both 28 s in). Until it has heard ``learn_s`` of its
own sound, the post-filter therefore takes down every bin the bridge's sound could reach: it assumes the room
returns what was played in the last ``length_s`` at the loudness it has returned it so far (the microphone's
power over the reference's), as echo cancellers do while they converge.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from gcs_voice.audio.speaker import EchoGate

__all__ = ["EchoCanceller", "PlayedEcho"]


class EchoCanceller:
    """Microphone in, microphone less the predicted echo of ``reference`` (what the bridge played) out.

    ``block`` samples per step (16 ms at 16 kHz), ``length_s`` of echo path modelled, ``step`` the NLMS
    step at full confidence, ``min_step`` its floor, ``regularization`` the share of the reference's mean
    power added to each bin's in the normalisation, ``comfort_noise_dbfs`` white noise under the output
    (relative to 16-bit full scale: samples in int16 units). Samples come in any chunk size; the output lags by
    less than one block. ``residual_gate_db``, ``window_s`` and ``loud_db``: see ``only_remains`` (None: it never
    says so). ``learn_s``: the seconds of its own sound over which the post-filter assumes the worst of the echo
    (0: never).
    """

    def __init__(self, rate: int = 16_000, block: int = 256, length_s: float = 0.256, step: float = 0.5,
                 min_step: float = 0.5, regularization: float = 0.1, suppress: float = 1.0,
                 comfort_noise_dbfs: float | None = None, residual_gate_db: float | None = None,
                 window_s: float = 0.6, loud_db: float = 6.0, learn_s: float = 0.0) -> None:
        if not (0 < step <= 1 and 0 <= min_step <= 1 and length_s > 0):
            raise ValueError(f"echo canceller: step {step} and min_step {min_step} must be in (0, 1], "
                             f"length_s {length_s} above 0")
        self.block = block
        self.parts = max(1, int(round(length_s * rate / block)))
        self.step = step
        self.min_step = min_step
        self.regularization = regularization
        self.suppress = suppress
        #: white noise this far below 16-bit full scale under everything it returns (None: none)
        self.comfort = None if comfort_noise_dbfs is None else 32768.0 * 10 ** (comfort_noise_dbfs / 20)
        self._noise = np.random.default_rng(0)  # seeded: the same audio gives the same output
        self.rate = rate
        self.residual_gate_db = residual_gate_db
        self.window_s = window_s
        self.loud_db = loud_db
        self.learn_s = learn_s
        #: seconds of the bridge's own sound the filter has learned from
        self.learned_s = 0.0
        #: the microphone's and the reference's power summed over the blocks with the bridge's sound, while it learns
        self._mic_sum = self._ref_sum = 0.0
        #: power per block of the microphone and of what was left of it, the last few seconds (newest last)
        self._levels: list[tuple[float, float]] = []
        bins = block + 1
        self._w = np.zeros((self.parts, bins), np.complex128)  # the echo path, per partition
        self._x = np.zeros((self.parts, bins), np.complex128)  # spectra of the last reference blocks, newest first
        self._x_power = np.zeros(bins)  # smoothed power of the reference per bin
        self._echo_power = np.zeros(bins)  # smoothed power of the predicted echo
        self._error_power = np.zeros(bins)  # smoothed power of what is left
        self._prev_ref = np.zeros(block)
        self._mic_in = np.zeros(0)
        self._ref_in = np.zeros(0)
        self.blocks = 0

    def process(self, mic: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """The microphone's samples with the echo of ``reference`` (the same length, aligned in time:
        ``reference[i]`` was played when ``mic[i]`` was captured) taken away; float samples, any scale."""
        if mic.shape != reference.shape:
            raise ValueError("microphone and reference must have the same length")
        self._mic_in = np.concatenate([self._mic_in, np.asarray(mic, np.float64)])
        self._ref_in = np.concatenate([self._ref_in, np.asarray(reference, np.float64)])
        n = (self._mic_in.size // self.block) * self.block
        out = np.empty(n)
        for i in range(0, n, self.block):
            mic_block = self._mic_in[i:i + self.block]
            out[i:i + self.block] = self._step(mic_block, self._ref_in[i:i + self.block])
            self._levels.append((float(np.mean(mic_block ** 2)), float(np.mean(out[i:i + self.block] ** 2))))
        del self._levels[:-int(4.0 * self.rate / self.block)]
        self._mic_in, self._ref_in = self._mic_in[n:], self._ref_in[n:]
        if self.comfort is not None:
            # Comfort noise, as every echo canceller's output has: what is left of the bridge's words in a silent
            # room is a faint, lone sound (-70 dBFS) that a keyword spotter, which normalises the level away,
            # took for "stay"; over a floor no real room is quieter than, it is nothing
            out += self._noise.normal(0.0, self.comfort, out.size)
        return out

    def drop_pending(self) -> None:
        """Forget the part-block waiting for more samples, and how loud the microphone was (what is learned of
        the room stays)."""
        self._mic_in, self._ref_in = np.zeros(0), np.zeros(0)
        self._levels.clear()

    def only_remains(self) -> bool:
        """Whether, in the last ``window_s``, the microphone was loud (within ``loud_db`` of its loudest) only where
        the canceller took it at least ``residual_gate_db`` down: what it gave out is our own echo's remains,
        not a voice over it.

        A double-talk detector on the canceller's own work, judged over a word rather than a block: a pilot
        talking over the bridge comes through whole (his vowels are near the microphone's level, whether or
        not the bridge is loud there), while what is left of the bridge alone stays far below it. The keyword
        spotter normalises the level away: to it, what was left of "fence reached" 17 dB down was as loud
        as a pilot, and sounded like "stay"."""
        if self.residual_gate_db is None:
            return False
        n = int(round(self.window_s * self.rate / self.block))
        if len(self._levels) < 3:
            return False
        smooth = np.ones(3) / 3  # powers over 48 ms: a click is no vowel
        mic = np.convolve([m for m, _o in self._levels[-n:]], smooth, "valid")
        out = np.convolve([o for _m, o in self._levels[-n:]], smooth, "valid")
        loud = mic >= mic.max() * 10 ** (-self.loud_db / 10)
        return bool(np.all(out[loud] < mic[loud] * 10 ** (-self.residual_gate_db / 10)))

    def _step(self, mic: np.ndarray, ref: np.ndarray) -> np.ndarray:
        b = self.block
        if not ref.any() and not self._prev_ref.any() and not self._x.any():
            return mic.copy()  # nothing of ours in the room: the microphone as it is
        self.blocks += 1
        x = np.fft.rfft(np.concatenate([self._prev_ref, ref]))
        self._prev_ref = ref.copy()
        self._x = np.roll(self._x, 1, axis=0)
        self._x[0] = x
        echo_spectrum = np.sum(self._w * self._x, axis=0)
        echo = np.fft.irfft(echo_spectrum)[b:]
        error = mic - echo
        e = np.fft.rfft(np.concatenate([np.zeros(b), error]))
        a = 0.9  # smoothing of the powers over about 10 blocks (160 ms)
        self._x_power = a * self._x_power + (1 - a) * np.sum(np.abs(self._x) ** 2, axis=0) / self.parts
        self._echo_power = a * self._echo_power + (1 - a) * np.abs(echo_spectrum) ** 2
        self._error_power = a * self._error_power + (1 - a) * np.abs(e) ** 2
        # Learn as much as what is left is our echo: little while the pilot talks over it (Valin 2007)
        share = np.clip(self._echo_power / (self._error_power + 1e-9), self.min_step, 1.0)
        # NLMS per bin, normalised by the reference's power there plus ``regularization`` times its mean over
        # the bins: a bin our sound hardly reaches (a tone's cue excites a few) must not take huge steps on
        # noise, or the filter there turns the next words into something else (the stop spotter heard "hold")
        power = self.parts * self._x_power
        mu = self.step * share / (power + self.regularization * power.mean() + 1e-6)
        gradient = np.conj(self._x) * (mu * e)
        g = np.fft.irfft(gradient, axis=1)
        g[:, b:] = 0.0  # the constraint: each partition stays a causal filter of one block
        self._w += np.fft.rfft(g, axis=1)
        if self.suppress <= 0:
            return error
        # What the filter leaves of our echo, taken down further where it still dominates (a post-filter, as
        # every echo canceller has): per bin, the share of what is left that the echo estimate says is ours
        echo_power = self._echo_power
        ref_power = float(np.mean(ref ** 2))
        learning = self.learned_s < self.learn_s
        if ref_power > 1.0:  # above one 16-bit step: the bridge's sound, not the silence between its cues
            self.learned_s += b / self.rate
            if learning:
                self._mic_sum += float(np.mean(mic ** 2))
                self._ref_sum += ref_power
        if learning and self._ref_sum > 0:
            # Still learning: the echo is taken to be as loud, in every bin, as the loudest the bridge played there
            # within the modelled path, times how loud the room has returned it so far (whatever the delay)
            coupling = self._mic_sum / self._ref_sum
            echo_power = np.maximum(echo_power, coupling * np.max(np.abs(self._x) ** 2, axis=0))
        gain = np.clip(1.0 - self.suppress * echo_power / (self._error_power + 1e-9), 0.05, 1.0)
        return np.fft.irfft(e * gain)[b:]


class PlayedEcho:
    """The microphone's audio less the echo of what ``gate`` says the bridge played at the time it was
    captured: ``(capture UNIX time of the first sample, PCM) -> PCM`` (16 kHz mono s16le), for the stop
    spotter while the microphone is deaf. One instance per microphone: it keeps the room it learned."""

    def __init__(self, gate: EchoGate, canceller: EchoCanceller | None = None, rate: int = 16_000) -> None:
        self.gate = gate
        self.canceller = canceller or EchoCanceller(rate)
        self.rate = rate
        self._next_t: float | None = None

    def __call__(self, start_t: float, pcm: bytes) -> bytes:
        mic = np.frombuffer(pcm, "<i2").astype(np.float64)
        if self._next_t is not None and abs(start_t - self._next_t) > self.canceller.block / self.rate:
            self.canceller.drop_pending()  # a gap in the capture: a part-block of before is not joined to now
        self._next_t = start_t + mic.size / self.rate
        out = self.canceller.process(mic, self.gate.played(start_t, mic.size))
        return np.clip(np.round(out), -32768, 32767).astype("<i2").tobytes()

    def only_remains(self) -> bool:
        """Whether what it gave the spotter of late is only what was left of the bridge's own sound
        (``EchoCanceller.only_remains``): a stop word heard in it is not the pilot's."""
        return self.canceller.only_remains()
