"""ArduPilot vs PX4: mode tables, how to ask for velocity control, how take-off altitude is given.

Mode numbers come from pymavlink's own tables (``mavutil.mode_mapping_acm``, ``mavutil.px4_map``,
``mavutil.interpret_px4_mode``); never retype them. ArduCopter's 4 is GUIDED, PX4's main mode 4 is AUTO
(MISSION): sending the wrong table's number is a real way to lose a vehicle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

__all__ = ["AutopilotProfile", "ModeTable", "ArduCopterModes", "Px4Modes", "ARDUPILOT", "PX4", "profile_for"]


class ModeTable(Protocol):
    """How an autopilot numbers its modes: HEARTBEAT -> name, and name -> DO_SET_MODE params / custom_mode."""

    def name(self, base_mode: int, custom_mode: int) -> str: ...
    def params(self, mode: str) -> tuple[float, float]: ...
    def custom_mode(self, main_mode: int, sub_mode: int) -> int: ...


class ArduCopterModes:
    """One number per mode (``mavutil.mode_mapping_acm``): custom_mode = DO_SET_MODE param2."""

    def name(self, base_mode: int, custom_mode: int) -> str:
        return mavutil.mode_mapping_acm.get(custom_mode, f"MODE({custom_mode})")

    def params(self, mode: str) -> tuple[float, float]:
        by_name = {name: number for number, name in mavutil.mode_mapping_acm.items()}
        return float(by_name[mode]), 0.0

    def custom_mode(self, main_mode: int, sub_mode: int) -> int:
        return main_mode


class Px4Modes:
    """Main and sub mode (``mavutil.px4_map``): custom_mode = sub << 24 | main << 16."""

    def name(self, base_mode: int, custom_mode: int) -> str:
        return mavutil.interpret_px4_mode(base_mode, custom_mode)

    def params(self, mode: str) -> tuple[float, float]:
        _base, main_mode, sub_mode = mavutil.px4_map[mode]
        return float(main_mode), float(sub_mode)

    def custom_mode(self, main_mode: int, sub_mode: int) -> int:
        return sub_mode << 24 | main_mode << 16


@dataclass(frozen=True)
class AutopilotProfile:
    """What differs between autopilots, as data plus two small lookups."""

    name: str
    #: mode that flies our velocity setpoints
    velocity_mode: str
    #: mode name for "land"
    land_mode: str
    #: True: the velocity mode is refused unless setpoints already stream (PX4 OFFBOARD)
    needs_prestream: bool
    #: True: NAV_TAKEOFF param7 is AMSL (PX4); False: metres above home (ArduCopter)
    takeoff_alt_is_amsl: bool
    #: True: arm in the velocity mode, then NAV_TAKEOFF (ArduCopter GUIDED); False: arm in a hold mode
    arm_in_velocity_mode: bool
    #: mode to arm in when not in the velocity mode (PX4 Hold = AUTO.LOITER)
    arm_mode: str
    #: True: DO_SET_MODE is acknowledged twice and the first ACK is always ACCEPTED (PX4)
    double_mode_ack: bool
    #: True: SET_POSITION_TARGET_LOCAL_NED honours each x/y/z ignore bit on its own (PX4); False: any one
    #: set drops the whole position (ArduCopter), so a height-only hold cannot ride with a velocity
    position_axes_separately: bool
    #: how this autopilot numbers its modes
    modes: ModeTable

    def mode_name(self, base_mode: int, custom_mode: int) -> str:
        return self.modes.name(base_mode, custom_mode)

    def mode_params(self, mode: str) -> tuple[float, float, float]:
        """DO_SET_MODE param1..3 for ``mode`` (KeyError when the autopilot has no such mode)."""
        main_mode, sub_mode = self.modes.params(mode)
        return float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), main_mode, sub_mode

    def custom_mode(self, mode: str) -> int:
        """The HEARTBEAT custom_mode that means ``mode``."""
        main_mode, sub_mode = self.modes.params(mode)
        return self.modes.custom_mode(int(main_mode), int(sub_mode))


ARDUPILOT = AutopilotProfile(
    name="ArduPilot", velocity_mode="GUIDED", land_mode="LAND", needs_prestream=False,
    takeoff_alt_is_amsl=False, arm_in_velocity_mode=True, arm_mode="GUIDED", double_mode_ack=False,
    position_axes_separately=False,
    modes=ArduCopterModes(),
)
PX4 = AutopilotProfile(
    name="PX4", velocity_mode="OFFBOARD", land_mode="LAND", needs_prestream=True,
    takeoff_alt_is_amsl=True, arm_in_velocity_mode=False, arm_mode="LOITER", double_mode_ack=True,
    position_axes_separately=True,
    modes=Px4Modes(),
)


def profile_for(autopilot: int) -> AutopilotProfile | None:
    """The profile for HEARTBEAT.autopilot, or None (not a flight controller we know how to fly)."""
    if autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return ARDUPILOT
    if autopilot == mavlink.MAV_AUTOPILOT_PX4:
        return PX4
    return None
