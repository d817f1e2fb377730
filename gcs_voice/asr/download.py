"""Fetch a Vosk model for a language, the way ``vosk.Model(lang=...)`` would, but only when asked.

The vosk package downloads silently whenever a model is missing; a ground station should not start
a 40-80 MB download in the middle of a session, so recognising never downloads here:
``gcs-voice download vosk --lang es`` does, once. Same source and choice as the vosk package
(``model-list.json`` at alphacephei.com: the small, non-obsolete model of the language), same place
(``$VOSK_MODEL_PATH`` or ``~/.cache/vosk``), so the model is then found by name. The archive is
unpacked beside the target and renamed into place only when it holds a Vosk model: an interrupted
or bad download leaves nothing that looks like a model.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import urllib.error
import urllib.request
import zipfile
from collections.abc import Callable
from pathlib import Path

from gcs_voice.asr.models import VOSK_DOWNLOAD_URL, WHISPER_SIZES, check_vosk_model_dir, vosk_model_in
from gcs_voice.errors import ModelError

__all__ = ["vosk_download_dir", "vosk_model_list", "choose_vosk_model", "download_vosk_model", "download_whisper_model"]

#: Environment variable naming another server with the same layout (a mirror, or a test server).
URL_ENV = "GCS_VOICE_VOSK_URL"
TIMEOUT_S = 20.0


def vosk_download_dir() -> Path:
    """Where a downloaded model goes: ``$VOSK_MODEL_PATH`` if set, else ``~/.cache/vosk``."""
    return Path(os.environ.get("VOSK_MODEL_PATH") or Path.home() / ".cache" / "vosk")


def _base_url(base_url: str | None) -> str:
    return (base_url or os.environ.get(URL_ENV) or VOSK_DOWNLOAD_URL).rstrip("/")


def _open(url: str, dest: Path):
    try:
        return urllib.request.urlopen(url, timeout=TIMEOUT_S)  # noqa: S310 (http/https URLs only, checked below)
    except urllib.error.HTTPError as exc:
        raise ModelError(f"cannot download {url}: HTTP {exc.code} {exc.reason}") from None
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", exc)
        raise ModelError(f"cannot download {url}: {reason} (offline? unzip a model from {VOSK_DOWNLOAD_URL} "
                         f"into {dest})") from None


def vosk_model_list(base_url: str | None = None, dest: Path | None = None) -> list[dict]:
    """The server's ``model-list.json`` (name, lang, type, obsolete... per model)."""
    url = f"{_base_url(base_url)}/model-list.json"
    if not url.startswith(("http://", "https://")):
        raise ModelError(f"not an http(s) URL: {url}")
    with _open(url, dest or vosk_download_dir()) as response:
        body = response.read(8 * 1024 * 1024)
    try:
        models = json.loads(body)
    except ValueError:
        raise ModelError(f"{url} is not a JSON model list") from None
    if not isinstance(models, list) or not all(isinstance(m, dict) for m in models):
        raise ModelError(f"{url} is not a list of models")
    return models


def choose_vosk_model(models: list[dict], lang: str) -> str:
    """The vosk package's choice: the small, non-obsolete model of ``lang`` (first listed)."""
    for m in models:
        if m.get("lang") == lang and m.get("type") == "small" and str(m.get("obsolete")) == "false":
            name = str(m.get("name", ""))
            if name and "/" not in name and "\\" not in name and not name.startswith("."):
                return name
    langs = sorted({str(m.get("lang")) for m in models if m.get("type") == "small"})
    raise ModelError(f"no small Vosk model for {lang!r} on the server (languages: {', '.join(langs) or 'none'})")


def _fetch(url: str, target: Path, dest: Path, progress: Callable[[str], None]) -> None:
    with _open(url, dest) as response, target.open("wb") as out:
        total = int(response.headers.get("Content-Length") or 0)
        done, shown = 0, -1
        while chunk := response.read(1 << 20):
            out.write(chunk)
            done += len(chunk)
            if total > 1 << 20 and (pct := 100 * done // total) // 10 != shown:
                shown = pct // 10
                progress(f"  {done / 1e6:.0f} / {total / 1e6:.0f} MB")


def _unpack(archive: Path, name: str, into: Path) -> Path:
    """Extract ``archive`` into ``into``; the model folder inside (``name/``, or the archive's only folder)."""
    try:
        with zipfile.ZipFile(archive) as z:
            for member in z.namelist():
                parts = Path(member).parts
                if Path(member).is_absolute() or ".." in parts:
                    raise ModelError(f"{archive.name}: refusing an entry outside the model folder ({member!r})")
            z.extractall(into)
    except zipfile.BadZipFile:
        raise ModelError(f"the download of {name} is not a zip archive") from None
    inside = into / name
    if not inside.is_dir():
        folders = [p for p in into.iterdir() if p.is_dir()]
        inside = folders[0] if len(folders) == 1 else into
    return check_vosk_model_dir(inside)


def download_vosk_model(lang: str, dest: str | Path | None = None, base_url: str | None = None,
                        progress: Callable[[str], None] | None = None) -> Path:
    """Download and unpack the Vosk model for ``lang`` unless one is already there; its folder.

    A model already in ``dest`` (any ``vosk-model(-small)?-<lang>`` folder) is returned as it is.
    """
    say = progress or (lambda line: print(line, file=sys.stderr))
    dest = Path(dest).expanduser() if dest else vosk_download_dir()
    present = vosk_model_in(dest, lang)
    if present is not None:
        say(f"already there: {present}")
        return present
    name = choose_vosk_model(vosk_model_list(base_url, dest), lang)
    url = f"{_base_url(base_url)}/{name}.zip"
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ModelError(f"cannot create {dest}: {exc.strerror}") from None
    final = dest / name
    with tempfile.TemporaryDirectory(prefix=f".{name}-", dir=dest) as tmp:
        archive = Path(tmp) / f"{name}.zip"
        say(f"downloading {url}")
        _fetch(url, archive, dest, say)
        unpacked = _unpack(archive, name, Path(tmp) / "unpacked")
        archive.unlink()
        if final.exists():  # another download finished first
            raise ModelError(f"{final} appeared during the download; remove it or use it")
        shutil.move(str(unpacked), final)
    say(f"model ready: {final}")
    return final


def download_whisper_model(size: str, progress: Callable[[str], None] | None = None) -> Path:
    """faster-whisper's own download of ``Systran/faster-whisper-<size>`` into the Hugging Face cache,
    where ``--model <size>`` then finds it offline."""
    if size not in WHISPER_SIZES:
        raise ModelError(f"unknown Whisper size {size!r} (known: {', '.join(WHISPER_SIZES)})")
    say = progress or (lambda line: print(line, file=sys.stderr))
    try:
        from faster_whisper.utils import download_model
    except ImportError:
        raise ModelError("the whisper engine needs the Python package 'faster-whisper': pip install faster-whisper") from None
    say(f"downloading faster-whisper {size} from Hugging Face")
    try:
        return Path(download_model(size))
    except Exception as exc:  # huggingface_hub raises many kinds (offline, HTTP, disk)
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError(f"cannot download faster-whisper {size}: {first}") from None
