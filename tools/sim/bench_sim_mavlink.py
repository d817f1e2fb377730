"""Benchmark gcs-sim's MAVLink side: lockstep speed with telemetry, stream rates, real-time pacing, ACK latency.

    nice -n 10 python -m tools.sim.bench_sim_mavlink [--out docs/bench/sim_mavlink.md]

1. Lockstep: a scripted 60 s flight (boot, GUIDED/OFFBOARD, takeoff, 10 Hz velocity setpoints, turn, land)
   against the in-process sim, with a pymavlink ground station on loopback UDP decoding everything the
   sim sends. Speed = simulated seconds / process CPU seconds (sim + client in one process), start-up
   excluded, best of 5.
2. Rates: messages per simulated second seen by that ground station while airborne.
3. Pacing: the gcs-sim process with --speedup 1 and 5 for a fixed simulated duration, timed by the wall clock.
4. Latency: REQUEST_MESSAGE -> COMMAND_ACK round trips over UDP to a real-time gcs-sim process.
"""

from __future__ import annotations

import argparse
import math
import platform
import socket
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as M

from gcs_voice.session.sim_process import BundledSim
from tools.flight.lockstep_gcs import VELOCITY_ONLY, VELOCITY_YAW, LockstepGcs

REPO = Path(__file__).resolve().parents[2]
FLIGHT_S = 60.0


def scripted_flight(autopilot: str, tlog: Path | None, decode: bool = True
                    ) -> tuple[float, float, LockstepGcs, tuple[float, float]]:
    """Returns (simulated s, CPU s, the ground station, (airborne start, end) in sim s)."""
    nan = math.nan
    g = LockstepGcs(autopilot, room="open_field", tlog=tlog, decode=decode)
    cpu0 = time.process_time()     # start-up (JSBSim load, hover trim: about 0.3 s) not included
    g.boot()
    zero = lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY)   # noqa: E731
    if autopilot == "ardupilot":
        for msg_id in (M.MAVLINK_MSG_ID_ATTITUDE, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
            g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 100_000)   # as the real capture's GCS asked
        g.command(M.MAV_CMD_DO_SET_MODE, 1, 4)
        g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, 2.0)
        g.run(9.0)
    else:
        g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, g.server.autopilot.home[2] + 2.0)
        g.run(7.0)
        g.run(1.0, every=zero)
        g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0)
    airborne_start = g.t_s
    legs = [(M.MAV_FRAME_BODY_NED if autopilot == "px4" else M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW, 1.0, 0.0, 0.0),
            (M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, 0.0, 0.0, math.radians(90)),
            (M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, 0.0, 1.0, math.radians(90)),
            (M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, 0.0, 0.0, 0.0)]
    while g.t_s < FLIGHT_S - 10.0:
        for frame, mask, vx, vy, yaw in legs:
            g.run(4.0, every=lambda: g.setpoint(frame, mask, vx=vx, vy=vy, yaw=yaw))
    airborne_end = g.t_s
    g.command(M.MAV_CMD_NAV_LAND, 0, 0, 0, nan, nan, nan, nan)
    g.run(FLIGHT_S - g.t_s)
    cpu = time.process_time() - cpu0
    g.close()
    return g.t_s, cpu, g, (airborne_start, airborne_end)


def bench_lockstep(rows: list[str]) -> dict:
    rates = {}
    rows += ["## Lockstep speed (sim + telemetry over loopback UDP, one process)", "",
             f"A scripted {FLIGHT_S:.0f} s flight per personality (see the module docstring); CPU = process time"
             " (JSBSim, vehicle, personality, telemetry packing and sending, and the ground station's socket reads),"
             " start-up excluded, best of 5. 'GCS decodes' adds pymavlink decoding of every message on the ground-station side."
             " Target: the sim with telemetry >= 20x real time on one core.", "",
             "| personality | tlog | GCS decodes | simulated s | CPU s | x real time | messages sent | target met |",
             "|---|---|---|---|---|---|---|---|"]
    for autopilot in ("ardupilot", "px4"):
        for with_tlog, decode in ((False, False), (True, False), (False, True)):
            best = None
            for _ in range(5):
                with tempfile.TemporaryDirectory() as tmp:
                    run = scripted_flight(autopilot, Path(tmp) / "b.tlog" if with_tlog else None, decode)
                if best is None or run[1] < best[1]:
                    best = run
            sim_s, cpu_s, g, window = best
            speed = sim_s / cpu_s
            rows.append(f"| {autopilot} | {'yes' if with_tlog else 'no'} | {'yes' if decode else 'no'} | {sim_s:.1f} |"
                        f" {cpu_s:.2f} | {speed:.1f} | {g.server.stats.sent} | {'yes' if speed >= 20 else 'NO'} |")
            if decode:
                counts = Counter(m.get_type() for t, m in g.received if window[0] <= t < window[1])
                rates[autopilot] = {k: v / (window[1] - window[0]) for k, v in counts.items()}
    rows.append("")
    return rates


def bench_rates(rows: list[str], rates: dict) -> None:
    rows += ["## Stream rates seen by the ground station while airborne (messages per simulated second)", "",
             "ArduCopter personality: default MAV1_* rates (sim default 2 Hz groups, ATTITUDE 4 Hz) with ATTITUDE and"
             " LOCAL_POSITION_NED asked at 10 Hz by SET_MESSAGE_INTERVAL, as the real capture's GCS did"
             " (real SITL: 10 Hz / 10 Hz / others 2 Hz). PX4 personality: PX4's GCS-link defaults.", "",
             "| message | ardupilot (Hz) | px4 (Hz) |", "|---|---|---|"]
    names = sorted(set(rates["ardupilot"]) | set(rates["px4"]))
    for name in names:
        rows.append(f"| {name} | {rates['ardupilot'].get(name, 0):.2f} | {rates['px4'].get(name, 0):.2f} |")
    rows.append("")


def _sim(port: int, speedup: float | None = None, *extra: str) -> BundledSim:
    return BundledSim(room="open_field", port=port, speedup=speedup, extra_args=extra)


def bench_pacing(rows: list[str]) -> None:
    rows += ["## Real-time pacing (gcs-sim process, nobody listening on the UDP port)", "",
             "| --speedup | simulated s | wall s (process start to exit) | achieved ratio |", "|---|---|---|---|"]
    for speedup, duration in ((1.0, 10.0), (5.0, 30.0), (math.inf, 60.0)):
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sim = _sim(sock.getsockname()[1], speedup, "--duration", str(duration))
        t0 = time.monotonic()
        try:
            sim.start()
            t_ready = time.monotonic()
            sim.process.wait(timeout=600)
            wall = time.monotonic() - t_ready
        finally:
            sim.stop()
            sock.close()
        label = "max" if math.isinf(speedup) else f"{speedup:g}"
        rows.append(f"| {label} | {duration:.0f} | {wall:.2f} (+{t_ready - t0:.2f} start-up) | {duration / wall:.2f} |")
    rows.append("")


def bench_latency(rows: list[str]) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    sim = _sim(sock.getsockname()[1]).start()
    mav = M.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = M.MAVLink(None)
    samples = []
    try:
        _data, sim_addr = sock.recvfrom(65535)
        for _ in range(100):
            t0 = time.monotonic()
            sock.sendto(mav.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(mav),
                        sim_addr)
            done = False
            while not done:
                for msg in parser.parse_buffer(sock.recv(65535)) or []:
                    if msg.get_type() == "COMMAND_ACK" and msg.command == M.MAV_CMD_REQUEST_MESSAGE:
                        done = True
            samples.append((time.monotonic() - t0) * 1000)
            time.sleep(0.02)
    finally:
        sim.stop()
        sock.close()
    samples.sort()
    rows += ["## Command latency (real time, UDP loopback)", "",
             "REQUEST_MESSAGE(AUTOPILOT_VERSION) -> COMMAND_ACK, 100 round trips, 20 ms apart, --speedup 1.", "",
             "| median ms | p95 ms | max ms |", "|---|---|---|",
             f"| {statistics.median(samples):.1f} | {samples[94]:.1f} | {samples[-1]:.1f} |", ""]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "bench" / "sim_mavlink.md")
    args = parser.parse_args()
    rows = ["# gcs-sim MAVLink side: benchmark", "",
            f"Produced by `nice -n 10 python -m tools.sim.bench_sim_mavlink` (tools/sim/bench_sim_mavlink.py) on "
            f"{platform.machine()}, Python {platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."
            " The machine is shared (2 cores, other jobs running): CPU times vary by +-30 % between runs.", ""]
    rates = bench_lockstep(rows)
    bench_rates(rows, rates)
    bench_pacing(rows)
    bench_latency(rows)
    text = "\n".join(rows) + "\n"
    previous = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
    marker = "<!-- notes below are kept by bench_sim_mavlink.py -->"
    if marker in previous:
        text += "\n" + previous[previous.index(marker):]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
