"""Is the vehicle ready to arm, and what should a ground station send next? Read from the vehicle's own signals.

Pure functions of a :class:`VehicleState`, so the same decisions run live (``FlightOperations.takeoff``)
and over a recorded .tlog (``tests/test_readiness_replay.py`` on the real SITL captures). The signals,
as seen in ../shared/tlogs:

- HEARTBEAT ``system_status``: ArduCopter BOOT (1) until "ArduPilot Ready"; PX4 UNINIT (0) while the
  current mode cannot be armed (estimator not ready, OFFBOARD without setpoints).
- SYS_STATUS bit MAV_SYS_STATUS_PREARM_CHECK: ArduCopter reports it present and enabled, and healthy
  once its pre-arm checks pass (+42.4 s in the capture); PX4 sets it only in ``health`` when armable.
- EKF_STATUS_REPORT.flags (ArduPilot): a horizontal position (rel or abs), not in constant-position
  mode, not uninitialised (167 -> 831 when "EKF3 IMU0 is using GPS").
- a local position (ArduCopter sends no LOCAL_POSITION_NED before its EKF has one) and, for PX4
  (whose NAV_TAKEOFF altitude is AMSL), home.

The decision never arms outside the arming mode and never trusts a mode the HEARTBEAT has not shown
for ``mode_settle_s``: ArduCopter resets a mode set during its boot to STABILIZE when it ends.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources

from pymavlink.dialects.v20 import ardupilotmega as ardupilot
from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.state import VehicleState

__all__ = ["Readiness", "ReadinessRules", "Step", "assess", "next_step", "load_rules",
           "WAIT", "SET_MODE", "ARM", "READY"]

PREARM_BIT = mavlink.MAV_SYS_STATUS_PREARM_CHECK
EKF_POSITION = ardupilot.EKF_POS_HORIZ_REL | ardupilot.EKF_POS_HORIZ_ABS
EKF_NOT_USABLE = ardupilot.EKF_CONST_POS_MODE | ardupilot.EKF_UNINITIALIZED
#: what the user sees in "waiting for: ..."
INITIALISATION, PREARM, POSITION, HOME, LINK = (
    "initialisation", "pre-arm checks", "position (EKF)", "home position", "vehicle")

WAIT, SET_MODE, ARM, READY = "wait", "set mode", "arm", "ready"


@dataclass(frozen=True)
class ReadinessRules:
    mode_settle_s: float = 1.0
    heartbeat_max_age_s: float = 1.5
    home_request_s: float = 5.0
    landed_timeout_s: float = 40.0


def load_rules() -> ReadinessRules:
    """The packaged ``readiness.toml``."""
    data = tomllib.loads(resources.files("gcs_voice.link").joinpath("readiness.toml").read_text(encoding="utf-8"))
    ready, landing = data["ready"], data["landing"]
    return ReadinessRules(float(ready["mode_settle_s"]),
                          float(ready["heartbeat_max_age_s"]), float(ready["home_request_s"]),
                          float(landing["timeout_s"]))


@dataclass(frozen=True)
class Readiness:
    """``waiting_for`` is empty when the vehicle says it can be armed; ``said`` its latest complaint."""

    waiting_for: tuple[str, ...]
    said: str | None = None

    @property
    def ready(self) -> bool:
        return not self.waiting_for

    def __str__(self) -> str:
        if self.ready:
            return "ready to arm"
        return "waiting for: " + ", ".join(self.waiting_for) + (f" (vehicle: {self.said})" if self.said else "")


def _prearm_ok(state: VehicleState) -> bool | None:
    """The PREARM_CHECK bit: True/False when the vehicle reports it, None when it never does."""
    if state.sensors_health is None:
        return None
    if state.sensors_health & PREARM_BIT:
        return True
    reported = (state.sensors_present or 0) | (state.sensors_enabled or 0)
    return False if reported & PREARM_BIT else None


def assess(state: VehicleState) -> Readiness:
    """What the vehicle still lacks before it can be armed (by its own words, not by a guess of time)."""
    if state.heartbeats == 0 or state.profile is None:
        return Readiness((LINK,))
    waiting: list[str] = []
    if state.system_status == mavlink.MAV_STATE_BOOT:
        waiting.append(INITIALISATION)
    prearm = _prearm_ok(state)
    if prearm is False:
        waiting.append(PREARM)
    elif prearm is None and state.system_status == mavlink.MAV_STATE_UNINIT:
        waiting.append(PREARM)   # PX4 before its first "armable" SYS_STATUS
    ekf_ok = state.ekf_flags is None or (state.ekf_flags & EKF_POSITION and not state.ekf_flags & EKF_NOT_USABLE)
    if not ekf_ok or state.north_m is None or state.down_m is None:
        waiting.append(POSITION)
    if state.home_amsl_m is None and state.profile.takeoff_alt_is_amsl:
        waiting.append(HOME)   # PX4's NAV_TAKEOFF takes an AMSL altitude: home first
    return Readiness(tuple(waiting), state.prearm_text)


@dataclass(frozen=True)
class Step:
    """The one thing to do now: wait (and why), ask for a mode, arm, or nothing (armed in the right mode)."""

    action: str
    mode: str | None = None
    why: str = ""


def _mode_settled(state: VehicleState, wanted: int, now_s: float, rules: ReadinessRules) -> bool:
    return (state.custom_mode == wanted and state.heartbeat_s is not None and state.mode_since_s is not None
            and now_s - state.heartbeat_s <= rules.heartbeat_max_age_s
            and now_s - state.mode_since_s >= rules.mode_settle_s)


def next_step(state: VehicleState, now_s: float, rules: ReadinessRules | None = None) -> Step:
    """What a careful ground station sends next to get the vehicle armed in its arming mode.

    Nothing is asked of a vehicle that is still booting (the mode would be overwritten); the arming
    mode is asked for again whenever the HEARTBEAT shows another one; ARM only once the vehicle says
    it is ready *and* the arming mode has been shown for ``mode_settle_s`` by a fresh HEARTBEAT.
    """
    rules = rules or ReadinessRules()
    readiness = assess(state)
    if LINK in readiness.waiting_for:
        return Step(WAIT, why=str(readiness))
    profile = state.profile
    wanted = profile.custom_mode(profile.arm_mode)
    if state.armed:
        if state.custom_mode == wanted:
            return Step(READY, why=f"armed in {profile.arm_mode}")
        return Step(SET_MODE, profile.arm_mode, f"armed in {state.mode}, not {profile.arm_mode}")
    if INITIALISATION in readiness.waiting_for:
        return Step(WAIT, why=str(readiness))
    if state.custom_mode != wanted:
        return Step(SET_MODE, profile.arm_mode, f"vehicle in {state.mode}, not {profile.arm_mode}")
    if not readiness.ready:
        return Step(WAIT, why=str(readiness))
    if not _mode_settled(state, wanted, now_s, rules):
        return Step(WAIT, why=f"waiting for: {profile.arm_mode} to settle")
    return Step(ARM, why=f"ready to arm in {profile.arm_mode}")
