"""Test-side names for the lockstep ground station (see sim_bridge.lockstep)."""

from sim_bridge.lockstep import VELOCITY_ONLY, VELOCITY_YAW, VELOCITY_YAW_RATE, LockstepGcs

__all__ = ["LockstepGcs", "VELOCITY_ONLY", "VELOCITY_YAW", "VELOCITY_YAW_RATE"]
