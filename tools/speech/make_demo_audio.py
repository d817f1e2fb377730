#!/usr/bin/env python3
"""Make the demo's spoken commands: espeak-ng text -> 16 kHz mono 16-bit WAV, deterministically.

Reads ``gcs_voice/session/demo_audio/sequence.toml`` and writes every step's ``file`` beside it. The same
espeak-ng version with the same voice, speed and text gives the same bytes, so the committed WAVs can
be checked by re-running this script (``git diff --stat`` stays empty). Resampling is done here with
numpy (linear interpolation) rather than sox, so the result does not depend on sox's version.

    python -m tools.speech.make_demo_audio            # rewrite all WAVs
    python -m tools.speech.make_demo_audio --check    # exit 1 if a committed WAV differs from a fresh one
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tomllib
import wave
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
AUDIO_DIR = ROOT / "gcs_voice" / "session" / "demo_audio"
RATE_HZ = 16_000
PAD_S = 0.3  # silence before and after, as a person leaves between commands


def synthesize(text: str, voice: str, speed_wpm: int) -> bytes:
    """espeak-ng -> WAV bytes (16 kHz, mono, int16) with PAD_S of silence on both sides."""
    raw = subprocess.run(["espeak-ng", "-v", voice, "-s", str(speed_wpm), "--stdout", text],
                         check=True, capture_output=True).stdout
    with wave.open(io.BytesIO(raw)) as w:
        rate = w.getframerate()
        samples = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(np.float64)
    n_out = int(round(len(samples) * RATE_HZ / rate))
    resampled = np.interp(np.arange(n_out) * rate / RATE_HZ, np.arange(len(samples)), samples)
    pad = np.zeros(int(PAD_S * RATE_HZ))
    pcm = np.clip(np.round(np.concatenate([pad, resampled, pad])), -32768, 32767).astype("<i2")
    out = io.BytesIO()
    with wave.open(out, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(RATE_HZ)
        w.writeframes(pcm.tobytes())
    return out.getvalue()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare instead of writing")
    args = parser.parse_args(argv)
    data = tomllib.loads((AUDIO_DIR / "sequence.toml").read_text(encoding="utf-8"))
    voices = data["voices"]
    differ = 0
    for lang, voice in voices.items():
        for step in data.get(lang, []):
            wav = synthesize(step["text"], step.get("voice", voice["voice"]),
                             int(step.get("speed_wpm", voice["speed_wpm"])))
            path = AUDIO_DIR / step["file"]
            if args.check:
                same = path.is_file() and path.read_bytes() == wav
                differ += not same
                print(f"{'same' if same else 'DIFFERS'} {path.relative_to(ROOT)}")
            else:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(wav)
                print(f"wrote {path.relative_to(ROOT)} ({len(wav) / 2 / RATE_HZ:.2f} s) {step['text']!r}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
