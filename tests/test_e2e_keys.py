"""The live view in a real terminal (a pty): keys take off and quit, and the view shows the vehicle."""

from __future__ import annotations

import os
import pty
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

from e2e_support import REPO, SPEEDUP, demo_wav, require_parts
from gcs_voice.session.session_log import read_session_log
from gcs_voice.session.sim_process import BundledSim

pytestmark = pytest.mark.slow


def _read_until(fd: int, seen: bytearray, predicate, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                seen += os.read(fd, 65536)
            except OSError:
                return predicate()
        if predicate():
            return True
    return False


def test_keys_in_the_live_view(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry")
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        master, slave = pty.openpty()
        cmd = [sys.executable, "-m", "gcs_voice", "--connect", sim.connection, "--engine", "sphinx",
               "--say", str(demo_wav("hold")), "--hold", "60", "--log-dir", str(tmp_path), "--log-name", "keys"]
        proc = subprocess.Popen(cmd, cwd=REPO, stdin=slave, stdout=slave, stderr=slave,
                                env={**os.environ, "COLUMNS": "100", "LINES": "40", "TERM": "xterm"})
        os.close(slave)
        screen = bytearray()
        log = tmp_path / "keys.jsonl"

        def logged(kind: str, **fields) -> bool:
            if not log.is_file():
                return False
            return any(e["kind"] == kind and all(e.get(k) == v for k, v in fields.items())
                       for e in read_session_log(log))

        try:
            assert _read_until(master, screen, lambda: logged("link", state="connected"), 40), screen[-2000:]
            os.write(master, b"t")  # take off by key
            assert _read_until(master, screen, lambda: logged("flight", what="take_off", ok=True), 60), screen[-2000:]
            os.write(master, b"q")  # quit: the vehicle is stopped, the session ends
            _read_until(master, screen, lambda: proc.poll() is not None, 20)
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait(10)
            os.close(master)
    assert proc.returncode == 0
    events = read_session_log(log)
    assert any(e["kind"] == "command" and e.get("action") == "take_off" and e.get("origin") == "key" for e in events)
    assert any(e["kind"] == "session" and e.get("phase") == "quit" for e in events)
    text = screen.decode("utf-8", "replace")
    for panel in ("vehicle", "ArduPilot", "GUIDED", "ARMED", "keys: t take off"):
        assert panel in text, panel
