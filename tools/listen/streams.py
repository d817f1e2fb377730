"""Streams of real speech over real noise, as a microphone in a room hears them: the clips chosen and laid at
random pauses, each at one voiced level, the noise under all of it at a stated SNR, the WAV and truth files.

Built by ``python -m tools.listen.bench_stream`` and the other listening benchmarks; scored by
tools/listen/stream_score.py.
"""

from __future__ import annotations

import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tools.speech.real_speech import Recording

RATE = 16_000
NOISE_FILES = {"kitchen": "doing_the_dishes.wav", "tap": "running_tap.wav", "machine": "exercise_bike.wav",
               "cat": "dude_miaowing.wav"}
SNRS = (20.0, 12.0, 6.0)
SPEECH_DBFS = -26.0  # every utterance is brought to this voiced level: a person at a steady distance


@dataclass(frozen=True)
class Placed:
    """A clip placed in a stream: where its audio and its voiced part are, in seconds."""

    clip: Recording
    start_s: float
    end_s: float
    voiced_start_s: float
    voiced_end_s: float


def owner(placed: list[Placed], s: float) -> int | None:
    """The placed utterance that a moment ``s`` seconds into the stream belongs to (inside its audio, 0.3 s before
    to 0.5 s after it; the nearest voiced end among several), or None: how a live session's events are matched to
    what was said."""
    inside = [i for i, p in enumerate(placed) if p.start_s - 0.3 <= s <= p.end_s + 0.5]
    return min(inside, key=lambda i: abs(placed[i].voiced_end_s - s)) if inside else None


def read_wav(path: Path) -> np.ndarray:
    with wave.open(str(path), "rb") as w:
        if w.getframerate() != RATE or w.getnchannels() != 1 or w.getsampwidth() != 2:
            raise SystemExit(f"bench_stream: {path} is not 16 kHz mono 16-bit")
        return np.frombuffer(w.readframes(w.getnframes()), "<i2").astype(np.float64) / 32768.0


def write_wav(path: Path, x: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(RATE)
        w.writeframes((np.clip(x, -1.0, 32767 / 32768) * 32768).astype("<i2").tobytes())


def voiced_frames(x: np.ndarray, frame: int = 320, below_peak_db: float = 25.0) -> np.ndarray:
    """Mask of 20 ms frames within ``below_peak_db`` of the loudest: the voiced part of a clip."""
    n = max(1, x.size // frame)
    rms = np.sqrt(np.mean(x[: n * frame].reshape(n, frame) ** 2, axis=1) + 1e-12)
    db = 20 * np.log10(rms)
    return db > db.max() - below_peak_db


def voiced_level(x: np.ndarray, frame: int = 320) -> tuple[float, int, int]:
    """RMS over the voiced frames, and the first and last voiced sample."""
    mask = voiced_frames(x, frame)
    idx = np.flatnonzero(mask)
    n = idx.size
    sel = np.concatenate([x[i * frame:(i + 1) * frame] for i in idx]) if n else x
    return float(np.sqrt(np.mean(sel**2))), int(idx[0] * frame) if n else 0, int((idx[-1] + 1) * frame) if n else x.size


def choose(clips: list[Recording], count: int, rng: np.random.Generator) -> list[Recording]:
    """70 % commands (every class represented), 15 % non-command words, 15 % sentences, shuffled."""
    by_kind = {k: [c for c in clips if c.kind == k] for k in ("command", "word", "sentence")}
    n_cmd = round(count * 0.7)
    n_word = (count - n_cmd) // 2
    n_sent = count - n_cmd - n_word
    picked = []
    for kind, n in (("command", n_cmd), ("word", n_word), ("sentence", n_sent)):
        pool = by_kind[kind]
        order = rng.permutation(len(pool))
        picked += [pool[i] for i in order[:n]] if n <= len(pool) else [pool[i % len(pool)] for i in rng.integers(0, len(pool), n)]
    return [picked[i] for i in rng.permutation(len(picked))]


def build_stream(clips: list[Recording], noise: np.ndarray | list[np.ndarray] | None, snr_db: float | None,
                 seed: int, pause_s: tuple[float, float] = (1.5, 6.0), level_spread_db: float = 0.0,
                 noise_change_s: float = 60.0) -> tuple[np.ndarray, list[Placed]]:
    """Clips at random pauses (seeded) over a noise track; each clip at SPEECH_DBFS over its voiced part
    (give or take up to ``level_spread_db``, uniformly: people at different distances). A list of noises
    takes turns every ``noise_change_s`` seconds."""
    speech, placed, rng = lay_clips(clips, seed, pause_s, level_spread_db)
    return under_noise(speech, noise, snr_db, rng, noise_change_s), placed


def lay_clips(clips: list[Recording], seed: int, pause_s: tuple[float, float] = (1.5, 6.0),
              level_spread_db: float = 0.0) -> tuple[np.ndarray, list[Placed], np.random.Generator]:
    """The speech track alone: clips at their levels and random pauses; the generator goes on to the noise."""
    rng = np.random.default_rng(seed)
    pieces, placed = [], []
    lead = int(rng.uniform(*pause_s) * RATE)
    pieces.append(np.zeros(lead))
    t = lead
    for clip in clips:
        x = read_wav(clip.path)
        _, v0, v1 = voiced_level(x)
        x = at_speech_level(x)
        if level_spread_db:
            x = x * 10 ** (rng.uniform(-level_spread_db, level_spread_db) / 20)
        placed.append(Placed(clip, t / RATE, (t + x.size) / RATE, (t + v0) / RATE, (t + v1) / RATE))
        pause = int(rng.uniform(*pause_s) * RATE)
        pieces += [x, np.zeros(pause)]
        t += x.size + pause
    return np.concatenate(pieces), placed, rng


def at_speech_level(x: np.ndarray) -> np.ndarray:
    """A clip brought to SPEECH_DBFS over its voiced frames: a person at a steady distance."""
    level, _, _ = voiced_level(x)
    return x * (10 ** (SPEECH_DBFS / 20) / max(level, 1e-6))


def noise_track(noise: np.ndarray | list[np.ndarray], n: int, snr_db: float, rng: np.random.Generator,
                change_s: float = 60.0) -> np.ndarray:
    """``n`` samples of noise ``snr_db`` below SPEECH_DBFS, each noise from a random point, looped; a list of
    noises takes turns every ``change_s`` seconds (1 s crossfades), each at that level."""
    target = 10 ** (SPEECH_DBFS / 20) / 10 ** (snr_db / 20)

    def level(track: np.ndarray) -> np.ndarray:
        return track * target / max(float(np.sqrt(np.mean(track**2))), 1e-9)

    if isinstance(noise, np.ndarray):
        start = int(rng.integers(0, noise.size))
        return level(np.resize(np.roll(noise, -start), n))
    tracks = [level(np.resize(np.roll(x, -int(rng.integers(0, x.size))), n)) for x in noise]
    period, fade = int(change_s * RATE), RATE
    t = np.arange(n)
    turn = t // period
    # the last second of each turn fades (equal power) into the next noise
    alpha = np.clip((t - turn * period - (period - fade)) / fade, 0.0, 1.0)
    out = np.zeros(n)
    for k, track in enumerate(tracks):
        out += np.where(turn % len(tracks) == k, np.sqrt(1 - alpha), 0.0) * track
        out += np.where((turn + 1) % len(tracks) == k, np.sqrt(alpha), 0.0) * track
    return out


def under_noise(speech: np.ndarray, noise: np.ndarray | list[np.ndarray] | None, snr_db: float | None,
                rng: np.random.Generator, change_s: float = 60.0) -> np.ndarray:
    """A stream of speech at SPEECH_DBFS with the noise (from a random point, looped) under all of it,
    ``snr_db`` below the speech's level; clean when either is None."""
    if noise is None or snr_db is None:
        return np.clip(speech, -1, 1)
    return np.clip(speech + noise_track(noise, speech.size, snr_db, rng, change_s), -1, 1)


def write_truth(path: Path, placed: list[Placed]) -> None:
    rows = ["index\tstart_s\tend_s\tvoiced_start_s\tvoiced_end_s\ttruth\tkind\tpath"]
    rows += [f"{i}\t{p.start_s:.3f}\t{p.end_s:.3f}\t{p.voiced_start_s:.3f}\t{p.voiced_end_s:.3f}\t{p.clip.action or 'none'}\t"
             f"{p.clip.kind}\t{p.clip.path}" for i, p in enumerate(placed)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
