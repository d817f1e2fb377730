"""Print what the bridge would send at each point of a recorded boot: ``link.readiness`` over a .tlog.

    python -m tools.flight.readiness_replay ../shared/tlogs/arducopter-sitl-guided-velocity.tlog --until 43
    python -m tools.flight.readiness_replay ../shared/tlogs/px4-sih-offboard-velocity.tlog --until 4

The vehicle's messages are fed to the state tracker one by one (the recorded ground station's own
packets are skipped) and each change of decision is printed with its time from the first record. Open
loop: the vehicle answered the recorded ground station, so this shows our decisions, not their effects.
"""

from __future__ import annotations

import argparse
import sys

from pymavlink import mavutil

from gcs_voice.link.readiness import assess, next_step
from gcs_voice.link.state import VehicleStateTracker


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tlog")
    parser.add_argument("--until", type=float, default=float("inf"), help="seconds from the first record")
    parser.add_argument("--gcs-system", type=int, default=255, help="system id of the recorded ground station")
    args = parser.parse_args(argv)
    try:
        log = mavutil.mavlink_connection(args.tlog)
    except OSError as exc:
        print(f"readiness_replay: error: {exc}", file=sys.stderr)
        return 2
    tracker = VehicleStateTracker(gcs_system_id=args.gcs_system)
    t0, last = None, None
    while (msg := log.recv_match()) is not None:
        t0 = msg._timestamp if t0 is None else t0
        t = msg._timestamp - t0
        if t > args.until:
            break
        if msg.get_srcSystem() == args.gcs_system:
            continue
        tracker.update(msg, msg._timestamp)
        step = next_step(tracker.state, msg._timestamp)
        key = (step.action, step.mode, assess(tracker.state).waiting_for)
        if key != last:
            last = key
            state = tracker.state
            print(f"{t:8.2f} s  {step.action:<8} {step.mode or '':<8} mode {state.mode}, "
                  f"{'armed' if state.armed else 'disarmed'}: {step.why}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
