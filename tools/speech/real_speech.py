"""The real recordings of ../shared/speech, split by speaker, and real noise mixed under them at a stated SNR.

Every real-speech benchmark and tuning tool reads its data here, so that all of them use the same
held-out part. A speaker goes to ``dev`` when sha1("gcs-voice-split:" + speaker) mod 1000 < 600, else
to ``test``; every file of a speaker follows it. Sentences have no published speaker id, so each
sentence file is placed by the same hash of its path. Thresholds are chosen on ``dev`` only and
reported on ``test``.

Noise (../shared/noise) is mixed so that the speech power *over its voiced frames* (not the whole file
with its silences) is ``snr_db`` above the noise power; the noise segment is fixed per (file, noise).

    python -m tools.speech.real_speech            # the split's counts
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import os
import wave
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["SHARED", "SAMPLE_RATE", "Recording", "CONDITIONS", "load_recordings", "read_wav", "mix",
           "condition_audio", "active_power", "NOISE_SEED"]

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("GCS_VOICE_SHARED", REPO.parent / "shared"))
SAMPLE_RATE = 16_000
UNKNOWN_SPEAKER = "picovoice_unknown"
DEV_FRACTION = 0.6

#: the seed of the noise segment each file gets (:func:`mix`): every shipped figure comes from this one draw
NOISE_SEED = 1234

#: condition name -> (noise file stem in ../shared/noise, SNR dB); "clean" adds nothing
CONDITIONS: dict[str, tuple[str | None, float | None]] = {
    "clean": (None, None),
    "kitchen20": ("doing_the_dishes", 20.0),
    "kitchen12": ("doing_the_dishes", 12.0),
    "kitchen6": ("doing_the_dishes", 6.0),
    "tap12": ("running_tap", 12.0),
    "bike12": ("exercise_bike", 12.0),
    "miaow12": ("dude_miaowing", 12.0),
}


@dataclass(frozen=True)
class Recording:
    """One labelled file. ``kind`` is command, word (a non-command word) or sentence; ``action`` None = no action."""

    path: Path
    action: str | None
    word: str
    speaker: str
    split: str
    kind: str
    lang: str


def split_of(key: str, dev_fraction: float = DEV_FRACTION) -> str:
    """'dev' or 'test' for a speaker (or a file without one), the same on every machine."""
    h = int(hashlib.sha1(("gcs-voice-split:" + key).encode()).hexdigest(), 16) % 1000
    return "dev" if h < dev_fraction * 1000 else "test"


def load_recordings(speech_dir: Path | None = None, split: str | None = None) -> list[Recording]:
    """Every labelled recording (or one split's), in labels.tsv order."""
    speech_dir = speech_dir or SHARED / "speech"
    labels = speech_dir / "labels.tsv"
    if not labels.is_file():
        raise SystemExit(f"no real recordings at {speech_dir} (set GCS_VOICE_SHARED to the shared folder)")
    out = []
    with open(labels, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh, delimiter="\t"):
            key = row["path"] if row["speaker"] == UNKNOWN_SPEAKER else row["speaker"]
            kind = "sentence" if "/_sentences/" in row["path"] else ("word" if row["class"] == "none" else "command")
            rec = Recording(speech_dir / row["path"], None if row["class"] == "none" else row["class"], row["word"],
                            row["speaker"], split_of(key), kind, row["lang"])
            if split is None or rec.split == split:
                out.append(rec)
    return out


def read_wav(path: Path) -> np.ndarray:
    """A 16 kHz mono 16-bit WAV as float32 in [-1, 1]."""
    with wave.open(str(path)) as w:
        if (w.getframerate(), w.getnchannels(), w.getsampwidth()) != (SAMPLE_RATE, 1, 2):
            raise ValueError(f"{path}: not 16 kHz mono 16-bit")
        return np.frombuffer(w.readframes(w.getnframes()), "<i2").astype(np.float32) / 32768.0


def _frame_power(audio: np.ndarray, frame: int = 400, hop: int = 160) -> np.ndarray:
    if audio.size < frame:
        audio = np.pad(audio, (0, frame - audio.size))
    n = 1 + (audio.size - frame) // hop
    idx = np.arange(frame)[None, :] + hop * np.arange(n)[:, None]
    return np.mean(audio[idx].astype(np.float64) ** 2, axis=1)


def active_power(audio: np.ndarray, within_db: float = 10.0) -> float:
    """Speech power over voiced frames: 25 ms frames within ``within_db`` dB of the 95th-percentile frame."""
    p = _frame_power(audio)
    ref = np.percentile(p, 95)
    return float(np.mean(p[p >= ref * 10 ** (-within_db / 10)]))


def mix(speech: np.ndarray, noise: np.ndarray, snr_db: float, key: str, seed: int = NOISE_SEED) -> np.ndarray:
    """``speech`` plus a segment of ``noise`` scaled to ``snr_db`` below its voiced power.

    The segment's offset comes from ``seed`` and crc32(``key``): the same file and noise always get the
    same segment, in any order. The sum is scaled down only if it would clip.
    """
    rng = np.random.default_rng([seed, zlib.crc32(key.encode())])
    if noise.size <= speech.size:
        noise = np.tile(noise, speech.size // noise.size + 2)
    off = int(rng.integers(0, noise.size - speech.size))
    seg = noise[off: off + speech.size].astype(np.float64)
    gain = np.sqrt(active_power(speech) / (np.mean(seg ** 2) + 1e-12) / 10 ** (snr_db / 10))
    out = speech + gain * seg
    peak = float(np.max(np.abs(out)))
    return (out / peak * 0.99 if peak > 1.0 else out).astype(np.float32)


_NOISES: dict[str, np.ndarray] = {}


def condition_audio(rec: Recording, condition: str, seed: int = NOISE_SEED) -> np.ndarray:
    """The recording as heard under ``condition`` (a key of CONDITIONS); ``seed`` draws another noise segment."""
    audio = read_wav(rec.path)
    stem, snr_db = CONDITIONS[condition]
    if stem is None:
        return audio
    if stem not in _NOISES:
        _NOISES[stem] = read_wav(SHARED / "noise" / f"{stem}.wav")
    return mix(audio, _NOISES[stem], float(snr_db), key=f"{rec.path.name}|{stem}", seed=seed)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.real_speech", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    recs = load_recordings()
    counts = Counter((r.split, r.kind) for r in recs)
    for key in sorted(counts):
        print(*key, counts[key], sep="\t")
    dev = {r.speaker for r in recs if r.split == "dev" and r.speaker != UNKNOWN_SPEAKER}
    test = {r.speaker for r in recs if r.split == "test" and r.speaker != UNKNOWN_SPEAKER}
    print(f"speakers: dev {len(dev)}, test {len(test)}, in both {len(dev & test)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
