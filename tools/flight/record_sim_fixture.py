"""Record the committed replay fixture: one lockstep gcs-sim flight as a .tlog.

    python -m tools.flight.record_sim_fixture [--out tests/fixtures/sim_ardupilot_guided_flight.tlog]

A pymavlink ground station (sys 255, comp 190) asks for AUTOPILOT_VERSION, sets GUIDED, arms, takes off
to 2 m, flies 1 m/s forward (BODY_OFFSET_NED) for 3 s, turns to 90 deg (LOCAL_NED yaw), lands.
open_field room, default home, fixed epoch so the file only changes when the sim's behaviour does.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as M

from tools.flight.lockstep_gcs import VELOCITY_YAW, LockstepGcs

DEFAULT_OUT = Path("tests/fixtures/sim_ardupilot_guided_flight.tlog")
EPOCH_UNIX_S = 1795000000.0     # 2026-11-18, fixed so re-recording is deterministic


def fly(g: LockstepGcs) -> None:
    nan = math.nan
    g.boot()
    g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, 2)          # refused: disarmed, STABILIZE
    g.command(M.MAV_CMD_DO_SET_MODE, 1, 4)
    g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, 2)
    g.run(8.0)
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW, vx=1.0))
    g.run(2.0, every=lambda: g.setpoint(M.MAV_FRAME_BODY_OFFSET_NED, VELOCITY_YAW))
    g.run(4.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, yaw=math.radians(90)))
    g.command(M.MAV_CMD_NAV_LAND, 0, 0, 0, nan, nan, nan, nan)
    g.run(8.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    g = LockstepGcs("ardupilot", room="open_field", tlog=args.out, epoch_unix_s=EPOCH_UNIX_S)
    try:
        fly(g)
    finally:
        g.close()
    print(f"{args.out}: {g.server.tlog.records} records, {args.out.stat().st_size} bytes, {g.t_s:.1f} s simulated")


if __name__ == "__main__":
    main()
