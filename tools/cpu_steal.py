"""The machine's CPU during a measurement: how much time the hypervisor took (Linux ``/proc/stat``), and
busy loops that load it on purpose.

On a shared virtual machine the host may run other guests on our cores: their time shows as *steal*.
A timing benchmark that ran while a third of its CPU time was stolen says more about the host than about
the code, and the load average does not show it (stolen time is not our load). Timing reports give the
stolen share beside their figures, so that runs on different days can be compared.

    with CpuSample() as cpu:
        ...  # the measurement
    print(cpu.describe())

    with busy_loops(2):  # both cores of a 2-core machine busy with another process
        ...
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["CpuSample", "busy_loops", "read_cpu_times"]

PROC_STAT = Path("/proc/stat")


def read_cpu_times(path: Path = PROC_STAT) -> dict[str, int] | None:
    """The machine's aggregate CPU times in clock ticks (user, nice, system, idle, iowait, irq, softirq,
    steal), or None where /proc/stat does not exist (not Linux)."""
    try:
        first = path.read_text(encoding="ascii").splitlines()[0].split()
    except (OSError, IndexError):
        return None
    if not first or first[0] != "cpu":
        return None
    names = ("user", "nice", "system", "idle", "iowait", "irq", "softirq", "steal")
    values = [int(v) for v in first[1:1 + len(names)]]
    return dict(zip(names, values + [0] * (len(names) - len(values))))


class CpuSample:
    """CPU times over a ``with`` block: the share of busy time that was stolen, and how busy we were."""

    def __init__(self, path: Path = PROC_STAT) -> None:
        self.path = path
        self.before: dict[str, int] | None = None
        self.after: dict[str, int] | None = None

    def __enter__(self) -> CpuSample:
        self.before = read_cpu_times(self.path)
        return self

    def __exit__(self, *exc) -> None:
        self.after = read_cpu_times(self.path)

    def _delta(self) -> dict[str, int] | None:
        if self.before is None or self.after is None:
            return None
        return {k: self.after[k] - self.before[k] for k in self.before}

    @property
    def steal_share(self) -> float | None:
        """Stolen ticks over the ticks the machine was running something (ours or stolen); None if unknown."""
        d = self._delta()
        if d is None:
            return None
        busy = sum(v for k, v in d.items() if k not in ("idle", "iowait"))
        return d["steal"] / busy if busy > 0 else 0.0

    def describe(self) -> str:
        """One phrase for a report: "CPU time stolen by the host: 31 % of the busy time"."""
        share = self.steal_share
        if share is None:
            return "CPU time stolen by the host: unknown (no /proc/stat)"
        return f"CPU time stolen by the host (hypervisor steal): {100 * share:.0f} % of the busy time"


@contextmanager
def busy_loops(n: int) -> Iterator[list[subprocess.Popen]]:
    """``n`` busy-loop processes for the duration of the block: "another process" loading the machine."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()
