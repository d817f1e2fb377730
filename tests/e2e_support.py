"""Helpers for the end-to-end tests: real speech (espeak-ng), the real simulator, the real CLI.

Nothing here fakes a part: WAVs come from espeak-ng (or the demo's committed espeak-ng WAVs), the
vehicle is ``python -m sim_bridge.cli`` on a free loopback port, the ground station is
``python -m gcs_voice`` run as a user would, and assertions read the tlog and session log it leaves.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

from gcs_voice.session.flight_log import Flight, read_flight
from gcs_voice.session.session_log import read_session_log
from tools.speech import make_demo_audio

REPO = Path(__file__).resolve().parent.parent
DEMO_AUDIO = REPO / "gcs_voice" / "session" / "demo_audio"
#: simulated seconds per wall second in the e2e flights (the sim keeps up with this on 2 busy cores)
SPEEDUP = 2.0


def require_parts(*modules: str) -> None:
    """Skip until the named modules of other branches are merged (in CI they are: fail there instead)."""
    import importlib.util
    import os

    missing = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:
            found = False
        if not found:
            missing.append(name)
    if missing:
        message = f"not in this checkout yet: {', '.join(missing)}"
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(message)
        pytest.skip(message)


def require_speech_tools() -> None:
    if shutil.which("espeak-ng") is None:
        pytest.skip("espeak-ng not installed")


def speech(out_dir: Path, text: str, voice: str = "en-us", speed_wpm: int = 140) -> Path:
    """A WAV of ``text`` spoken by espeak-ng (16 kHz mono, 0.3 s silence each side)."""
    require_speech_tools()
    path = out_dir / (text.replace(" ", "_") + f"_{voice}.wav")
    path.write_bytes(make_demo_audio.synthesize(text, voice, speed_wpm))
    return path


def demo_wav(name: str, lang: str = "en") -> Path:
    return DEMO_AUDIO / lang / f"{name}.wav"


@dataclass
class FlyResult:
    returncode: int
    events: list[dict]
    stdout: str
    stderr: str
    tlog: Path
    jsonl: Path

    def flight(self) -> Flight:
        return read_flight(self.tlog)

    def kinds(self, kind: str) -> list[dict]:
        return [e for e in self.events if e["kind"] == kind]

    def commands(self, origin: str = "voice") -> list[dict]:
        return [e for e in self.events if e["kind"] == "command" and e.get("origin") == origin]


def _fly_command(connection: str, wavs: list[Path], tmp_path: Path, takeoff_m: float | None, gap_s: float,
                 hold_s: float, extra: Sequence[str], listen: Path | None = None) -> list[str]:
    heard = ["--say", *map(str, wavs), "--gap", str(gap_s)] if listen is None else ["--listen-wav", str(listen)]
    cmd = [sys.executable, "-m", "gcs_voice", "--connect", connection, *heard, "--hold", str(hold_s), "--headless", "--json", "--log-dir", str(tmp_path), "--log-name", "flight",
           "--engine", "sphinx", *extra]
    if takeoff_m is not None:
        cmd += ["--takeoff", str(takeoff_m)]
    return cmd


def _fly_result(returncode: int, stdout: str, stderr: str, tmp_path: Path) -> FlyResult:
    events = []
    for line in stdout.splitlines():
        try:
            events.append(json.loads(line))
        except json.JSONDecodeError:
            pass
    jsonl = tmp_path / "flight.jsonl"
    # The console (--json) and the session log carry the same records.
    if jsonl.is_file():
        assert [e["kind"] for e in read_session_log(jsonl)] == [e["kind"] for e in events]
    return FlyResult(returncode, events, stdout, stderr, tmp_path / "flight.tlog", jsonl)


def run_fly(connection: str, wavs: list[Path], tmp_path: Path, *, takeoff_m: float | None = 1.5, gap_s: float = 3.0,
            hold_s: float = 2.0, extra: Sequence[str] = (), timeout_s: float = 150.0,
            listen: Path | None = None) -> FlyResult:
    """``python -m gcs_voice --connect ... --say ... --headless --json`` as a user would run it (``listen``:
    ``--listen-wav`` that recording instead of ``--say``)."""
    cmd = _fly_command(connection, wavs, tmp_path, takeoff_m, gap_s, hold_s, extra, listen)
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=timeout_s)
    return _fly_result(proc.returncode, proc.stdout, proc.stderr, tmp_path)


class FlyProcess:
    """``run_fly`` started in the background: ``started()`` waits for its "session start" record (the
    recogniser is loaded and the link opens next), so a vehicle started after it is met from its first packet."""

    def __init__(self, connection: str, wavs: list[Path], tmp_path: Path, *, takeoff_m: float | None = 1.5,
                 gap_s: float = 3.0, hold_s: float = 2.0, extra: Sequence[str] = ()) -> None:
        self.tmp_path = tmp_path
        self.proc = subprocess.Popen(_fly_command(connection, wavs, tmp_path, takeoff_m, gap_s, hold_s, extra),
                                     cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._head: list[str] = []

    def started(self) -> None:
        """Block until the session says it has started (or fail with what it printed if it ended first)."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._head.append(line)
            if '"kind": "session"' in line and '"phase": "start"' in line:
                return
        raise AssertionError("gcs-voice ended before its session started: " + "".join(self._head)
                             + (self.proc.stderr.read() if self.proc.stderr else ""))

    def finish(self, timeout_s: float) -> FlyResult:
        try:
            rest, stderr = self.proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rest, stderr = self.proc.communicate()
            raise AssertionError(f"gcs-voice still running after {timeout_s:g} s: " + "".join(self._head) + rest
                                 + stderr) from None
        return _fly_result(self.proc.returncode, "".join(self._head) + rest, stderr, self.tmp_path)


def speed_at(flight: Flight, t_s: float) -> float:
    tr = flight.track
    i = max(0, min(range(len(tr.t_s)), key=lambda k: abs(tr.t_s[k] - t_s)))
    return math.hypot(tr.vn_m_s[i], tr.ve_m_s[i])


def angle_diff_deg(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0
