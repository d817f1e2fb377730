"""The simulated battery drains while the motors run, SYS_STATUS and BATTERY_STATUS say so, and the
autopilot warns once when it runs low, in its own words (lockstep, real JSBSim physics, loopback UDP)."""

from __future__ import annotations

import math

import pytest
from tools.flight.lockstep_gcs import LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

NAN = math.nan
#: (personality, its capacity parameter, the arming mode's custom_mode, words its low-battery warning starts with)
CASES = [("ardupilot", "BATT_CAPACITY", 4, "Battery 1 is low"), ("px4", "BAT1_CAPACITY", None, "Low battery level")]


@pytest.mark.parametrize("autopilot, capacity_param, _mode, warning", CASES)
def test_a_small_battery_drains_in_flight_and_the_autopilot_warns_once(autopilot, capacity_param, _mode,
                                                                        warning) -> None:
    g = LockstepGcs(autopilot, room="open_field")
    try:
        g.boot()
        full = g.last("SYS_STATUS")
        assert full.battery_remaining >= 99 and full.voltage_battery >= 12500
        # a 10 mAh battery: armed (12 A) it drains 1 % every 0.03 s
        g.send(g.mav.param_set_encode(1, 1, capacity_param.encode(), 10.0,
                                      M.MAV_PARAM_TYPE_REAL32 if autopilot == "px4" else M.MAV_PARAM_TYPE_INT32))
        g.run(0.5)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196 if autopilot == "px4" else 0) == [
            M.MAV_RESULT_ACCEPTED]
        g.run(5.0, until=lambda m: m.get_type() == "STATUSTEXT" and m.text.startswith(warning))
        assert any(t.startswith(warning) for t in g.texts()), g.texts()
        g.run(1.5)  # the next SYS_STATUS (a few Hz) reports it
        low = g.last("SYS_STATUS")
        assert low.battery_remaining < 20 and low.voltage_battery < full.voltage_battery, low
        assert low.current_battery > 0
        status = g.last("BATTERY_STATUS")  # (streamed at 1 Hz: the latest may be a little older)
        assert status is not None and status.battery_remaining < full.battery_remaining and status.current_consumed > 0
        said = [t for t in g.texts() if t.startswith(warning)]
        g.run(1.0)
        assert len([t for t in g.texts() if t.startswith(warning)]) == len(said) == 1, g.texts()
    finally:
        g.close()
