"""Whisper's recognitions and the ear's features of the real recordings, cached (out/ear/rows.jsonl).

One row per (recording, condition): the Recognition of Whisper base in scoring mode WITHOUT the ear (its
evidence is added later, from whichever ear is judged: the shipped one on held-out speakers, one trained
without the speaker on dev) and the ear's pooled feature vector of the same audio. The held-out speakers
are heard over the second half of each noise, the dev speakers over the first.

    python -m tools.speech.ear_rows --split test
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import Hypothesis, Recognition
from tools.speech.real_cache import read_rows
from tools.speech.real_speech import SHARED
from tools.speech.ear_data import EVAL_CONDITIONS, Clip, clip_audio, condition_audio, features, real_clips

REPO = Path(__file__).resolve().parents[2]
ROWS = REPO / "out" / "ear" / "rows.jsonl"
DEFAULT_MODEL = SHARED / "models" / "faster-whisper-base"
#: the dev speakers' conditions (thresholds are chosen over these)
DEV_CONDITIONS = ("clean", "kitchen20", "kitchen12", "tap12", "bike12", "miaow12")
NOISE_SEED = 1234


def encode_vector(vec: np.ndarray) -> str:
    return base64.b64encode(vec.astype(np.float16).tobytes()).decode()


def decode_vector(text: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype=np.float16).astype(np.float32)


def load_rows(path: Path = ROWS) -> dict[str, dict]:
    """Cached rows by key ("<file>|<condition>")."""
    return read_rows(path)


def recognition(row: dict, ear: dict[str, float] | None = None) -> Recognition:
    """The row's Recognition, with an ear's evidence added when given."""
    extra = dict(row["extra"])
    extra.update(ear or {})
    return Recognition(tuple(Hypothesis(t, c, s) for t, c, s in row["hypotheses"]), row["engine"], row["lang"],
                       row["audio_s"], extra, transcript=row["transcript"])


def half_of(clip: Clip) -> str:
    return "train" if clip.split == "dev" else "test"


def recognise(split: str, conditions: list[str], model: Path = DEFAULT_MODEL, limit: int | None = None) -> int:
    """Recognise (and featurise) every real file of ``split`` under ``conditions``; only what is not cached."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language

    dictionary = load_language("en")
    recognizer = load_recognizer("whisper", [dictionary], model=str(model), mode="score")
    recognizer.ear = None  # the rows hold Whisper's own evidence; the ear's is added when judged
    config = hashlib.sha1((json.dumps(recognizer.settings, sort_keys=True, default=str)
                           + dictionary.path.read_text(encoding="utf-8")).encode()).hexdigest()[:12]
    cached = {k: r for k, r in load_rows().items() if r.get("config") == config}
    clips = [c for c in real_clips() if c.split == split][:limit]
    todo = [(c, cond) for cond in conditions for c in clips if f"{c.key}|{cond}" not in cached]
    print(f"ear_rows: {len(todo)} to recognise ({len(clips)} files x {len(conditions)} conditions)", file=sys.stderr)
    ROWS.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    with open(ROWS, "a", encoding="utf-8") as out:
        for i, (clip, cond) in enumerate(todo):
            noise, snr = EVAL_CONDITIONS[cond]
            audio = condition_audio(clip, clip_audio(clip), noise, snr, half_of(clip), NOISE_SEED)
            pcm = (np.clip(audio, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
            stream = recognizer.start_stream("en")
            stream.accept(pcm)
            result = stream.finish()
            vec = features(recognizer.model.encode, recognizer.log_mel, audio)
            row = {"key": f"{clip.key}|{cond}", "config": config, "engine": result.engine, "lang": result.lang,
                   "hypotheses": [[h.text, h.confidence, h.score] for h in result.hypotheses],
                   "extra": dict(result.extra), "transcript": result.transcript, "audio_s": result.audio_s,
                   "features": encode_vector(vec)}
            out.write(json.dumps(row) + "\n")
            out.flush()
            if i % 100 == 0:
                print(f"  {i}/{len(todo)} {row['key']} {time.time() - t0:.0f} s", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.ear_rows", description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("dev", "test"), required=True)
    parser.add_argument("--conditions", help="default: dev " + ",".join(DEV_CONDITIONS) + "; test all of "
                        + ",".join(EVAL_CONDITIONS))
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    parser.add_argument("--limit", type=int, help="only the first N files (a smoke run)")
    args = parser.parse_args(argv)
    conditions = (args.conditions.split(",") if args.conditions
                  else list(DEV_CONDITIONS if args.split == "dev" else EVAL_CONDITIONS))
    unknown = set(conditions) - set(EVAL_CONDITIONS)
    if unknown:
        parser.error(f"unknown conditions {sorted(unknown)} (known: {', '.join(EVAL_CONDITIONS)})")
    return recognise(args.split, conditions, args.model, args.limit)


if __name__ == "__main__":
    raise SystemExit(main())
