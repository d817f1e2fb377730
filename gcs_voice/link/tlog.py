"""A .tlog writer for both directions: 8-byte big-endian microseconds since the epoch + the raw packet.

pymavlink's ``setup_logfile`` records only what is received; a flight log needs what we sent too.
"""

from __future__ import annotations

import struct
import threading
import time
from pathlib import Path

__all__ = ["TlogWriter"]


class TlogWriter:
    """Append-only, thread-safe; flushed every write so a crash keeps the log."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "ab")
        self._lock = threading.Lock()
        self.records = 0

    def write(self, packet: bytes, time_s: float | None = None) -> None:
        usec = int((time.time() if time_s is None else time_s) * 1e6)
        with self._lock:
            if self._file.closed:
                return
            self._file.write(struct.pack(">Q", usec) + bytes(packet))
            self._file.flush()
            self.records += 1

    def close(self) -> None:
        with self._lock:
            self._file.close()
