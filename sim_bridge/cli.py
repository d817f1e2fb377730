"""``gcs-sim``: a MAVLink quadrotor (JSBSim physics) that speaks like ArduCopter SITL or PX4.

Only flags live here: ``sim_bridge.build.build_sim`` puts room, physics, vehicle, personality, links
and tlog together; ``main`` parses flags, runs the loop and prints one line when ready and one when done.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
from pathlib import Path
from typing import Sequence

__all__ = ["main"]

from sim_bridge.build import AUTOPILOTS, SimUsageError, build_sim

DEFAULT_OUT = "udp:127.0.0.1:14550"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, not usage + error
        self.exit(2, f"gcs-sim: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="gcs-sim", description="A simulated quadrotor (JSBSim physics in a room) that speaks MAVLink "
                "like ArduCopter SITL (default) or PX4, for MAVProxy, MAVSDK, QGroundControl and gcs-voice.")
    p.add_argument("--out", action="append", metavar="udp:HOST:PORT", default=[],
                   help="send MAVLink to a ground station listening there (repeatable); it answers to our source "
                        f"port. Default when neither --out nor --tcp is given: {DEFAULT_OUT}")
    p.add_argument("--tcp", action="append", metavar="[HOST:]PORT", default=[],
                   help="also listen for TCP clients (several at once), like SITL's port 5760; HOST defaults to "
                        "127.0.0.1, port 0 picks a free one (printed in the ready line)")
    p.add_argument("--room", default="living_room", metavar="FILE|NAME",
                   help="room to fly in: a name from rooms/ (living_room, open_field) or a JSON file")
    p.add_argument("--autopilot", choices=AUTOPILOTS, default="ardupilot",
                   help="personality on the wire: ArduCopter (modes, GUIDED, FAILED refusals) or PX4 (OFFBOARD rules, "
                        "double DO_SET_MODE ACK, offboard-loss failsafe)")
    p.add_argument("--speedup", default="1", metavar="N|max",
                   help="simulated seconds per wall second (default 1 = real time); 'max' runs as fast as the CPU can")
    p.add_argument("--home", metavar="LAT,LON,ALT", help="home position in degrees and metres AMSL (default: the room's)")
    p.add_argument("--tlog", metavar="FILE", type=Path,
                   help="write everything sent and received to this .tlog (mavlogdump.py reads it)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S simulated seconds (default: run until Ctrl-C)")
    return p


def _parse_home(text: str | None) -> tuple[float, float, float] | None:
    if text is None:
        return None
    try:
        lat, lon, alt = (float(x) for x in text.split(","))
    except ValueError:
        raise SimUsageError(f"--home {text!r}: expected LAT,LON,ALT (three numbers)") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180 and math.isfinite(alt)):
        raise SimUsageError(f"--home {text!r}: latitude -90..90, longitude -180..180")
    return lat, lon, alt


def _parse_speedup(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise SimUsageError(f"--speedup {text!r}: a positive number or 'max'")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from sim_bridge.params import ParamsError
    from sim_bridge.transport import TransportError
    from sim_bridge.world import RoomError

    try:
        speedup = _parse_speedup(args.speedup)
        home = _parse_home(args.home)
        if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
            raise SimUsageError("--duration: a positive number of seconds")
        outs = args.out or ([] if args.tcp else [DEFAULT_OUT])
        server = build_sim(args.autopilot, args.room, home, outs, args.tcp, args.tlog)
    except (SimUsageError, TransportError, RoomError, ParamsError) as exc:
        print(f"gcs-sim: error: {exc}", file=sys.stderr)
        return 2
    stop = {"now": False}

    def _stop(_signum: int, _frame: object) -> None:
        stop["now"] = True

    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)
    ends = ", ".join([f"udp out {link.dest[0]}:{link.dest[1]}" for link in server.links]
                     + [f"tcp {s.host}:{s.port}" for s in server.tcp_servers])
    name = server.autopilot.identity["name"]
    print(f"gcs-sim: {name} quad ready in {args.room}, home {server.autopilot.home[0]:.6f},"
          f"{server.autopilot.home[1]:.6f},{server.autopilot.home[2]:.1f}; {ends}"
          f"{'; tlog ' + str(args.tlog) if args.tlog else ''}; speedup {args.speedup}", flush=True)
    duration = args.duration
    try:
        server.serve(speedup, lambda: stop["now"] or (duration is not None and server.vehicle.time_s >= duration))
    finally:
        server.close()
    s = server.stats
    print(f"gcs-sim: stopped after {server.vehicle.time_s:.1f} s simulated; sent {s.sent}, received {s.received}; "
          f"{server.summary_text()}{'; tlog ' + str(args.tlog) + f' ({server.tlog.records} records)' if args.tlog else ''}"
          f"{f'; {s.handler_errors} handler errors, last {server.last_handler_error}' if s.handler_errors else ''}",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
