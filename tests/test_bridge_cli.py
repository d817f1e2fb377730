"""``gcs-voice`` (fly) user mistakes: each is one line on stderr and exit status 2, never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from e2e_support import REPO, demo_wav
from gcs_voice.session.sim_process import free_udp_port


def _fly(*args: str, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gcs_voice", *args, "--headless", "--log-dir", str(tmp_path)],
                          cwd=REPO, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("args, message", [
    (["--connect", "udpin://0.0.0.0:14540"], "udpin"),
    (["--udp", "70000"], "70000"),
    (["--say", "/no/such/file.wav", "--engine", "sphinx"], "/no/such/file.wav"),
    (["--engine", "nonsense"], "nonsense"),
    (["--matcher", "nonsense", "--engine", "sphinx"], "nonsense"),
])
def test_bad_input_is_one_line(args: list[str], message: str, tmp_path: Path) -> None:
    proc = _fly(*args, tmp_path=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("gcs-voice: error:") and proc.stderr.count("\n") == 1, proc.stderr
    assert message in proc.stderr
    assert list(tmp_path.iterdir()) == []  # nothing was flown, so no session logs


def test_no_vehicle_is_one_line_and_leaves_the_logs(tmp_path: Path) -> None:
    port = free_udp_port()
    proc = _fly("--connect", f"udpin:127.0.0.1:{port}", "--wait", "1", "--engine", "sphinx", "--say",
                str(demo_wav("hover")), "--log-name", "s", tmp_path=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("gcs-voice: error: no vehicle heard")
    assert (tmp_path / "s.jsonl").is_file()  # the attempt is on record
