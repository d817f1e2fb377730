"""Benchmark the simulator's physics: step responses, hover hold, yaw turn, lockstep speed.

    nice -n 10 python -m tools.bench_sim            # writes docs/bench/sim.md and docs/bench/img/sim_*.png
    python -m tools.bench_sim --no-write            # print the figures only

Everything runs in lockstep (``Multicopter.step`` in a loop) on one core; wall time is process CPU time.
Targets (issue): 1 m/s step reaches 90 % within 1.5 s with < 20 % overshoot; hover holds altitude within
+/-5 cm; a 90 deg yaw turn settles within 3 s to +/-3 deg; the physics runs well above 20x real time.
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim_bridge.control import ControlTarget
from sim_bridge.multicopter import Multicopter
from sim_bridge.world import load_room

REPO = Path(__file__).resolve().parent.parent
DOC = REPO / "docs" / "bench" / "sim.md"
IMG = REPO / "docs" / "bench" / "img"
STEP_S = 0.02          # lockstep period used by the bench (50 Hz, like a telemetry loop)
HOVER_DOWN_M = -1.5
COMMAND = "nice -n 10 python -m tools.bench_sim"


@dataclass
class Trace:
    t_s: np.ndarray
    values: np.ndarray


def hovering(physics_hz: float) -> Multicopter:
    vehicle = Multicopter(load_room("open_field"), physics_hz=physics_hz)
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, HOVER_DOWN_M)))
    run(vehicle, 8.0, lambda s: 0.0)
    return vehicle


def run(vehicle: Multicopter, seconds: float, pick) -> Trace:
    t0 = vehicle.t_s
    ts, vs = [], []
    for _ in range(round(seconds / STEP_S)):
        vehicle.step(STEP_S)
        state = vehicle.state
        ts.append(state.t_s - t0)
        vs.append(pick(state))
    return Trace(np.array(ts), np.array(vs))


def step_metrics(trace: Trace, target: float, tolerance: float) -> dict[str, float]:
    """90 % rise time, overshoot (% of the step) and settling time into +/-tolerance."""
    v = trace.values / target
    above = np.nonzero(v >= 0.9)[0]
    outside = np.nonzero(np.abs(trace.values - target) > tolerance)[0]
    settle = trace.t_s[outside[-1] + 1] if len(outside) and outside[-1] + 1 < len(v) else (
        0.0 if not len(outside) else math.inf)
    return {
        "rise90_s": float(trace.t_s[above[0]]) if len(above) else math.inf,
        "overshoot_pct": float(max(0.0, (v.max() - 1.0) * 100.0)),
        "settle_s": float(settle),
        "final": float(trace.values[-1]),
    }


def velocity_step(physics_hz: float, axis: int) -> tuple[Trace, dict[str, float]]:
    vehicle = hovering(physics_hz)
    target = [0.0, 0.0, 0.0]
    target[axis] = 1.0 if axis < 2 else -1.0   # vertical: climb
    vehicle.set_target(ControlTarget(vel_ned_m_s=tuple(target)))
    trace = run(vehicle, 4.0, lambda s: s.vel_ned_m_s[axis])
    return trace, step_metrics(trace, target[axis], 0.05)


def yaw_step(physics_hz: float) -> tuple[Trace, dict[str, float]]:
    vehicle = hovering(physics_hz)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, HOVER_DOWN_M), yaw_rad=math.pi / 2))
    trace = run(vehicle, 5.0, lambda s: math.degrees(s.yaw_rad))
    return trace, step_metrics(trace, 90.0, 3.0)


def hover_hold(physics_hz: float) -> tuple[Trace, dict[str, float]]:
    vehicle = hovering(physics_hz)
    trace = run(vehicle, 30.0, lambda s: -s.pos_ned_m[2])
    error = trace.values + HOVER_DOWN_M
    return trace, {"max_error_m": float(np.abs(error).max()), "rms_error_m": float(np.sqrt((error ** 2).mean()))}


def speed(physics_hz: float, sim_s: float = 120.0) -> dict[str, float]:
    """Real-time factor of a busy flight: takeoff, legs in four directions with yaw, landing."""
    vehicle = Multicopter(load_room("living_room"), physics_hz=physics_hz)
    legs = [ControlTarget(pos_ned_m=(0.0, 0.0, -1.2)), ControlTarget(vel_ned_m_s=(1.0, 0.0, 0.0), yaw_rad=0.0),
            ControlTarget(vel_ned_m_s=(0.0, 1.0, 0.0), yaw_rate_rad_s=0.5),
            ControlTarget(vel_ned_m_s=(-1.0, 0.0, 0.0), yaw_rad=math.pi),
            ControlTarget(vel_ned_m_s=(0.0, -1.0, 0.3)), ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.5))]
    vehicle.set_armed(True)
    start = time.process_time()
    steps = round(sim_s / STEP_S)
    for k in range(steps):
        if k % round(sim_s / len(legs) / STEP_S) == 0:
            vehicle.set_target(legs[min(len(legs) - 1, k * len(legs) // steps)])
        vehicle.step(STEP_S)
        _ = vehicle.state
    cpu_s = time.process_time() - start
    return {"sim_s": sim_s, "cpu_s": cpu_s, "realtime_x": sim_s / cpu_s,
            "physics_steps_per_s": sim_s * physics_hz / cpu_s}


def plot(path: Path, title: str, ylabel: str, traces: list[tuple[str, Trace]], target: float | None,
         band: float | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    for label, trace in traces:
        ax.plot(trace.t_s, trace.values, label=label)
    if target is not None:
        ax.axhline(target, color="k", lw=0.8, ls="--", label="target")
    if band is not None and target is not None:
        ax.axhspan(target - band, target + band, color="g", alpha=0.12, label=f"+/-{band:g}")
    ax.set_xlabel("time since command (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
