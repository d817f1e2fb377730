"""Pushed against a wall for 40 s, the vehicle must still obey at once: the controller does not wind up.

Lockstep (simulated time), through the real MAVLink path: GUIDED for ArduCopter, OFFBOARD for PX4, in the
living room (north wall 3 m ahead of the start).
"""

from __future__ import annotations

import math

import pytest
from tools.flight.lockstep_gcs import VELOCITY_ONLY, LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

NAN = math.nan
ACCEPTED = M.MAV_RESULT_ACCEPTED
HOVER_M = 1.5


def _airborne(g: LockstepGcs, autopilot: str) -> None:
    g.boot()
    zero = lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY)   # noqa: E731
    if autopilot == "ardupilot":
        assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == [ACCEPTED]
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [ACCEPTED]
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, HOVER_M) == [ACCEPTED]
        g.run(8.0)
    else:
        home_amsl_m = g.server.autopilot.home[2]
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [ACCEPTED]
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, home_amsl_m + HOVER_M) == [ACCEPTED]
        g.run(8.0)
        g.run(1.0, every=zero)
        assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == [ACCEPTED, ACCEPTED]
    assert -g.server.vehicle.state.pos_ned_m[2] == pytest.approx(HOVER_M, abs=0.3)


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_after_40_s_against_a_wall_a_command_away_acts_at_once_and_up_does_not_creep_back(autopilot: str) -> None:
    g = LockstepGcs(autopilot, room="living_room")
    try:
        _airborne(g, autopilot)
        north = lambda: float(g.server.vehicle.state.pos_ned_m[0])   # noqa: E731

        def fly(vx: float, vz: float, sim_s: float) -> None:
            g.run(sim_s, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, vx=vx, vz=vz))

        fly(0.5, 0.0, 40.0)
        assert any(text.startswith("SIM Hit north wall") for text in g.texts()), "it did reach the wall"
        at_wall = north()
        start_s = g.t_s
        while at_wall - north() < 0.1 and g.t_s - start_s < 5.0:
            fly(-0.5, 0.0, 0.1)
        assert g.t_s - start_s <= 1.2, f"a command away took {g.t_s - start_s:.1f} s to move the vehicle 0.1 m"

        fly(-0.5, 0.0, 1.5)
        away = north()
        farthest = away
        for _ in range(50):                                   # "up": zero horizontal velocity, 5 s
            fly(0.0, -0.3, 0.1)
            farthest = max(farthest, north())
        assert farthest - away < 0.1, f"crept {farthest - away:.2f} m back toward the wall"
    finally:
        g.close()
