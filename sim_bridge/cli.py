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
    p.add_argument("--cold-start", action="store_true",
                   help="boot like the real autopilot (ArduCopter: BOOT 2 s, a mode set then is reset to STABILIZE, "
                        "arming refused with its 'Arm: ...' texts until the EKF has a position after ~41 s; PX4: "
                        "pre-flight checks fail for ~4 s); default: ready to arm after 2.5 s")
    p.add_argument("--boot-scale", type=float, metavar="S",
                   help="with --cold-start: multiply the boot's times by S (0.1: ArduCopter has a position after 4 s)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S simulated seconds (default: run until Ctrl-C)")
    p.add_argument("--signing-key", metavar="PASSPHRASE|@FILE",
                   help="MAVLink 2 signing with SHA-256(PASSPHRASE) as the key (MAVProxy's 'signing setup'): sign "
                        "everything sent and obey only messages signed with it (arm, mode, setpoints, params, "
                        "missions); @FILE reads the passphrase from the file's first line, out of sight of 'ps'")
    p.add_argument("--allow", action="append", metavar="HOST|NET", default=[],
                   help="take UDP datagrams and TCP clients only from these addresses or networks (repeatable, e.g. "
                        "127.0.0.1 or 192.168.1.0/24); default: from anyone who can reach this machine")
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
    from sim_bridge.access import AccessError
    from sim_bridge.params import ParamsError
    from sim_bridge.signing import SigningKeyError, key_from_flag
    from sim_bridge.transport import TransportError
    from sim_bridge.world import RoomError

    try:
        speedup = _parse_speedup(args.speedup)
        home = _parse_home(args.home)
        if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
            raise SimUsageError("--duration: a positive number of seconds")
        outs = args.out or ([] if args.tcp else [DEFAULT_OUT])
        if args.boot_scale is not None and not args.cold_start:
            raise SimUsageError("--boot-scale needs --cold-start")
        scale = (1.0 if args.boot_scale is None else args.boot_scale) if args.cold_start else None
        key = None if args.signing_key is None else key_from_flag(args.signing_key)
        server = build_sim(args.autopilot, args.room, home, outs, args.tcp, args.tlog, signing_key=key,
                           allow=args.allow, cold_start_scale=scale)
    except (SimUsageError, TransportError, RoomError, ParamsError, SigningKeyError, AccessError) as exc:
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
          f"{f'; {s.handler_errors} handler errors, last {server.last_handler_error}' if s.handler_errors else ''}"
          f"{_access_summary(server)}", flush=True)
    return 0


def _access_summary(server) -> str:
    """``; signing on: 40 signed ok, refused 3 unsigned; --allow refused 2`` (empty when neither was used)."""
    parts = [server.signing.summary()]
    peer_filter = getattr(server, "peer_filter", None)
    if peer_filter is not None:
        parts.append(f"--allow {peer_filter} refused {peer_filter.refused}")
    return "".join(f"; {part}" for part in parts if part)


if __name__ == "__main__":
    sys.exit(main())
