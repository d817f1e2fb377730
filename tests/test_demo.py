"""``gcs-voice demo``: the README's first command, run as a user runs it, in a fresh directory."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from e2e_support import REPO, require_parts
from gcs_voice.session.flight_log import read_flight
from gcs_voice.session.session_log import read_session_log

pytestmark = pytest.mark.slow


def test_demo_flies_the_english_sequence_and_writes_its_outputs(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry", "gcs_voice.audio.sources")
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "demo", "--lang", "en", "--engine", "sphinx"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=180,
                          env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    elapsed = time.monotonic() - started
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr
    assert elapsed < 120
    for name in ("demo-en.tlog", "demo-en.jsonl", "demo-en.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert "utterances heard as intended" in proc.stdout

    events = read_session_log(tmp_path / "demo-en.jsonl")
    done = [e["action"] for e in events if e["kind"] == "command" and e.get("origin") in ("voice", "script")]
    assert done[0] == "take_off" and done[-1] == "land"
    assert any(e["kind"] == "command" and e.get("origin") == "voice" for e in events)  # flown by voice
    heard = [e for e in events if e["kind"] == "heard"]
    assert len(heard) == 8  # every shipped utterance went through the recogniser
    flight = read_flight(tmp_path / "demo-en.tlog")
    assert max(flight.track.alt_m) > 1.2  # it flew
    assert flight.track.alt_m[-1] < 0.2  # and landed
    # the simulator was stopped: no process is left sending to the demo's port
    port = next(e["connection"] for e in events if e["kind"] == "session" and e.get("phase") == "start").rsplit(":", 1)[1]
    running = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert f"udp:127.0.0.1:{port} " not in running and not running.rstrip().endswith(f"udp:127.0.0.1:{port}")
