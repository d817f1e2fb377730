"""The first lines of every report a tool writes: its command, then date, commit and machine load."""

from __future__ import annotations

import datetime
import os
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def header(module: str, argv: list[str] | None = None) -> str:
    """``Command: python -m MODULE ARGS`` and ``Date · commit · load`` (two lines and a blank one)."""
    args = sys.argv[1:] if argv is None else argv
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=REPO).stdout.strip() or "unknown"
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True,
                           cwd=REPO).stdout.strip()
    return (f"Command: python -m {module} {' '.join(map(shlex.quote, args))}".rstrip() + "\n"
            f"Date: {datetime.date.today().isoformat()} · commit: {commit}{' (with changes)' if dirty else ''} · "
            f"machine load: {os.getloadavg()[0]:.1f} (1-min load average, 2 cores)\n\n")
