"""Fly a fixed action sequence through ActionMapper + VehicleLink against any vehicle and measure it.

    python -m tools.flight.link_flight --connect udpin:127.0.0.1:14550 [--tlog out/flight.tlog] [--markdown]

Works with the bundled simulator (``python -m sim_bridge.cli``), an ArduCopter or PX4 SITL, or a
real vehicle (careful: it flies). Prints one row per step: what was commanded, how long it lasted,
the outcome measured from telemetry (height, heading, displacement) and the operation results.
"""

from __future__ import annotations

import argparse
import sys
import time


from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.settings import load_settings

#: (action, seconds to let it run)
SEQUENCE: list[tuple[str, float]] = [
    ("take_off", 0.0), ("go_forward", 4.0), ("stop", 2.0), ("turn_right", 4.0), ("turn_right", 4.0),
    ("go_right", 3.0), ("stop", 2.0), ("up", 3.0), ("down", 15.0), ("turn_left", 4.0), ("stop", 1.0), ("land", 0.0),
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--connect", required=True)
    parser.add_argument("--tlog")
    parser.add_argument("--config")
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args()
    settings = load_settings(args.config)
    mapper = ActionMapper(settings)
    rows: list[str] = []
    t_start = time.monotonic()
    events_seen = 0
    with VehicleLink(args.connect, settings, tlog_path=args.tlog, on_event=lambda line: print("  ", line)) as link:
        state = link.connect(timeout_s=args.timeout)
        print(f"vehicle: {state.autopilot} sys {state.system_id}, mode {state.mode}, armed {state.armed}")
        for action, seconds in SEQUENCE:
            before = link.state
            t0 = time.monotonic()
            result = ""
            mapped = mapper.apply(action, before)
            if mapped.flight_operation == "take_off":
                res = link.takeoff(settings.takeoff_altitude_m, source=mapper.setpoint)
                mapper.reset_heading(link.state)
                link.start_stream(mapper.setpoint)
                result = str(res)
                if not res.ok:
                    rows.append(f"| {action} | {time.monotonic() - t0:.1f} | {result} |")
                    break
            elif mapped.flight_operation == "land":
                res = link.land()
                link.wait_for(lambda s: s.armed is False, 30.0)
                result = str(res)
            else:
                if not link.streaming:
                    link.start_stream(mapper.setpoint)
                time.sleep(seconds)
            after = link.state
            moved = ""
            if None not in (before.north_m, after.north_m, before.east_m, after.east_m):
                moved = f"dN {after.north_m - before.north_m:+.2f} m, dE {after.east_m - before.east_m:+.2f} m"
            height = f"{after.height_m:.2f} m" if after.height_m is not None else "?"
            heading = f"{after.heading_deg:.1f} deg" if after.heading_deg is not None else "?"
            target = f"{mapper.yaw_target_deg:.1f}" if mapper.yaw_target_deg is not None else "?"
            new_events = list(mapper.events)[events_seen:]
            events_seen = len(mapper.events)
            notes = "; ".join(n for n in (result, mapper.limit_reason, *new_events) if n)
            rows.append(f"| {action} | {time.monotonic() - t0:.1f} | height {height}, heading {heading} "
                        f"(target {target}), {moved}, mode {after.mode} | {notes} |")
        sent = link.setpoints_sent
    total = time.monotonic() - t_start
    print("\n| action | s | measured after it | notes |\n| --- | --- | --- | --- |")
    print("\n".join(rows))
    print(f"\n{sent} setpoints sent in {total:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
