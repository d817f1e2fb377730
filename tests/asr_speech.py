"""Test speech made on the spot with espeak-ng (and sox for other WAV formats): real audio, no files committed.

sox runs with -R (repeatable): its dither is otherwise random, and PocketSphinx answers differently to
the same words under different dither ("open the door" vs "oh lord" about one run in six), which made
tests flaky. The dither itself stays: without it espeak's exact digital silence throws PocketSphinx off.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from gcs_voice.audio.sources import read_wav


def need(tool: str) -> None:
    if shutil.which(tool) is None:
        pytest.skip(f"{tool} not installed")


def say(text: str, path: Path, voice: str = "en-us", speed_wpm: int = 175) -> Path:
    """Speak ``text`` into a 16 kHz mono s16le WAV at ``path``."""
    need("espeak-ng")
    need("sox")
    raw = path.with_suffix(".espeak.wav")
    subprocess.run(["espeak-ng", "-v", voice, "-s", str(speed_wpm), "-w", str(raw), text], check=True)
    subprocess.run(["sox", "-R", str(raw), "-r", "16000", "-c", "1", "-b", "16", str(path)], check=True)
    raw.unlink()
    return path


def pcm_of(text: str, tmp: Path, voice: str = "en-us") -> bytes:
    name = "".join(c if c.isalnum() else "_" for c in text)[:40] or "speech"
    return read_wav(say(text, tmp / f"{voice}_{name}.wav", voice))
