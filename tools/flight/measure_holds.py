"""Measure what the setpoint holds buy: stop error and height kept, with and without position targets.

    python -m tools.flight.measure_holds                      # both gcs-sim personalities, holds on and off
    python -m tools.flight.measure_holds --connect udpin:127.0.0.1:14550 --variants holds   # a SITL (it flies!)

For each vehicle and variant ("holds": what gcs-voice sends, docs/link.md; "velocity": the same
setpoints with every position target removed, type_mask 2503 throughout) it takes off to 1.5 m, then
flies go_forward 3 s, stop 4 s, turn_right 4 s, go_right 3 s, stop 4 s, and measures from the vehicle's
LOCAL_POSITION_NED: how far it ends from where each "stop" was heard, how far the turn moved it, and how
far the height strayed from the height at the first stop. gcs-sim runs in real time on 127.0.0.1
(``python -m sim_bridge.cli --room open_field``); its extra flags go after ``--sim-args``.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.settings import load_settings

REPO = Path(__file__).resolve().parents[2]
SEQUENCE = [("go_forward", 3.0), ("stop", 4.0), ("turn_right", 4.0), ("go_right", 3.0), ("stop", 4.0)]


def _free_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def fly(connection: str, variant: str, timeout_s: float) -> dict[str, float | str]:
    """One flight; returns the measured figures (metres)."""
    settings = load_settings()
    mapper = ActionMapper(settings)

    def source(state):
        sp = mapper.setpoint(state)
        return sp if variant == "holds" else replace(sp, hold_north_m=None, hold_east_m=None, hold_down_m=None)

    out: dict[str, float | str] = {}
    with VehicleLink(connection, settings) as link:
        link.connect(timeout_s=timeout_s)
        result = link.takeoff(settings.takeoff_altitude_m, source=source)
        if not result.ok:
            return {"error": str(result)}
        mapper.reset_heading(link.state)
        link.start_stream(source)
        time.sleep(2.0)
        stop_errors, height_ref, height_err, turn_moved, moved = [], None, 0.0, 0.0, []
        for action, seconds in SEQUENCE:
            heard = link.state
            mapper.apply(action, heard)
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                time.sleep(0.1)
                now = link.state
                if height_ref is not None:
                    height_err = max(height_err, abs(now.height_m - height_ref))
            done = link.state
            if action == "stop":
                stop_errors.append(math.hypot(done.north_m - heard.north_m, done.east_m - heard.east_m))
                height_ref = done.height_m if height_ref is None else height_ref
            if action.startswith("go_"):
                moved.append(math.hypot(done.north_m - heard.north_m, done.east_m - heard.east_m))
            if action.startswith("turn"):
                turn_moved = math.hypot(done.north_m - heard.north_m, done.east_m - heard.east_m)
        out = {"stop_1_m": stop_errors[0], "stop_2_m": stop_errors[1], "turn_moved_m": turn_moved,
               "height_max_err_m": height_err, "leg_1_m": moved[0], "leg_2_m": moved[1]}
        link.land()
        link.wait_for(lambda s: s.armed is False, 30.0)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--connect", help="fly this vehicle instead of starting gcs-sim")
    parser.add_argument("--variants", default="holds,velocity")
    parser.add_argument("--autopilots", default="ardupilot,px4")
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--sim-args", nargs=argparse.REMAINDER, default=[])
    args = parser.parse_args(argv)
    rows = []
    vehicles = [("given", args.connect)] if args.connect else [(a, None) for a in args.autopilots.split(",")]
    for vehicle, connection in vehicles:
        for variant in args.variants.split(","):
            sim = None
            if connection is None:
                port = _free_port()
                sim = subprocess.Popen([sys.executable, "-m", "sim_bridge.cli", "--out", f"udp:127.0.0.1:{port}",
                                        "--autopilot", vehicle, "--room", "open_field", *args.sim_args],
                                       cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            try:
                figures = fly(connection or f"udpin:127.0.0.1:{port}", variant, args.timeout)
            finally:
                if sim is not None:
                    sim.terminate()
                    sim.wait(timeout=10)
            rows.append((vehicle, variant, figures))
            print(vehicle, variant, figures, flush=True)
    print("\n| vehicle | setpoints | legs flown | 1st stop: end from where heard | 2nd stop | moved during the turn | "
          "height, worst from the 1st stop's |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for vehicle, variant, f in rows:
        if "error" in f:
            print(f"| {vehicle} | {variant} | {f['error']} | | | | |")
            continue
        print(f"| {vehicle} | {variant} | {f['leg_1_m']:.2f}, {f['leg_2_m']:.2f} m | {f['stop_1_m']:.2f} m | {f['stop_2_m']:.2f} m | {f['turn_moved_m']:.2f} m | "
              f"{f['height_max_err_m']:.2f} m |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
