"""tools.cpu_steal: the share of busy CPU time the hypervisor took, read from /proc/stat (timing reports)."""

from __future__ import annotations

from pathlib import Path

from tools.cpu_steal import CpuSample, busy_loops, read_cpu_times

#             user nice system idle iowait irq softirq steal guest guest_nice
BEFORE = "cpu  1000 0 100 5000 10 0 0 50 0 0\ncpu0 500 0 50 2500 5 0 0 25 0 0\n"
AFTER = "cpu  1700 0 100 5400 10 0 0 350 0 0\ncpu0 850 0 50 2700 5 0 0 175 0 0\n"


def test_steal_share_is_stolen_over_busy_ticks(tmp_path: Path) -> None:
    stat = tmp_path / "stat"
    stat.write_text(BEFORE)
    with CpuSample(stat) as cpu:
        stat.write_text(AFTER)
    # busy: 700 user + 300 steal; idle time is not busy
    assert cpu.steal_share == 0.3
    assert "30 %" in cpu.describe()


def test_no_proc_stat_is_unknown_not_an_error(tmp_path: Path) -> None:
    assert read_cpu_times(tmp_path / "missing") is None
    with CpuSample(tmp_path / "missing") as cpu:
        pass
    assert cpu.steal_share is None
    assert "unknown" in cpu.describe()


def test_this_machine_reads() -> None:
    times = read_cpu_times()
    if Path("/proc/stat").exists():
        assert times is not None and times["user"] >= 0 and "steal" in times


def test_busy_loops_run_for_the_block_only() -> None:
    with busy_loops(2) as procs:
        assert len(procs) == 2 and all(proc.poll() is None for proc in procs)
    assert all(proc.returncode is not None for proc in procs)
    with busy_loops(0) as none:
        assert none == []
