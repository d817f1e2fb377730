"""Run the bundled simulator as a child process on loopback, ready when it says so, and always stop it.

The bridge never imports ``sim_bridge``: the two meet only on the wire, as with a real vehicle. The
demo, the tests and the benchmarks all start the simulator through this module
(``sys.executable -m sim_bridge.cli``), so they use the same flags, the same readiness and the same clean-up.
"""

from __future__ import annotations

import math
import os
import re
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import IO

from gcs_voice.errors import GcsVoiceError

__all__ = ["BundledSim", "free_udp_port", "SimError"]

#: the line gcs-sim prints once its sockets are open ("gcs-sim: ArduCopter quad ready in open_field, ...")
READY_LINE = re.compile(r"^gcs-sim: .* ready in ")
#: not a guess at readiness (the ready line says it): how long a child that prints nothing may hang start()
READY_TIMEOUT_S = 60.0
#: how long stop() lets a terminated simulator finish (close its tlog, print its last line) before killing it
STOP_TIMEOUT_S = 10.0


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
    ``tcp=True`` also serves TCP on a free port (``sim.tcp_port``, read from the ready line); ``udp=False``
    sends to no UDP port (``sim.port`` is None; ``sim.connection`` is then ``tcp:127.0.0.1:TCP_PORT``).
    ``start()`` returns once the simulator printed its ready line; its stdout and stderr are kept (``ready``,
    ``stop()``'s return, ``stderr``) and copied to ``log_path``.
    """

    def __init__(self, autopilot: str = "ardupilot", speedup: float | None = None, room: str | None = None,
                 port: int | None = None, extra_args: Sequence[str] = (), log_path: Path | None = None,
                 sim_tlog: Path | None = None, tcp: bool = False, udp: bool = True) -> None:
        self.port = (port or free_udp_port()) if udp else None
        self.autopilot = autopilot
        self.speedup = speedup
        self.room = room
        self.tcp = tcp
        self.extra_args = list(extra_args)
        self.log_path = log_path
        self.sim_tlog = sim_tlog
        self.process: subprocess.Popen | None = None
        #: the simulator's ready line ("" until start() returned)
        self.ready = ""
        #: the TCP port the simulator serves, from its ready line (None without ``--tcp``)
        self.tcp_port: int | None = None
        self._stdout: list[str] = []
        self._stderr: list[str] = []
        self._said_ready = threading.Event()
        self._readers: list[threading.Thread] = []
        self._log_file: IO[str] | None = None
        self._log_lock = threading.Lock()

    @property
    def connection(self) -> str:
        """What a ground station connects with: ``udpin:`` on the UDP out, else ``tcp:`` to the TCP port."""
        if self.port is not None:
            return f"udpin:127.0.0.1:{self.port}"
        if self.tcp_port is not None:
            return f"tcp:127.0.0.1:{self.tcp_port}"
        raise SimError("no connection to the bundled simulator: udp=False and "
                       + ("its TCP port is known once start() returned" if self.tcp else "tcp=False"))

    @property
    def stderr(self) -> str:
        """What the simulator wrote to stderr so far (a crash's traceback, a flag error)."""
        return "".join(self._stderr)

    def command(self) -> list[str]:
        cmd = [sys.executable, "-m", "sim_bridge.cli", "--autopilot", self.autopilot]
        if self.port is not None:
            cmd += ["--out", f"udp:127.0.0.1:{self.port}"]
        if self.tcp:
            cmd += ["--tcp", "127.0.0.1:0"]
        if self.speedup:
            cmd += ["--speedup", "max" if math.isinf(self.speedup) else f"{self.speedup:g}"]
        if self.room:
            cmd += ["--room", self.room]
        if self.sim_tlog:
            cmd += ["--tlog", str(self.sim_tlog)]
        return cmd + self.extra_args

    def start(self) -> "BundledSim":
        """Start the simulator and wait for its ready line; SimError (with its stderr) if it exits first."""
        env = dict(os.environ)
        # The package that holds gcs_voice holds sim_bridge too (source tree or wheel): make it importable
        # for the child even when the parent was started from elsewhere.
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self._log_file = open(self.log_path, "w", encoding="utf-8") if self.log_path else None
        try:
            self.process = subprocess.Popen(self.command(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                            stdin=subprocess.DEVNULL, env=env, start_new_session=True, text=True,
                                            errors="replace")
        except OSError as exc:
            self._close_log()
            raise SimError(f"cannot start the bundled simulator: {exc}") from None
        self._readers = [threading.Thread(target=self._read, args=(stream, lines), name=f"sim-{name}", daemon=True)
                         for name, stream, lines in (("stdout", self.process.stdout, self._stdout),
                                                     ("stderr", self.process.stderr, self._stderr))]
        for reader in self._readers:
            reader.start()
        if not self._said_ready.wait(READY_TIMEOUT_S):
            self.stop()
            raise SimError(f"the bundled simulator did not say it was ready within {READY_TIMEOUT_S:g} s"
                           + self._see_log())
        if not self.ready:
            self.stop()
            last = self.stderr.strip().splitlines()[-1:] or [""]
            raise SimError(f"the bundled simulator exited at once (status {self.process.returncode})"
                           + (f": {last[0]}" if last[0] else "") + self._see_log())
        found = re.search(r"tcp [\d.]+:(\d+)", self.ready)
        self.tcp_port = int(found.group(1)) if found else None
        return self

    def _read(self, stream: IO[str], lines: list[str]) -> None:
        """Keep each line of one of the child's streams (and log it); the first ready line releases start()."""
        for line in stream:
            lines.append(line)
            if self._log_file is not None:
                with self._log_lock:
                    self._log_file.write(line)
                    self._log_file.flush()
            if not self.ready and stream is self.process.stdout and READY_LINE.match(line):
                self.ready = line
                self._said_ready.set()
        if stream is self.process.stdout:
            self._said_ready.set()  # the end of stdout: no ready line will come

    def _see_log(self) -> str:
        return f"; see {self.log_path}" if self.log_path else ""

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def pause(self) -> None:
        """Freeze the simulator (SIGSTOP): the vehicle falls silent, as on a lost link."""
        if self.alive():
            os.kill(self.process.pid, signal.SIGSTOP)

    def resume(self) -> None:
        if self.alive():
            os.kill(self.process.pid, signal.SIGCONT)

    def stop(self) -> str:
        """Terminate, then kill after ``STOP_TIMEOUT_S``; safe to call twice and after a crash.

        Returns what the simulator printed after its ready line (its last line counts what it did)."""
        proc = self.process
        if proc is not None and proc.poll() is None:
            try:
                os.kill(proc.pid, signal.SIGCONT)  # a paused process cannot handle SIGTERM
                proc.terminate()
                proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=STOP_TIMEOUT_S)
            except ProcessLookupError:
                pass
        for reader in self._readers:  # the child has exited: its pipes end, and so do the readers
            reader.join(timeout=STOP_TIMEOUT_S)
        self._close_log()
        after = self._stdout[self._stdout.index(self.ready) + 1:] if self.ready in self._stdout else self._stdout
        return "".join(after)

    def _close_log(self) -> None:
        with self._log_lock:
            if self._log_file is not None:
                self._log_file.close()
                self._log_file = None

    def __enter__(self) -> "BundledSim":
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()
