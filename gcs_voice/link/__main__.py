"""``python -m gcs_voice.link``: connect, ask for telemetry and print the vehicle's state once a second.

A link check that commands nothing (no arming, no setpoints), for a first contact with a real vehicle:

    python -m gcs_voice.link --udp 14550 --seconds 10
    python -m gcs_voice.link --connect /dev/ttyUSB0,57600
"""

from __future__ import annotations

import argparse
import sys
import time

from gcs_voice.errors import GcsVoiceError
from gcs_voice.link.options import add_link_arguments, connection_from_args, settings_from_args


def _line(state) -> str:
    def fmt(value, unit: str, digits: int = 1) -> str:
        return "?" if value is None else f"{value:.{digits}f}{unit}"

    link = "ok" if state.link_ok else ("lost" if state.last_heard_s is not None else "waiting")
    return (f"link {link} | {state.autopilot or '?'} sys {state.system_id} | mode {state.mode} | "
            f"{'armed' if state.armed else 'disarmed'} | {state.landed_state or '?'} | "
            f"height {fmt(state.height_m, ' m', 2)} | heading {fmt(state.heading_deg, ' deg')} | "
            f"from home {fmt(state.home_distance_m, ' m', 2)}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gcs_voice.link", description=__doc__.splitlines()[0])
    add_link_arguments(parser)
    parser.add_argument("--seconds", type=float, default=10.0, help="how long to watch (default 10)")
    parser.add_argument("--wait", type=float, default=30.0, help="seconds to wait for a HEARTBEAT (default 30)")
    args = parser.parse_args(argv)
    from gcs_voice.link.security import security_from_args
    from gcs_voice.link.vehicle_link import VehicleLink

    try:
        with VehicleLink(connection_from_args(args), settings_from_args(args), tlog_path=args.tlog,
                         on_event=lambda text: print(f"  {text}"), security=security_from_args(args)) as link:
            link.connect(timeout_s=args.wait)
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                print(_line(link.state), flush=True)
                time.sleep(1.0)
    except GcsVoiceError as exc:
        print(f"gcs-voice: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
