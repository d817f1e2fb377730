"""``--headless``: one line per event on stdout, human-readable or (``--json``) the session-log record.

For scripts, tests and SSH sessions where a live terminal view is not wanted. Lines are flushed
at once so that a reader on a pipe sees each event when it happens.
"""

from __future__ import annotations

import json
import sys
import threading
from typing import IO

from gcs_voice.session.events import Event

__all__ = ["HeadlessPrinter"]


class HeadlessPrinter:
    """EventBus subscriber printing ``+SECONDS kind message`` (or JSON) per event."""

    def __init__(self, as_json: bool = False, stream: IO[str] | None = None, t0: float | None = None) -> None:
        self.as_json = as_json
        self.stream = stream or sys.stdout
        self.t0 = t0
        self._lock = threading.Lock()

    def __call__(self, event: Event) -> None:
        if self.as_json:
            line = json.dumps(event.to_dict(), ensure_ascii=False, default=str)
        else:
            if self.t0 is None:
                self.t0 = event.t
            line = f"{event.t - self.t0:+8.2f}  {event.kind:<8} {event.msg}"
        with self._lock:
            self.stream.write(line + "\n")
            self.stream.flush()
