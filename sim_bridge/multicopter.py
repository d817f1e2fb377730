"""The simulated quadrotor as one object: JSBSim dynamics + our controller + the room, stepped in lockstep.

This is everything below MAVLink. The vehicle layer owns one ``Multicopter``, calls ``step(dt_s)`` from its
loop, reads ``state``, sends ``set_target(ControlTarget)`` and turns ``pop_events()`` into STATUSTEXT.
Units: SI, NED relative to home (the room's start spot, on the floor), yaw 0 = north, clockwise positive.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim_bridge.control import DEFAULT_GAINS_PATH, CascadedController, ControlTarget, load_gains
from sim_bridge.fdm import GEAR_HEIGHT_M, FdmSample, QuadFdm, RigidBodyState
from sim_bridge.world import Contact, ContactModel, Room, load_contact_params

__all__ = ["Multicopter", "RigidBodyState", "ControlTarget", "Contact", "DEFAULT_HOME", "DEFAULT_PHYSICS_HZ"]

DEFAULT_HOME = (47.397742, 8.545594, 488.0)   # lat_deg, lon_deg, alt_m: PX4 SITL's default home
DEFAULT_PHYSICS_HZ = 300.0                     # 200-400 Hz fly alike (docs/bench/sim.md); 300 keeps >= 60x
# the feet (3000 N/m, 100 N s/m each, a quarter of 1.4 kg on each) are integrated explicitly: the damping term
# needs dt * c / m < 2 or the ground ADDS energy. At 100 Hz it is 2.9 (touchdowns flipped and launched the
# vehicle at 55 m/s); at 200 Hz 1.4 and every touchdown of docs/bench/sim.md comes to rest
MIN_PHYSICS_HZ, MAX_PHYSICS_HZ = 200.0, 2000.0
MAX_DISTURBANCE_N = 50.0
ON_GROUND_MIN_GEAR_CONTACTS = 2                # of the four feet
ON_GROUND_MAX_CLIMB_M_S = 0.3                  # and not moving up faster than this
TIPPED_OVER_TILT_RAD = math.radians(60.0)      # armed, touching something and tilted past this: crashed
NONPHYSICAL_SPEED_FACTOR = 3.0                 # armed and faster than 3x the speed limits: the model broke
FELL_THROUGH_FLOOR_M = 0.3                     # gear this far below the floor: the model broke
TIPPED_OVER_EVENT = "ground (tipped over, motors cut)"
PHYSICS_FAULT_EVENT = "physics fault (vehicle reset to rest, disarmed)"


class Multicopter:
    """A quadrotor you arm, give targets and step; never raises on bad targets (see ``sim_bridge.control``)."""

    def __init__(self, room: Room | None = None, *, home_lat_deg: float | None = None,
                 home_lon_deg: float | None = None, home_alt_m: float | None = None,
                 start_ned_m: tuple[float, float, float] = (0.0, 0.0, 0.0), start_yaw_rad: float | None = None,
                 physics_hz: float = DEFAULT_PHYSICS_HZ, gains_path: str | Path = DEFAULT_GAINS_PATH) -> None:
        """Home defaults to the room's ``home`` (else ``DEFAULT_HOME``); start yaw to the room's heading."""
        room_home = (room.home_lat_deg, room.home_lon_deg, room.home_alt_m) if room else (None, None, None)
        self.home_lat_deg = _first(home_lat_deg, room_home[0], DEFAULT_HOME[0])
        self.home_lon_deg = _first(home_lon_deg, room_home[1], DEFAULT_HOME[1])
        self.home_alt_m = _first(home_alt_m, room_home[2], DEFAULT_HOME[2])
        self.room = room
        self.start_ned_m = tuple(float(x) for x in start_ned_m)
        self.start_yaw_rad = float(_first(start_yaw_rad, math.radians(room.start_yaw_deg) if room else None, 0.0))
        if not (isinstance(physics_hz, (int, float)) and MIN_PHYSICS_HZ <= physics_hz <= MAX_PHYSICS_HZ):
            raise ValueError(f"physics_hz must be {MIN_PHYSICS_HZ:g}..{MAX_PHYSICS_HZ:g}, not {physics_hz!r}")
        self.physics_hz = float(physics_hz)
        gains = load_gains(gains_path)              # data files first: a typo fails before JSBSim loads
        self._contacts = ContactModel(room, load_contact_params()) if room else None
        self._fdm = QuadFdm(self.physics_hz, self.home_lat_deg, self.home_lon_deg, self.home_alt_m)
        self.hover_throttle = self._fdm.find_hover_throttle()
        self._controller = CascadedController(gains, self._fdm.mass_kg, self._fdm.inertia_kg_m2,
                                              self.hover_throttle)
        self.reset()

    # ---- lifecycle -------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the start spot, at rest, disarmed, time 0, no events."""
        self._fdm.place(self.start_ned_m, self.start_yaw_rad)
        self._steps = 0
        self._dt_carry_s = 0.0
        self._armed = False
        self._events: list[Contact] = []
        self._touching: dict[str, float] = {}   # obstacle -> last time touched
        self._pushing = False                   # a contact force is set in JSBSim
        self._disturbance_n: tuple[float, ...] = (0.0, 0.0, 0.0)
        self._disturbance_changed = True
        self._sample = self._fdm.sample()
        self._last_good: FdmSample = self._sample
        self._controller.hold_here(self._sample)

    @property
    def t_s(self) -> float:
        """Simulated seconds since the last reset."""
        return self._steps / self.physics_hz

    def set_armed(self, armed: bool) -> None:
        """Arming spins the props at idle and holds where it is; disarming cuts the motors at once."""
        armed = bool(armed)
        if armed != self._armed:
            self._controller.hold_here(self._sample)
        self._armed = armed
        if not armed:
            self._fdm.set_throttles((0.0, 0.0, 0.0, 0.0))

    def set_target(self, target: ControlTarget) -> None:
        """Adopt a target; invalid parts are dropped or clamped, never raised (see ``sim_bridge.control``)."""
        self._controller.set_target(target, self._sample)

    @property
    def target(self) -> ControlTarget:
        """The target being flown, after sanitising."""
        return self._controller.target

    def set_disturbance_force_ned_n(self, force_ned_n: tuple[float, float, float]) -> None:
        """A steady external push at the CG (N, NED), e.g. a gust, until changed; non-finite parts count as 0.

        For benchmarks and tests of disturbance rejection; the vehicle layer has no need of it.
        """
        clean = []
        try:
            values = tuple(force_ned_n)[:3]
        except TypeError:
            values = ()
        for value in values:
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = 0.0
            clean.append(max(-MAX_DISTURBANCE_N, min(MAX_DISTURBANCE_N, number)) if math.isfinite(number) else 0.0)
        self._disturbance_n = tuple(clean + [0.0] * (3 - len(clean)))
        self._disturbance_changed = True

    def pop_events(self) -> list[Contact]:
        """Contacts since the last call, oldest first."""
        events, self._events = self._events, []
        return events

    # ---- simulation ------------------------------------------------------------------------
    def step(self, dt_s: float) -> None:
        """Advance the simulation by ``dt_s`` seconds (rounded to whole physics steps, remainder carried)."""
        if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s)) or dt_s <= 0.0:
            return
        physics_dt_s = 1.0 / self.physics_hz
        total_s = dt_s + self._dt_carry_s
        steps = int(total_s / physics_dt_s + 1e-9)
        self._dt_carry_s = total_s - steps * physics_dt_s
        for _ in range(steps):
            self._physics_step(physics_dt_s)

    def _physics_step(self, dt_s: float) -> None:
        s = self._sample
        on_ground = self._on_ground(s)
        touching = s.gear_contacts > 0 or s.frame_contacts > 0 or self._supported()
        if self._armed and touching and self._tilt_rad(s) > TIPPED_OVER_TILT_RAD:
            self._cut_motors(TIPPED_OVER_EVENT, s)   # as ArduPilot's crash check: never thrust into the ground
        if self._armed:
            self._fdm.set_throttles(self._controller.update(s, dt_s, on_ground, touching, -s.down_m))
        if self._contacts is not None:
            self._apply_contacts(s)
        elif self._disturbance_changed:
            self._fdm.set_contact_force_ned_n(*self._disturbance_n)
        self._disturbance_changed = False
        self._fdm.run_step()
        self._steps += 1
        self._sample = self._fdm.sample()
        if self._physical(self._sample):
            self._last_good = self._sample
        else:
            self._recover()

    def _supported(self) -> bool:
        return self._contacts is not None and self._contacts.supported

    @staticmethod
    def _tilt_rad(s: FdmSample) -> float:
        cos_tilt = math.cos(s.roll_rad) * math.cos(s.pitch_rad)
        return math.acos(max(-1.0, min(1.0, cos_tilt)))

    def _cut_motors(self, event_name: str, s: FdmSample) -> None:
        """Disarm (the vehicle layer reads ``state.armed``) and report why as an event."""
        self.set_armed(False)
        self._events.append(Contact(self.t_s, event_name, (s.north_m, s.east_m, s.down_m)))

    def _physical(self, s: FdmSample) -> bool:
        """A last safety net: NaN/inf, under the floor, climbing at 3x the limit, or (armed) 3x any limit."""
        values = (s.north_m, s.east_m, s.down_m, s.vn_m_s, s.ve_m_s, s.vd_m_s, s.roll_rad, s.pitch_rad,
                  s.yaw_rad, s.p_rad_s, s.q_rad_s, s.r_rad_s)
        if not all(math.isfinite(v) for v in values) or s.down_m > FELL_THROUGH_FLOOR_M:
            return False
        g = self._controller.gains
        if -s.vd_m_s > NONPHYSICAL_SPEED_FACTOR * g.limits_vertical_speed_m_s:
            return False  # climbing that fast: only a misbehaving ground could have thrown it up
        if not self._armed:
            return True   # a disarmed vehicle may fall fast from high up: that is physics
        return (math.hypot(s.vn_m_s, s.ve_m_s) <= NONPHYSICAL_SPEED_FACTOR * g.limits_horizontal_speed_m_s
                and s.vd_m_s <= NONPHYSICAL_SPEED_FACTOR * g.limits_vertical_speed_m_s)

    def _recover(self) -> None:
        """The model left physics: put the vehicle at rest, level and disarmed where it last was sane.

        On the floor below that point if it was low (or below the floor), else in the air (it then falls,
        disarmed). Any disturbance force is cleared. Reported as a ``PHYSICS_FAULT_EVENT`` contact, which the
        MAVLink layer turns into a STATUSTEXT like any contact; the vehicle layer sees ``state.armed`` False.
        """
        good = self._last_good
        down_m = good.down_m if good.down_m < -0.5 else 0.0
        self._fdm.place((good.north_m, good.east_m, down_m), good.yaw_rad)
        self._armed = False
        self._pushing = False
        self._disturbance_n = (0.0, 0.0, 0.0)   # whatever pushed it there is gone too
        self._disturbance_changed = True
        self._sample = self._last_good = self._fdm.sample()
        self._controller.hold_here(self._sample)
        self._events.append(Contact(self.t_s, PHYSICS_FAULT_EVENT, (good.north_m, good.east_m, down_m)))

    def _apply_contacts(self, s: FdmSample) -> None:
        center = (s.north_m, s.east_m, s.down_m - GEAR_HEIGHT_M)
        force, touching = self._contacts.force_ned_n(center, (s.vn_m_s, s.ve_m_s, s.vd_m_s))
        if touching or self._pushing or self._disturbance_changed:
            extra = self._disturbance_n
            self._fdm.set_contact_force_ned_n(force[0] + extra[0], force[1] + extra[1], force[2] + extra[2])
            self._pushing = bool(touching)
        now = self.t_s
        for name in touching:
            last = self._touching.get(name)
            if last is None or now - last > self._contacts.params.event_repeat_s:
                self._events.append(Contact(now, name, (s.north_m, s.east_m, s.down_m)))
            self._touching[name] = now

    def _on_ground(self, s: FdmSample) -> bool:
        """Standing on the floor (gear), or resting on top of furniture (contact from below)."""
        if s.vd_m_s <= -ON_GROUND_MAX_CLIMB_M_S:
            return False
        if s.gear_contacts >= ON_GROUND_MIN_GEAR_CONTACTS or s.frame_contacts > 0:
            return True   # standing, or lying on its frame (tipped over)
        return self._supported() and s.vd_m_s < ON_GROUND_MAX_CLIMB_M_S

    @property
    def state(self) -> RigidBodyState:
        s = self._sample
        return RigidBodyState(
            t_s=self.t_s,
            pos_ned_m=np.array([s.north_m, s.east_m, s.down_m]),
            vel_ned_m_s=np.array([s.vn_m_s, s.ve_m_s, s.vd_m_s]),
            roll_rad=s.roll_rad, pitch_rad=s.pitch_rad, yaw_rad=s.yaw_rad,
            roll_rate_rad_s=s.p_rad_s, pitch_rate_rad_s=s.q_rad_s, yaw_rate_rad_s=s.r_rad_s,
            on_ground=self._on_ground(s), armed=self._armed,
            lat_deg=s.lat_deg, lon_deg=s.lon_deg, alt_amsl_m=self.home_alt_m - s.down_m,
            throttle=self._fdm.mean_throttle,
        )


def _first(*values: float | None) -> float:
    return next(float(v) for v in values if v is not None)
