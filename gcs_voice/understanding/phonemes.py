"""Text -> IPA phoneme tokens with espeak-ng, in-process (libespeak-ng via ctypes) and cached.

The library call takes microseconds; if the shared library cannot be loaded we fall back to the
``espeak-ng -q --ipa`` command (milliseconds). Tokens drop stress, length and word boundaries, and
keep diphthongs and affricates as one token, so "takeoff" and "take off" sound the same.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import shutil
import subprocess
import threading
from functools import lru_cache

from gcs_voice.errors import GcsVoiceError

__all__ = ["PhonemeError", "ipa", "phoneme_tokens", "library_name", "ESPEAK_VOICE"]

#: dictionary language -> espeak-ng voice used to pronounce it. Spanish is pronounced as in Latin America
#: (es-419: seseo, "z" and "c" before e/i sound "s"), as most Spanish speakers say it: Whisper writes what it hears
#: with any of the three letters ("Asiala" for "hacia la"), and Spain's "θ" would make each such spelling a
#: different sound (issue 31, item 4; chosen by python -m tools.speech.bench_spanish: more commands right, none wrong).
ESPEAK_VOICE = {"en": "en-us", "es": "es-419"}
#: multi-character phonemes kept as one token (longest first).
_MULTI = sorted(
    ["aɪ", "aʊ", "eɪ", "oʊ", "ɔɪ", "əʊ", "ɪə", "eə", "ʊə", "tʃ", "dʒ", "ɜː", "ɑː", "iː", "uː", "ɔː"],
    key=len, reverse=True,
)
_DROP = set("ˈˌːˑ ‿-_|'\u0361\u035c")

_lock = threading.Lock()
_lib: ctypes.CDLL | None = None
_lib_failed = False
_ESPEAK_CHARS_UTF8 = 1
_PHONEMES_IPA = 0x02
_AUDIO_OUTPUT_SYNCHRONOUS = 0x02


class PhonemeError(GcsVoiceError):
    """espeak-ng is not installed (neither its library nor its command)."""


def _library() -> ctypes.CDLL | None:
    global _lib, _lib_failed
    if _lib is not None or _lib_failed:
        return _lib
    try:
        lib, data_path = _load_espeak()
        lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
        lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
        lib.espeak_TextToPhonemes.restype = ctypes.c_char_p
        lib.espeak_TextToPhonemes.argtypes = [ctypes.POINTER(ctypes.c_char_p), ctypes.c_int, ctypes.c_int]
        if lib.espeak_Initialize(_AUDIO_OUTPUT_SYNCHRONOUS, 0, data_path, 0) <= 0:
            raise OSError("espeak_Initialize failed")
        _lib = lib
    except (OSError, AttributeError):
        _lib_failed = True
    return _lib


def library_name() -> str | None:
    """The espeak-ng library ``ipa`` uses (the system's or the pip wheel's); None when only the command is there."""
    with _lock:
        lib = _library()
    return None if lib is None else lib._name


def _load_espeak() -> tuple[ctypes.CDLL, bytes | None]:
    """The system's libespeak-ng (Debian's espeak-ng), else the copy in the ``espeakng-loader`` wheel.

    The wheel is a dependency so that ``pip install`` alone is enough for the phonetic matcher;
    the system library wins when present because it is the one the tests' speech was made with.
    """
    name = ctypes.util.find_library("espeak-ng")
    if name:
        try:
            return ctypes.cdll.LoadLibrary(name), None
        except OSError:
            pass
    try:
        import espeakng_loader
    except ImportError:
        return ctypes.cdll.LoadLibrary("libespeak-ng.so.1"), None
    return (ctypes.cdll.LoadLibrary(espeakng_loader.get_library_path()),
            espeakng_loader.get_data_path().encode())


@lru_cache(maxsize=8192)
def ipa(text: str, voice: str) -> str:
    """IPA transcription of ``text`` as spoken by espeak-ng ``voice`` (cached)."""
    if not text:
        return ""
    with _lock:
        lib = _library()
        if lib is not None:
            if lib.espeak_SetVoiceByName(voice.encode()) != 0:
                raise PhonemeError(f"espeak-ng has no voice {voice!r}")
            buf = ctypes.c_char_p(text.encode("utf-8"))
            ptr = ctypes.cast(ctypes.pointer(buf), ctypes.POINTER(ctypes.c_char_p))
            parts = []
            while buf.value:
                out = lib.espeak_TextToPhonemes(ptr, _ESPEAK_CHARS_UTF8, _PHONEMES_IPA)
                if out is None:
                    break
                parts.append(out.decode("utf-8", "replace"))
            return " ".join(parts)
    exe = shutil.which("espeak-ng")
    if exe is None:
        raise PhonemeError("espeak-ng is needed for phonetic matching (apt install espeak-ng)")
    done = subprocess.run([exe, "-q", "--ipa", "-v", voice, text], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise PhonemeError(f"espeak-ng failed for voice {voice!r}: {done.stderr.strip()}")
    return " ".join(done.stdout.split())


@lru_cache(maxsize=8192)
def phoneme_tokens(text: str, voice: str) -> tuple[str, ...]:
    """Phoneme tokens of ``text`` (no stress, length or word boundaries)."""
    s = ipa(text, voice)
    tokens: list[str] = []
    i = 0
    while i < len(s):
        for m in _MULTI:
            if s.startswith(m, i):
                tokens.append(m.rstrip("ː"))
                i += len(m)
                break
        else:
            if s[i] not in _DROP:
                tokens.append(s[i])
            i += 1
    return tuple(tokens)
