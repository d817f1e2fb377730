"""Benchmark the simulator's physics: step responses, hover hold, yaw turn, touchdowns, lockstep speed.

    nice -n 10 python -m tools.sim.bench_sim            # writes docs/bench/sim.md and docs/bench/img/sim_*.png
    python -m tools.sim.bench_sim --no-write            # print the figures only

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

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "bench" / "sim.md"
IMG = REPO / "docs" / "bench" / "img"
STEP_S = 0.02          # lockstep period used by the bench (50 Hz, like a telemetry loop)
HOVER_DOWN_M = -1.5
DISTURB_DOWN_N = 2.0
DISTURB_EAST_N = 1.0
SPEED_REPEATS = 5     # the machine is shared: report the best of five
COMMAND = "nice -n 10 python -m tools.sim.bench_sim"
# sideways touchdowns from a 1.5 m hover: (room, mode, horizontal m or m/s, heading deg, yaw rate rad/s);
# "vel": descend at the 2.5 m/s limit while moving sideways; "pos": a target that far away, 0.5 m underground
TOUCHDOWNS = [(room, mode, size, heading, yaw_rate) for room in ("open_field", "living_room")
              for mode, size, heading, yaw_rate in (("vel", 2.0, 0.0, 0.0), ("vel", 5.0, 45.0, 0.0),
                                                    ("vel", 5.0, 90.0, 1.5), ("vel", 3.0, 200.0, -1.5),
                                                    ("pos", 4.0, 0.0, 0.0), ("pos", 8.0, 135.0, 1.0))]
REST_M_S = 0.05


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


def disturbance(physics_hz: float) -> tuple[Trace, Trace, dict[str, float]]:
    """Hold position at 1.5 m under pushes: 2 N down (15 % of the weight), then 1 N east, 3 s each."""
    vehicle = hovering(physics_hz)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, HOVER_DOWN_M)))
    pick = lambda s: (s.pos_ned_m[1], -s.pos_ned_m[2])  # noqa: E731
    parts = []
    for force in ((0.0, 0.0, DISTURB_DOWN_N), (0.0, 0.0, 0.0), (0.0, DISTURB_EAST_N, 0.0), (0.0, 0.0, 0.0)):
        vehicle.set_disturbance_force_ned_n(force)
        parts.append(run(vehicle, 3.0, pick))
    t = np.concatenate([p.t_s + 3.0 * i for i, p in enumerate(parts)])
    v = np.concatenate([p.values for p in parts])
    height = Trace(t, v[:, 1])
    east = Trace(t, v[:, 0])
    push_end = len(parts[0].t_s) * 3 - 1
    return height, east, {"max_height_error_m": float(np.abs(height.values + HOVER_DOWN_M).max()),
                          "height_error_end_m": float(abs(height.values[len(parts[0].t_s) - 1] + HOVER_DOWN_M)),
                          "max_east_error_m": float(np.abs(east.values).max()),
                          "east_error_end_m": float(abs(east.values[push_end]))}


def wall_contact(physics_hz: float) -> tuple[Trace, dict[str, float]]:
    """Fly north at 2 m/s into the living room's north wall at 1.2 m: where does it stop, what is reported."""
    vehicle = Multicopter(load_room("living_room"), physics_hz=physics_hz)
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, -1.2)))
    run(vehicle, 5.0, lambda s: 0.0)
    vehicle.pop_events()
    room = vehicle.room
    surface_m = room.bounds_max_m[0] - room.start_xy_m[0] - 0.25  # wall minus the vehicle's radius
    vehicle.set_target(ControlTarget(vel_ned_m_s=(2.0, 0.0, 0.0)))
    trace = run(vehicle, 4.0, lambda s: s.pos_ned_m[0])
    events = vehicle.pop_events()
    return trace, {"surface_m": surface_m, "max_m": float(trace.values.max()), "final_m": float(trace.values[-1]),
                   "events": ", ".join(f"{e.obstacle_name} at {e.t_s:.2f} s" for e in events)}


def plot_room(path: Path, room_name: str, path_ned: np.ndarray | None = None) -> None:
    """Top view of a room: blocks, walls, the start spot and (optionally) a flown path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    room = load_room(room_name)
    fig, ax = plt.subplots(figsize=(6.4, 5.6), dpi=100)
    (x0, y0, _), (x1, y1, z1) = room.bounds_min_m, room.bounds_max_m
    ax.add_patch(Rectangle((y0, x0), y1 - y0, x1 - x0, fill=False, lw=2, color="k"))
    for block in room.blocks:
        (bx0, by0, _), (bx1, by1, bz1) = block.min_m, block.max_m
        ax.add_patch(Rectangle((by0, bx0), by1 - by0, bx1 - bx0, color="tab:brown", alpha=0.35))
        ax.text((by0 + by1) / 2, (bx0 + bx1) / 2, f"{block.name}\n{bz1:.2f} m", ha="center", va="center", fontsize=7)
    sx, sy = room.start_xy_m
    ax.plot([sy], [sx], "o", color="tab:blue", label="start (home)")
    ax.annotate("", xy=(sy + 0.5 * math.sin(math.radians(room.start_yaw_deg)),
                        sx + 0.5 * math.cos(math.radians(room.start_yaw_deg))),
                xytext=(sy, sx), arrowprops={"arrowstyle": "->", "color": "tab:blue"})
    if path_ned is not None:
        ax.plot(path_ned[:, 1] + sy, path_ned[:, 0] + sx, color="tab:red", lw=1, label="flown path")
    ax.set_xlim(y0 - 0.2, y1 + 0.2)
    ax.set_ylim(x0 - 0.2, x1 + 0.2)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"{room.name}: top view, ceiling {z1:.1f} m")
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot(path: Path, title: str, ylabel: str, traces: list[tuple[str, Trace]], target: float | None,
         band: float | None, target_label: str = "target") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    for label, trace in traces:
        ax.plot(trace.t_s, trace.values, label=label)
    if target is not None:
        ax.axhline(target, color="k", lw=0.8, ls="--", label=target_label)
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


def fmt(x: float, digits: int = 2) -> str:
    return "never" if math.isinf(x) else f"{x:.{digits}f}"


def touchdown(physics_hz: float, room: str, mode: str, size: float, heading_deg: float,
              yaw_rate_rad_s: float) -> dict[str, float]:
    """Hover at 1.5 m, then command a descent into the ground while moving or steering sideways (8 s)."""
    vehicle = Multicopter(load_room(room), physics_hz=physics_hz)
    vehicle.set_armed(True)
    vehicle.set_target(ControlTarget(pos_ned_m=(0.0, 0.0, HOVER_DOWN_M)))
    run(vehicle, 6.0, lambda s: 0.0)
    vehicle.pop_events()
    north, east = size * math.cos(math.radians(heading_deg)), size * math.sin(math.radians(heading_deg))
    vehicle.set_target(ControlTarget(vel_ned_m_s=(north, east, 2.5), yaw_rate_rad_s=yaw_rate_rad_s)
                       if mode == "vel" else
                       ControlTarget(pos_ned_m=(north, east, 0.5), yaw_rate_rad_s=yaw_rate_rad_s))
    states = []
    for _ in range(round(8.0 / STEP_S)):
        vehicle.step(STEP_S)
        states.append(vehicle.state)
    moving = [i for i, s in enumerate(states) if not (s.on_ground and np.linalg.norm(s.vel_ned_m_s) < REST_M_S)]
    tilt = [math.degrees(math.acos(max(-1.0, min(1.0, math.cos(s.roll_rad) * math.cos(s.pitch_rad)))))
            for s in states]
    return {
        "max_up_m": max(-s.pos_ned_m[2] for s in states),
        "max_h_m_s": max(math.hypot(*s.vel_ned_m_s[:2]) for s in states),
        "max_v_m_s": max(abs(s.vel_ned_m_s[2]) for s in states),
        "max_tilt_deg": max(tilt), "final_tilt_deg": tilt[-1],
        "rest_s": (moving[-1] + 1) * STEP_S if moving else 0.0,
        "at_rest": bool(not moving or moving[-1] < len(states) - 1),
        "finite": all(np.all(np.isfinite(s.vel_ned_m_s)) for s in states),
        "events": ", ".join(e.obstacle_name for e in vehicle.pop_events()) or "none",
    }


def touchdown_sweep(rates: list[float]) -> list[str]:
    """Every touchdown case at each physics rate: how many end at rest, level, with no event of ours."""
    lines = ["| physics (Hz) | at rest and level (of 12) | max height (m) | max vert. (m/s) |", "|---|---|---|---|"]
    for rate in rates:
        runs = [touchdown(rate, *case) for case in TOUCHDOWNS]
        good = sum(1 for m in runs if m["at_rest"] and m["finite"] and m["final_tilt_deg"] < 5.0)
        lines.append(f"| {rate:g} | {good} | {max(m['max_up_m'] for m in runs):.2f} | "
                     f"{max(m['max_v_m_s'] for m in runs):.2f} |")
    return lines + ["", "Below 200 Hz the feet's damping is numerically unstable (explicit integration needs "
                    "dt * c / m < 2: 2.9 at 100 Hz, where touchdowns flipped and threw the vehicle up at 55 m/s), "
                    "so `Multicopter` refuses rates under 200 Hz.", ""]


def touchdown_lines(hz: float) -> list[str]:
    lines = [
        "## Touchdowns while moving sideways (regression: a tilted touchdown once launched the vehicle)", "",
        f"From a hover at {-HOVER_DOWN_M} m, either a velocity target descending at the 2.5 m/s limit while moving "
        "sideways (`vel`, m/s), or a position target that far away and 0.5 m underground (`pos`, m), with a yaw "
        "rate; 8 s. At rest = on the ground and slower than 0.05 m/s. The same 12 cases flown before the fix "
        "(commit 4212341: three-point gear, no touchdown mode): 8 rolled over, then 3 went NaN, 4 sank 25-160 m "
        "through the floor and 2 climbed to 61-68 m (vertical speeds up to 69 m/s).",
        "", "| room | target | size | heading (deg) | yaw rate (rad/s) | max height (m) | max horiz. (m/s) | "
        "max vert. (m/s) | max tilt (deg) | final tilt (deg) | at rest after (s) | events |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for case in TOUCHDOWNS:
        m = touchdown(hz, *case)
        rest = fmt(m["rest_s"]) if m["at_rest"] and m["finite"] else "**never**"
        lines.append(f"| {case[0]} | {case[1]} | {case[2]:g} | {case[3]:g} | {case[4]:g} | {m['max_up_m']:.2f} | "
                     f"{m['max_h_m_s']:.2f} | {m['max_v_m_s']:.2f} | {m['max_tilt_deg']:.0f} | "
                     f"{m['final_tilt_deg']:.1f} | {rest} | {m['events']} |")
    lines += ["", "Targets: never above the hover height + 1 m, within the speed limits (5 and 2.5 m/s) plus a "
              "touchdown margin, at rest and level. Tests: `tests/test_sim_physics_touchdown.py`.", ""]
    return lines


def touchdown_section(hz: float, rates: list[float]) -> list[str]:
    return touchdown_lines(hz) + ["The same cases at other physics rates:", ""] + touchdown_sweep(rates)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--physics-hz", type=float, default=300.0, help="JSBSim rate for the step responses")
    parser.add_argument("--rates", default="200,300,400", help="JSBSim rates to time (comma separated)")
    parser.add_argument("--no-write", action="store_true", help="print only; do not write docs/bench/")
    args = parser.parse_args(argv)
    hz = args.physics_hz

    steps = {name: velocity_step(hz, axis) for axis, name in enumerate(("north", "east", "up"))}
    yaw_trace, yaw = yaw_step(hz)
    hover_trace, hover = hover_hold(hz)
    speeds = {rate: min((speed(rate) for _ in range(SPEED_REPEATS)), key=lambda m: m["cpu_s"])
              for rate in (float(r) for r in args.rates.split(","))}
    wall_trace, wall = wall_contact(hz)
    hover_throttle = Multicopter(physics_hz=hz).hover_throttle
    push_height, push_east, push = disturbance(hz)
    touchdowns = touchdown_section(hz, [float(r) for r in args.rates.split(",")])

    ok = lambda good: "yes" if good else "**NO**"  # noqa: E731
    lines = [
        "# Simulator physics benchmark", "",
        f"Produced by `{COMMAND}` (tools/sim/bench_sim.py) on {platform.machine()}, Python "
        f"{platform.python_version()}; JSBSim airframe `sim_bridge/data/aircraft/gcs_quad`, gains "
        "`sim_bridge/data/control.toml`. All runs are lockstep (`Multicopter.step(0.02)` in a loop) from a "
        f"hover at {-HOVER_DOWN_M} m in `open_field`, physics at {hz:g} Hz. Speed is process CPU time.", "",
        "## Model", "",
        "- Dynamics: JSBSim 6-DoF, airframe `gcs_quad` = the `F450` shipped in the jsbsim wheel (1.4 kg, "
        "same inertia, four DJI E305 motors with DJI 9450 propellers read from the wheel's "
        "`engine/` folder) re-packaged without its rate-only FCS (which needs sensor systems that print "
        "\"Failed to tie property\" pages), plus three NED external forces for contacts. Gravity, propeller "
        "thrust and reaction torque, motor spin-up, body drag and ground contact all come from JSBSim.",
        "- Ground: four feet 0.24 m apart (F450 had three points and tipped over at 17 deg of tilt; these stand "
        "to about 38 deg), 3000 N/m and 100 N s/m each, skid friction 0.8 static / 0.5 sliding, plus frame "
        "contact points (motor pods, top) so a tipped vehicle lies on the floor instead of sinking through it.",
        "- Touchdown (`control.toml` [landing]): touching the ground and not asked to climb, the controller "
        "levels the vehicle, clears its integrators and spools the collective down to idle in 0.5 s (back up "
        "to 0.6 g while tilted over 8 deg, to level first); below 0.3 m it limits the tilt to 10 deg. `Multicopter` cuts the motors (disarms) if it is tipped past 60 "
        "deg on the ground, and resets the vehicle to rest, disarmed, on a non-physical state (NaN, under the "
        "floor, climbing at 3x the vertical limit, or armed and over 3x any speed limit); both are reported as "
        "events (STATUSTEXT).",
        f"- Hover point: found by a trim search at start (a vertical PI loop flown 30 m up for 4 s): "
        f"throttle {hover_throttle:.3f}. The mixer models thrust = k * throttle^2 with k fitted at that point; "
        "the velocity integrators absorb the rest.",
        "- Controller (ours, `sim_bridge/control.py`): position P (hold, takeoff) -> velocity target slewed at "
        "4 m/s^2 -> velocity PI plus the slew's acceleration as feedforward -> tilt and collective thrust -> "
        "attitude P -> body-rate P (yaw PI) -> X mixer -> four ESC commands, every physics step.",
        "- Contacts (`sim_bridge/world.py`): the vehicle is a 0.25 m sphere around the CG; a spring-damper "
        "push-out force (3000 N/m, 130 N s/m, `data/contact.toml`) against each box, wall and the ceiling. "
        "The floor is JSBSim's ground (gear contacts).", "",
        "![living room](img/sim_room.png)", "",
        "## Velocity steps (0 -> 1 m/s)", "",
        "| axis | 90 % rise (s) | overshoot (%) | settles to +/-0.05 m/s (s) | at 4 s (m/s) | target met |",
        "|---|---|---|---|---|---|",
    ]
    for name, (_, m) in steps.items():
        met = m["rise90_s"] <= 1.5 and m["overshoot_pct"] < 20.0
        lines.append(f"| {name} | {fmt(m['rise90_s'])} | {m['overshoot_pct']:.1f} | {fmt(m['settle_s'])} | "
                     f"{abs(m['final']):.3f} | {ok(met)} |")
    lines += [
        "", "Target: 90 % within 1.5 s, overshoot under 20 %.", "",
        "![velocity steps](img/sim_velocity_step.png)", "",
        "## Yaw turn (0 -> +90 deg, holding position)", "",
        "| 90 % rise (s) | overshoot (%) | settles to +/-3 deg (s) | final (deg) | target met |", "|---|---|---|---|---|",
        f"| {fmt(yaw['rise90_s'])} | {yaw['overshoot_pct']:.1f} | {fmt(yaw['settle_s'])} | {yaw['final']:.2f} | "
        f"{ok(yaw['settle_s'] <= 3.0)} |", "",
        "Target: settles within 3 s to +/-3 deg (yaw rate is limited to 90 deg/s).", "",
        "![yaw step](img/sim_yaw_step.png)", "",
        "## Hover hold (30 s at 1.5 m)", "",
        f"Max altitude error {hover['max_error_m'] * 100:.2f} cm, RMS {hover['rms_error_m'] * 100:.3f} cm "
        f"(target +/-5 cm: {ok(hover['max_error_m'] <= 0.05)}). No wind or sensor noise is modelled: this "
        "shows the controller's trim; pushes are in the next section.", "",
        "![hover](img/sim_hover.png)", "",
        "## Disturbance rejection (position hold at 1.5 m)", "",
        f"A steady {DISTURB_DOWN_N:g} N downward push (15 % of the weight) for 3 s, released for 3 s, then a "
        f"{DISTURB_EAST_N:g} N eastward push for 3 s (`Multicopter.set_disturbance_force_ned_n`): max height "
        f"error {push['max_height_error_m'] * 100:.1f} cm ({push['height_error_end_m'] * 100:.1f} cm at the end "
        f"of the push), max east drift {push['max_east_error_m'] * 100:.1f} cm ({push['east_error_end_m'] * 100:.1f}"
        " cm at the end of the push). The height integrator takes a push over in about 2 s; sideways the velocity "
        "integrator is kept slow (0.3 /s^2) so that velocity steps stay clean, and a sideways push is worked off "
        "over several seconds. Indoors there is no wind, so this is the trade we chose.",
        "", "![disturbance](img/sim_disturbance.png)", "",
        "## Contact: 2 m/s into the north wall (living room, 1.2 m up)", "",
        f"Contact surface (wall minus the 0.25 m vehicle radius) at north {wall['surface_m']:.3f} m; the vehicle "
        f"reached at most {wall['max_m']:.3f} m (penetration {max(0.0, wall['max_m'] - wall['surface_m']) * 100:.1f}"
        f" cm) and rests at {wall['final_m']:.3f} m while still commanded north. Events: {wall['events']}.", "",
        "![wall contact](img/sim_wall_contact.png)", "",
        *touchdowns,
        "## Lockstep speed (one core)", "",
        "A 120 s flight in `living_room`: take off, then legs north, east (turning), south (turning), "
        "west and down, 20 s each (best of five runs), so the vehicle spends much of it pinned against walls (the contact model "
        "works hardest). Target: the whole sim >= 20x real time; this layer should be well above.", "",
        "| physics (Hz) | CPU (s) | real-time factor | physics steps/s |", "|---|---|---|---|",
    ]
    for rate, m in speeds.items():
        lines.append(f"| {rate:g} | {m['cpu_s']:.2f} | {m['realtime_x']:.0f}x | {m['physics_steps_per_s']:.0f} |")
    lines += ["", "The shared 2-core machine (load average about 5 while measuring) was running other jobs: repeated runs "
              "vary by up to 2x and the ordering between rates is noise; what holds is that every rate is far above "
              "20x. Per step the cost is about 30-50 us: JSBSim about 10, our controller and contact model the rest.", ""]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        IMG.mkdir(parents=True, exist_ok=True)
        plot(IMG / "sim_velocity_step.png", "1 m/s velocity steps from hover", "speed along the step (m/s)",
             [(name, Trace(t.t_s, np.abs(t.values))) for name, (t, _) in steps.items()], 1.0, 0.1)
        plot(IMG / "sim_yaw_step.png", "Yaw step to +90 deg", "yaw (deg)", [("yaw", yaw_trace)], 90.0, 3.0)
        plot(IMG / "sim_wall_contact.png", "2 m/s north into a wall", "north (m)", [("north", wall_trace)],
             wall["surface_m"], None, "contact surface")
        plot_room(IMG / "sim_room.png", "living_room")
        plot(IMG / "sim_disturbance.png", "Pushes at hover: 0-3 s down, 6-9 s east", "m",
             [("height", push_height), ("east", push_east)], None, None)
        plot(IMG / "sim_hover.png", "Hover at 1.5 m", "height (m)", [("height", hover_trace)], 1.5, 0.05)
        DOC.parent.mkdir(parents=True, exist_ok=True)
        DOC.write_text(text, encoding="utf-8")
        print(f"wrote {DOC.relative_to(REPO)} and {IMG.relative_to(REPO)}/sim_*.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
