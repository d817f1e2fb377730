"""The JSON-lines record of a session: what was heard and what was done, one event per line.

Written beside the session's ``.tlog`` with the same stem, flushed per line so that a crash or a
Ctrl-C still leaves a readable log; ``gcs-voice plot`` reads its ``command`` events.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import IO

from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.events import Event

__all__ = ["SessionLog", "session_paths", "read_session_log"]


class SessionLogError(GcsVoiceError):
    """The log directory cannot be created or written."""


def session_paths(log_dir: str | Path, stem: str | None = None) -> tuple[Path, Path]:
    """(tlog, jsonl) for a new session in ``log_dir``: ``gcs-voice-YYYYmmdd-HHMMSS`` unless ``stem`` is given."""
    log_dir = Path(log_dir)
    try:
        log_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SessionLogError(f"cannot create log directory {log_dir}: {exc.strerror or exc}") from None
    if stem is None:
        stem = time.strftime("gcs-voice-%Y%m%d-%H%M%S", time.localtime())
        n = 1
        base = stem
        while (log_dir / f"{stem}.tlog").exists() or (log_dir / f"{stem}.jsonl").exists():
            n += 1
            stem = f"{base}-{n}"
    return log_dir / f"{stem}.tlog", log_dir / f"{stem}.jsonl"


class SessionLog:
    """Append events as JSON lines; usable as an EventBus subscriber."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._file: IO[str] | None = self.path.open("w", encoding="utf-8")
        except OSError as exc:
            raise SessionLogError(f"cannot write session log {self.path}: {exc.strerror or exc}") from None
        self._lock = threading.Lock()

    def __call__(self, event: Event) -> None:
        line = json.dumps(event.to_dict(), ensure_ascii=False, default=str)
        with self._lock:
            if self._file is not None:
                self._file.write(line + "\n")
                self._file.flush()

    def close(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None


def read_session_log(path: str | Path) -> list[dict]:
    """All complete events of a session log (a half-written last line is skipped)."""
    events = []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(record, dict):
            events.append(record)
    return events
