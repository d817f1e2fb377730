"""Run the bundled simulator as a child process on a free loopback port, and always stop it.

The bridge never imports ``sim_bridge``: the two meet only on the wire, as with a real vehicle. The
demo, the end-to-end tests and the latency benchmark all start the simulator through this module
(``sys.executable -m sim_bridge.cli``), so they use the same flags and the same clean-up.
"""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from gcs_voice.errors import GcsVoiceError

__all__ = ["BundledSim", "free_udp_port", "SimError"]


class SimError(GcsVoiceError):
    """The bundled simulator could not be started or ended early."""


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that nothing is bound to right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class BundledSim:
    """``with BundledSim(autopilot="ardupilot", speedup=2) as sim: connect to sim.connection``.

    The simulator sends to ``udp:127.0.0.1:PORT``; the ground station listens there
    (``sim.connection`` is the matching ``udpin:`` string). ``speedup`` infinity is ``--speedup max``.
    """

    def __init__(self, autopilot: str = "ardupilot", speedup: float | None = None, room: str | None = None,
                 port: int | None = None, extra_args: Sequence[str] = (), log_path: Path | None = None,
                 sim_tlog: Path | None = None) -> None:
        self.port = port or free_udp_port()
        self.autopilot = autopilot
        self.speedup = speedup
        self.room = room
        self.extra_args = list(extra_args)
        self.log_path = log_path
        self.sim_tlog = sim_tlog
        self.process: subprocess.Popen | None = None
        self._log_file = None

    @property
    def connection(self) -> str:
        return f"udpin:127.0.0.1:{self.port}"

    def command(self) -> list[str]:
        cmd = [sys.executable, "-m", "sim_bridge.cli", "--out", f"udp:127.0.0.1:{self.port}",
               "--autopilot", self.autopilot]
        if self.speedup:
            cmd += ["--speedup", "max" if math.isinf(self.speedup) else f"{self.speedup:g}"]
        if self.room:
            cmd += ["--room", self.room]
        if self.sim_tlog:
            cmd += ["--tlog", str(self.sim_tlog)]
        return cmd + self.extra_args

    def start(self) -> "BundledSim":
        env = dict(os.environ)
        # The package that holds gcs_voice holds sim_bridge too (source tree or wheel): make it importable
        # for the child even when the parent was started from elsewhere.
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self._log_file = open(self.log_path, "wb") if self.log_path else subprocess.DEVNULL
        try:
            self.process = subprocess.Popen(self.command(), stdout=self._log_file, stderr=subprocess.STDOUT,
                                            stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        except OSError as exc:
            raise SimError(f"cannot start the bundled simulator: {exc}") from None
        time.sleep(0.2)
        if self.process.poll() is not None:
            raise SimError(f"the bundled simulator exited at once (status {self.process.returncode})"
                           + (f"; see {self.log_path}" if self.log_path else ""))
        return self

    def pause(self) -> None:
        """Freeze the simulator (SIGSTOP): the vehicle falls silent, as on a lost link."""
        if self.process is not None and self.process.poll() is None:
            os.kill(self.process.pid, signal.SIGSTOP)

    def resume(self) -> None:
        if self.process is not None and self.process.poll() is None:
            os.kill(self.process.pid, signal.SIGCONT)

    def stop(self) -> None:
        """Terminate, then kill after 5 s; safe to call twice and after a crash."""
        proc = self.process
        if proc is not None and proc.poll() is None:
            try:
                os.kill(proc.pid, signal.SIGCONT)  # a paused process cannot handle SIGTERM
                proc.terminate()
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5.0)
            except ProcessLookupError:
                pass
        if self._log_file not in (None, subprocess.DEVNULL):
            self._log_file.close()
            self._log_file = None

    def __enter__(self) -> "BundledSim":
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()
