"""Summarise a ground-station .tlog: setpoint stream timing, encodings used, modes, ACKs, link gaps.

    python -m tools.flight.link_tlog_stats FILE.tlog [FILE.tlog ...]

Prints markdown. Works on ../shared/tlogs/*.tlog (the reference SITL captures) and on what
``VehicleLink(tlog_path=...)`` writes, so the bridge's stream can be compared with a known-good one.
"""

from __future__ import annotations

import statistics
import sys
from collections import Counter
from pathlib import Path

from pymavlink import mavutil

from gcs_voice.link.acks import command_name
from gcs_voice.link.state import CommandAck, VehicleStateTracker

GCS_SYSTEM_ID = 255


def summarise(path: Path) -> str:
    log = mavutil.mavlink_connection(str(path))
    tracker = VehicleStateTracker()
    setpoint_t: list[float] = []
    encodings: Counter = Counter()
    vehicle_t: list[float] = []
    modes: list[tuple[float, str, bool]] = []
    acks: Counter = Counter()
    t0 = None
    while (msg := log.recv_match()) is not None:
        t0 = msg._timestamp if t0 is None else t0
        t = msg._timestamp - t0
        if msg.get_srcSystem() == GCS_SYSTEM_ID:
            if msg.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
                setpoint_t.append(t)
                encodings[(msg.coordinate_frame, msg.type_mask)] += 1
            continue
        if msg.get_type() == "BAD_DATA":
            continue
        vehicle_t.append(t)
        for event in tracker.update(msg, msg._timestamp):
            if isinstance(event, CommandAck):
                acks[(command_name(event.command), event.result_name)] += 1
        state = tracker.state
        if state.mode and (not modes or (modes[-1][1], modes[-1][2]) != (state.mode, bool(state.armed))):
            modes.append((t, state.mode, bool(state.armed)))
    lines = [f"### {path.name}", ""]
    if len(setpoint_t) > 1:
        gaps = sorted(b - a for a, b in zip(setpoint_t, setpoint_t[1:]))
        bursts = [g for g in gaps if g < 1.0]  # gaps >= 1 s are pauses between streams, not jitter
        q = statistics.quantiles(bursts, n=100) if len(bursts) > 1 else bursts * 99
        lines.append(f"- setpoints sent: {len(setpoint_t)}; interval within streams: median "
                     f"{statistics.median(bursts) * 1000:.1f} ms, p99 {q[98] * 1000:.1f} ms, max "
                     f"{max(bursts) * 1000:.1f} ms; pauses >= 1 s: {len(gaps) - len(bursts)}")
        lines.append("- encodings (frame, type_mask): " + ", ".join(f"{k} x{v}" for k, v in sorted(encodings.items())))
    else:
        lines.append("- setpoints sent: none")
    if len(vehicle_t) > 1:
        silent = max(b - a for a, b in zip(vehicle_t, vehicle_t[1:]))
        lines.append(f"- vehicle messages: {len(vehicle_t)}; longest silence {silent:.2f} s")
    lines.append("- modes (t s, mode, armed): " + "; ".join(f"{t:.2f} {m} {'A' if a else 'D'}" for t, m, a in modes))
    lines.append("- ACKs: " + ", ".join(f"{c} {r} x{n}" for (c, r), n in sorted(acks.items())))
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(prog="python -m tools.flight.link_tlog_stats", description=__doc__.splitlines()[0])
    parser.add_argument("tlogs", nargs="+", type=Path, metavar="FILE.tlog")
    args = parser.parse_args(argv)
    for name in args.tlogs:
        if not name.is_file():
            parser.error(f"{name}: no such file")
        print(summarise(name))
    return 0


if __name__ == "__main__":
    sys.exit(main())
