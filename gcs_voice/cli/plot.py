"""``gcs-voice plot FLIGHT.tlog [--room NAME|FILE] [--session FILE.jsonl] [-o PNG]``."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("tlog", help="MAVLink telemetry log (.tlog) of the flight")
    parser.add_argument("--room", help="room to draw: a bundled room name (e.g. the simulator's) or a room JSON file")
    parser.add_argument("--session", metavar="JSONL",
                        help="session log with the commands (default: FLIGHT.jsonl beside the tlog if present, "
                             "otherwise commands are read from the setpoints in the tlog)")
    parser.add_argument("-o", "--output", metavar="PNG", help="output image (default: FLIGHT.png beside the tlog)")


def run(args: argparse.Namespace) -> int:
    from gcs_voice.session.plot import load_room, plot_flight

    room = load_room(args.room) if args.room else None
    out = Path(args.output) if args.output else Path(args.tlog).with_suffix(".png")
    path = plot_flight(args.tlog, out, room=room, session_log=args.session)
    print(path)
    return 0
