"""The flying part of an autopilot: what the vehicle does in each behaviour, on top of the physics.

An autopilot personality (``sim_bridge.autopilot``) decides *which* behaviour runs (its flight modes,
its refusals, its failsafes); this module decides *how*: take off after a spool-up, hold where it
stopped, follow a velocity setpoint with the ArduCopter yaw rules, land and disarm, return home, and
stop before the fence. It owns the ``Multicopter`` facade and talks to it only through
``set_target(ControlTarget)``, ``step(dt_s)``, ``set_armed`` and ``state``; no sockets here.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.control import ControlTarget
from sim_bridge.fdm import RigidBodyState
from sim_bridge.fence import FENCE_BRAKE_ACCEL_M_S2, Fence
from sim_bridge.frames import wrap_pi
from sim_bridge.multicopter import Multicopter
from sim_bridge.setpoints import Setpoint

__all__ = ["Behaviour", "Fence", "Vehicle", "VehicleEvent", "VehicleLimits"]   # Fence re-exported

#: Below this climb (m) after a takeoff started the vehicle is still "on the ground" for the auto-disarm.
LIFTOFF_HEIGHT_M = 0.1
#: Braking is over and the hold point is captured when the horizontal speed falls below this.
HOLD_CAPTURE_SPEED_M_S = 0.15
#: Gain turning a per-axis position target into a velocity (used when position and velocity are mixed).
POSITION_TO_VELOCITY_PER_S = 1.0
#: Altitude targets stay this far below ``ceiling_m`` (the highest the gear point can go without touching).
CEILING_MARGIN_M = 0.2


class Behaviour(enum.Enum):
    IDLE = "idle"          # disarmed, or armed on the ground waiting for a takeoff
    HOLD = "hold"          # brake, then hold the point where it stopped
    VELOCITY = "velocity"  # follow the latest external setpoint
    TAKEOFF = "takeoff"    # spool up, climb to the takeoff altitude, then HOLD
    LAND = "land"          # descend at the landing speed where it is, disarm after touchdown
    RTL = "rtl"            # climb, fly home, then LAND


class VehicleEvent(enum.Enum):
    TAKEOFF_DONE = "takeoff done"
    LIFTOFF = "liftoff"
    TOUCHDOWN = "touchdown"
    DISARMED_LANDED = "disarmed after landing"
    DISARMED_IDLE = "disarmed: no takeoff after arming"
    SETPOINT_TIMEOUT = "setpoint timeout"
    RTL_LANDING = "rtl landing"


@dataclass
class VehicleLimits:
    """Numbers a personality derives from its parameters (SI units)."""

    max_speed_xy_m_s: float = 10.0
    max_climb_m_s: float = 2.5
    max_descent_m_s: float = 1.5
    takeoff_climb_m_s: float = 1.0
    takeoff_delay_s: float = 2.5
    land_speed_m_s: float = 0.5
    disarm_after_land_s: float = 2.0
    disarm_idle_s: float = 10.0             # 0 = never
    setpoint_timeout_s: float | None = 3.0  # None: the personality handles setpoint loss itself
    yaw_slew_rad_s: float | None = math.radians(60)
    auto_yaw_min_speed_m_s: float = 0.5
    return_alt_m: float = 15.0
    return_cone_deg: float | None = None    # PX4: return no higher than distance / tan(cone) near home
    return_speed_m_s: float = 5.0


@dataclass
class _Hold:
    point_ned_m: tuple[float, float, float] | None = None   # None while still braking
    yaw_rad: float = 0.0


@dataclass
class Vehicle:
    """Behaviours over a ``sim_bridge.multicopter.Multicopter``; ``step(dt_s)`` returns what happened."""

    multicopter: Multicopter
    limits: VehicleLimits = field(default_factory=VehicleLimits)
    fence: Fence = field(default_factory=Fence)
    ceiling_m: float | None = None          # highest gear altitude (m above home) before the vehicle touches the ceiling
    room_box_ned_m: tuple[float, float, float, float] | None = None   # where the gear point fits: n_min, n_max, e_min, e_max
    time_s: float = 0.0
    behaviour: Behaviour = Behaviour.IDLE
    setpoint: Setpoint | None = None
    clamped_setpoints: int = 0
    fence_stops: int = 0

    def __post_init__(self) -> None:
        self._state: RigidBodyState | None = None
        self._hold = _Hold(yaw_rad=self.state.yaw_rad)
        self._yaw_target_rad: float = self.state.yaw_rad
        self._takeoff_alt_m = 0.0
        self._takeoff_started_s = 0.0
        self._armed_idle_since_s: float | None = None
        self._touchdown_s: float | None = None
        self._airborne = not self.state.on_ground
        self._rtl_phase = "climb"
        self.rtl_alt_m = 0.0
        self._last_descent_m_s = 0.0
        self.touchdown_speed_m_s = 0.0

    # ----------------------------------------------------------------- state
    @property
    def state(self) -> RigidBodyState:
        """The physics state, read once per tick (building it costs more than everything that reads it)."""
        if self._state is None:
            self._state = self.multicopter.state
        return self._state

    @property
    def armed(self) -> bool:
        return bool(self.state.armed)

    @property
    def altitude_m(self) -> float:
        return -float(self.state.pos_ned_m[2])

    @property
    def landed(self) -> bool:
        return bool(self.state.on_ground)

    def landed_state(self) -> int:
        """MAV_LANDED_STATE as EXTENDED_SYS_STATE reports it."""
        if not self.armed or (self.landed and self.behaviour is not Behaviour.TAKEOFF):
            return mavlink.MAV_LANDED_STATE_ON_GROUND
        if self.behaviour is Behaviour.TAKEOFF:
            return mavlink.MAV_LANDED_STATE_TAKEOFF
        if self.behaviour is Behaviour.LAND or (self.behaviour is Behaviour.RTL and self._rtl_phase == "land"):
            return mavlink.MAV_LANDED_STATE_LANDING
        return mavlink.MAV_LANDED_STATE_IN_AIR

    def setpoint_age_s(self) -> float:
        return math.inf if self.setpoint is None else self.time_s - self.setpoint.received_s

    # ----------------------------------------------------------------- commands
    def arm(self) -> None:
        self.multicopter.set_armed(True)
        self._state = None
        self._armed_idle_since_s = self.time_s
        if self.behaviour is not Behaviour.TAKEOFF:
            self.behaviour = Behaviour.IDLE if self.landed else Behaviour.HOLD

    def disarm(self) -> None:
        self.multicopter.set_armed(False)
        self._state = None
        self._armed_idle_since_s = None
        self.behaviour = Behaviour.IDLE

    def takeoff(self, alt_m: float) -> None:
        """Climb to ``alt_m`` above home after the spool-up; the caller checked armed and landed."""
        self._takeoff_alt_m = self._cap_altitude(alt_m)
        self._takeoff_started_s = self.time_s
        self._yaw_target_rad = float(self.state.yaw_rad)
        self._hold = _Hold(point_ned_m=None, yaw_rad=self._yaw_target_rad)
        self.behaviour = Behaviour.TAKEOFF

    def hold(self) -> None:
        """Brake, then hold the point where the vehicle stopped, keeping the current heading target."""
        if self.behaviour is Behaviour.HOLD:
            return
        self._hold = _Hold(point_ned_m=None, yaw_rad=self._yaw_target_rad)
        self.behaviour = Behaviour.HOLD if not (self.landed and self.behaviour is Behaviour.IDLE) else Behaviour.IDLE

    def land(self) -> None:
        """Brake, then descend where it stopped (never toward an older hold point)."""
        self._touchdown_s = None
        self._hold = _Hold(point_ned_m=None, yaw_rad=self._yaw_target_rad)
        self.behaviour = Behaviour.LAND

    def return_to_launch(self) -> float:
        """Climb (never descend) to the return altitude, fly home, land; returns that altitude (m above home)."""
        pos = self.state.pos_ned_m
        return_alt = self.limits.return_alt_m
        if self.limits.return_cone_deg:
            distance = math.hypot(float(pos[0]), float(pos[1]))
            return_alt = min(return_alt, distance / math.tan(math.radians(self.limits.return_cone_deg)))
        self.rtl_alt_m = self._cap_altitude(max(-float(pos[2]), return_alt))
        self._rtl_phase = "climb"
        self._touchdown_s = None
        self.behaviour = Behaviour.RTL
        return self.rtl_alt_m

    def follow(self, setpoint: Setpoint, from_ground: bool = False) -> None:
        """Take a new external setpoint (already in NED, absolute yaw).

        ArduCopter (``from_ground`` False): on the ground it does nothing, and it replaces a takeoff in
        progress. PX4 offboard (``from_ground`` True) flies from the ground with it.
        """
        self.setpoint = setpoint
        if not from_ground and self.landed and self.behaviour in (Behaviour.IDLE, Behaviour.TAKEOFF) \
                and not self._airborne:
            # ArduCopter: a GUIDED velocity command replaces the takeoff; landed, it just sits there.
            self.behaviour = Behaviour.IDLE
            return
        self.behaviour = Behaviour.VELOCITY

    def set_yaw_target(self, yaw_rad: float) -> None:
        """CONDITION_YAW-style heading change while holding or following."""
        self._hold.yaw_rad = wrap_pi(yaw_rad)
        if self.setpoint is not None:
            self.setpoint = self.setpoint.with_yaw(wrap_pi(yaw_rad))

    # ----------------------------------------------------------------- the loop
    def step(self, dt_s: float) -> list[VehicleEvent]:
        """Advance the physics by ``dt_s`` under the current behaviour."""
        events: list[VehicleEvent] = []
        state = self.state
        pos = (float(state.pos_ned_m[0]), float(state.pos_ned_m[1]), float(state.pos_ned_m[2]))
        vel_now = state.vel_ned_m_s
        target: ControlTarget | None = None

        if self.behaviour is Behaviour.VELOCITY and self.limits.setpoint_timeout_s is not None \
                and self.setpoint_age_s() > self.limits.setpoint_timeout_s:
            events.append(VehicleEvent.SETPOINT_TIMEOUT)
            self.hold()

        if self.behaviour is Behaviour.IDLE:
            target = ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=self._yaw_target_rad) if self.armed else None
        elif self.behaviour is Behaviour.HOLD:
            target = self._hold_target(pos, vel_now)
        elif self.behaviour is Behaviour.TAKEOFF:
            target, done = self._takeoff_target(pos)
            if done:
                events.append(VehicleEvent.TAKEOFF_DONE)
                self._hold = _Hold(point_ned_m=(pos[0], pos[1], -self._takeoff_alt_m), yaw_rad=self._hold.yaw_rad)
                self.behaviour = Behaviour.HOLD
        elif self.behaviour is Behaviour.VELOCITY:
            target = self._velocity_target(pos, dt_s)
        elif self.behaviour is Behaviour.LAND:
            target = self._land_target(pos)
        elif self.behaviour is Behaviour.RTL:
            target = self._rtl_target(pos, events)

        if target is not None:
            self.multicopter.set_target(target)
        self.multicopter.step(dt_s)
        self._state = None
        self.time_s += dt_s
        events.extend(self._after_step())
        return events

    # ----------------------------------------------------------------- behaviours
    def _slew_yaw(self, desired_rad: float, dt_s: float) -> float:
        slew = self.limits.yaw_slew_rad_s
        error = wrap_pi(desired_rad - self._yaw_target_rad)
        if slew is not None:
            error = max(-slew * dt_s, min(slew * dt_s, error))
        self._yaw_target_rad = wrap_pi(self._yaw_target_rad + error)
        return self._yaw_target_rad

    def _hold_target(self, pos: tuple[float, float, float], vel_now: tuple[float, float, float]) -> ControlTarget:
        self._yaw_target_rad = self._hold.yaw_rad
        if self._hold.point_ned_m is None:
            if math.hypot(float(vel_now[0]), float(vel_now[1])) > HOLD_CAPTURE_SPEED_M_S:
                return ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=self._hold.yaw_rad)
            self._hold.point_ned_m = pos
        return ControlTarget(pos_ned_m=self._hold.point_ned_m, yaw_rad=self._hold.yaw_rad)

    def _takeoff_target(self, pos: tuple[float, float, float]) -> tuple[ControlTarget, bool]:
        if self.time_s - self._takeoff_started_s < self.limits.takeoff_delay_s:
            return ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=self._hold.yaw_rad), False
        remaining = self._takeoff_alt_m - (-pos[2])
        if remaining <= 0.05:
            return ControlTarget(pos_ned_m=(pos[0], pos[1], -self._takeoff_alt_m), yaw_rad=self._hold.yaw_rad), True
        climb = min(self.limits.takeoff_climb_m_s, max(0.2, POSITION_TO_VELOCITY_PER_S * remaining))
        return ControlTarget(vel_ned_m_s=(0.0, 0.0, -climb), yaw_rad=self._hold.yaw_rad), False

    def _velocity_target(self, pos: tuple[float, float, float], dt_s: float) -> ControlTarget:
        sp = self.setpoint
        assert sp is not None
        vel = list(sp.vel_ned_m_s)
        for axis in range(3):
            wanted = sp.pos_ned_m[axis]
            if wanted is not None:
                if axis == 2:
                    wanted = -self._cap_altitude(-wanted)
                vel[axis] += POSITION_TO_VELOCITY_PER_S * (wanted - pos[axis])
        vel = self._limit_velocity(vel)
        if self.fence.limit(pos, vel):
            self.fence_stops += 1
        if self.ceiling_m is not None:
            vel[2] = max(vel[2], -math.sqrt(2.0 * FENCE_BRAKE_ACCEL_M_S2 * max(0.0, self._cap_altitude(1e9) + pos[2])))
        if sp.yaw_rate_rad_s is not None:
            self._yaw_target_rad = float(self.state.yaw_rad)
            self._hold.yaw_rad = self._yaw_target_rad
            return ControlTarget(vel_ned_m_s=tuple(vel), yaw_rate_rad_s=sp.yaw_rate_rad_s)
        if sp.yaw_rad is not None:
            yaw = self._slew_yaw(sp.yaw_rad, dt_s)
        elif sp.auto_yaw and math.hypot(sp.vel_ned_m_s[0], sp.vel_ned_m_s[1]) >= self.limits.auto_yaw_min_speed_m_s:
            yaw = self._slew_yaw(math.atan2(sp.vel_ned_m_s[1], sp.vel_ned_m_s[0]), dt_s)
        else:
            yaw = self._yaw_target_rad
        self._hold.yaw_rad = yaw
        return ControlTarget(vel_ned_m_s=tuple(vel), yaw_rad=yaw)

    def _land_target(self, pos: tuple[float, float, float]) -> ControlTarget:
        if self.landed:
            return ControlTarget(vel_ned_m_s=(0.0, 0.0, self.limits.land_speed_m_s), yaw_rad=self._hold.yaw_rad)
        if self._hold.point_ned_m is None:
            vel_now = self.state.vel_ned_m_s
            if math.hypot(float(vel_now[0]), float(vel_now[1])) > HOLD_CAPTURE_SPEED_M_S:
                return ControlTarget(vel_ned_m_s=(0.0, 0.0, 0.0), yaw_rad=self._hold.yaw_rad)   # brake first
            self._hold.point_ned_m = pos
        hold_n, hold_e, _ = self._hold.point_ned_m
        vel = (POSITION_TO_VELOCITY_PER_S * (hold_n - pos[0]), POSITION_TO_VELOCITY_PER_S * (hold_e - pos[1]),
               self.limits.land_speed_m_s)
        return ControlTarget(vel_ned_m_s=vel, yaw_rad=self._hold.yaw_rad)

    def _rtl_target(self, pos: tuple[float, float, float], events: list[VehicleEvent]) -> ControlTarget:
        return_alt = self.rtl_alt_m
        if self._rtl_phase == "climb":
            if -pos[2] >= return_alt - 0.1:
                self._rtl_phase = "return"
            else:
                return ControlTarget(pos_ned_m=(pos[0], pos[1], -return_alt), yaw_rad=self._hold.yaw_rad)
        if self._rtl_phase == "return":
            dist = math.hypot(pos[0], pos[1])
            if dist < 0.2:
                self._rtl_phase = "land"
                self._hold = _Hold(point_ned_m=(0.0, 0.0, pos[2]), yaw_rad=self._hold.yaw_rad)
                events.append(VehicleEvent.RTL_LANDING)
            else:
                speed = min(self.limits.return_speed_m_s, self.limits.max_speed_xy_m_s, POSITION_TO_VELOCITY_PER_S * dist)
                vel = (-pos[0] / dist * speed, -pos[1] / dist * speed, POSITION_TO_VELOCITY_PER_S * (-return_alt - pos[2]))
                return ControlTarget(vel_ned_m_s=vel, yaw_rad=self._hold.yaw_rad)
        return self._land_target(pos)

    # ----------------------------------------------------------------- helpers
    def _cap_altitude(self, alt_m: float) -> float:
        if self.ceiling_m is not None:
            alt_m = min(alt_m, self.ceiling_m - CEILING_MARGIN_M)
        if self.fence.enabled and self.fence.alt_max_m is not None:
            alt_m = min(alt_m, self.fence.alt_max_m - self.fence.margin_m)
        return alt_m

    def _limit_velocity(self, vel: list[float]) -> list[float]:
        limits = self.limits
        clamped = False
        speed_xy = math.hypot(vel[0], vel[1])
        if speed_xy > limits.max_speed_xy_m_s:
            scale = limits.max_speed_xy_m_s / speed_xy
            vel[0] *= scale
            vel[1] *= scale
            clamped = True
        if vel[2] < -limits.max_climb_m_s or vel[2] > limits.max_descent_m_s:
            vel[2] = max(-limits.max_climb_m_s, min(limits.max_descent_m_s, vel[2]))
            clamped = True
        if clamped and self.setpoint is not None and not self.setpoint.clamp_counted:
            self.setpoint.clamp_counted = True
            self.clamped_setpoints += 1
        return vel

    def _after_step(self) -> list[VehicleEvent]:
        events = []
        state = self.state
        on_ground = bool(state.on_ground)
        if not on_ground:
            self._last_descent_m_s = max(0.0, float(state.vel_ned_m_s[2]))
        if self._airborne and on_ground:
            self._airborne = False
            self.touchdown_speed_m_s = self._last_descent_m_s
            if self.armed:
                events.append(VehicleEvent.TOUCHDOWN)
                self._touchdown_s = self.time_s
        elif not self._airborne and not on_ground and self.altitude_m > LIFTOFF_HEIGHT_M:
            self._airborne = True
            self._armed_idle_since_s = None
            events.append(VehicleEvent.LIFTOFF)
        if not self.armed:
            return events
        landing = self.behaviour is Behaviour.LAND or (self.behaviour is Behaviour.RTL and self._rtl_phase == "land")
        if landing and on_ground:
            if self._touchdown_s is None:
                self._touchdown_s = self.time_s
            if self.time_s - self._touchdown_s >= self.limits.disarm_after_land_s:
                self.disarm()
                events.append(VehicleEvent.DISARMED_LANDED)
                return events
        idle_on_ground = on_ground and self.behaviour in (Behaviour.IDLE, Behaviour.HOLD, Behaviour.VELOCITY)
        if not idle_on_ground:
            self._armed_idle_since_s = None
        elif self._armed_idle_since_s is None:
            self._armed_idle_since_s = self.time_s
        elif self.limits.disarm_idle_s > 0 and self.time_s - self._armed_idle_since_s >= self.limits.disarm_idle_s:
            self.disarm()
            events.append(VehicleEvent.DISARMED_IDLE)
        return events
