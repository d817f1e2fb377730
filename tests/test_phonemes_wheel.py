"""The phonetic matcher works with pip alone: espeak-ng from the espeakng-loader wheel gives the same phonemes."""

from __future__ import annotations

import subprocess
import sys

_PROBE = """
import ctypes.util, sys
if sys.argv[1] == "wheel":
    ctypes.util.find_library = lambda name: None   # as on a machine without Debian's espeak-ng
from gcs_voice.understanding import phonemes
for text, voice in [("go right", "en-us"), ("turn counterclockwise", "en-us"), ("gira a la derecha", "es")]:
    print(phonemes.ipa(text, voice))
print(phonemes.library_name())
"""


def _probe(which: str) -> list[str]:
    out = subprocess.run([sys.executable, "-c", _PROBE, which], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines()


def test_wheel_espeak_gives_the_system_phonemes() -> None:
    system, wheel = _probe("system"), _probe("wheel")
    assert "espeakng_loader" in wheel[-1] and "espeakng_loader" not in system[-1]
    assert wheel[:-1] == system[:-1]
    assert wheel[0].replace("ˌ", "").replace("ˈ", "") == "ɡoʊ ɹaɪt"
