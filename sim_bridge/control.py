"""Our flight controller: a cascade velocity -> attitude -> body rate -> motor mix, gains from a data file.

Targets (``ControlTarget``) are NED with absolute yaw. Bad targets never reach JSBSim (``sanitize_target``):
* a vector (velocity or position) with any NaN/inf component, the wrong length or a non-number is DROPPED;
* velocities are CLAMPED to the limits (horizontal norm, vertical), positions to ``position_offset_m`` of home;
* a non-finite yaw or yaw rate is DROPPED; yaw is wrapped to [-pi, pi), yaw rate clamped;
* a target with no valid vector holds the position where the vehicle was when the first such target came
  (a stream of them keeps that point), and one with no valid yaw/yaw rate likewise holds the heading it had
  then. So garbage brakes the vehicle (and returns it to where the garbage began), never sends it anywhere.
Precedence: position over velocity, yaw over yaw rate.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from sim_bridge.fdm import FdmSample
from sim_bridge.frames import GRAVITY_M_S2, wrap_pi

__all__ = ["ControlTarget", "ControlGains", "load_gains", "sanitize_target", "CascadedController",
           "DEFAULT_GAINS_PATH"]

DEFAULT_GAINS_PATH = Path(__file__).resolve().parent / "data" / "control.toml"
CLIMB_INTENT_M_S = 0.05      # a vertical target this far upward (or a position this far above) means "take off"
MIN_LIFT_FRACTION = 0.3      # never ask for less than 0.3 g of lift while flying (keeps the attitude valid)
MIN_TILT_COSINE = 0.5        # thrust tilt compensation is capped at 2x
YAW_TORQUE_SHARE = 0.3       # the yaw term may move a motor's thrust by at most 30 % of the mean thrust


@dataclass(frozen=True)
class ControlTarget:
    """What the vehicle layer asks for. NED frame, metres, radians, absolute yaw (0 = north)."""

    vel_ned_m_s: tuple[float, float, float] | None = None   # velocity mode
    pos_ned_m: tuple[float, float, float] | None = None     # position-hold mode (hold, brake, takeoff altitude)
    yaw_rad: float | None = None                            # absolute heading, or
    yaw_rate_rad_s: float | None = None                     # yaw rate; neither = keep current heading


@dataclass(frozen=True)
class ControlGains:
    """Flattened ``control.toml``: ``<section>_<key>`` (e.g. ``velocity_kp_horizontal_per_s``)."""

    limits_horizontal_speed_m_s: float
    limits_vertical_speed_m_s: float
    limits_yaw_rate_deg_s: float
    limits_tilt_deg: float
    limits_position_offset_m: float
    limits_ground_idle_throttle: float
    position_kp_horizontal_per_s: float
    position_kp_vertical_per_s: float
    velocity_kp_horizontal_per_s: float
    velocity_ki_horizontal_per_s2: float
    velocity_kp_vertical_per_s: float
    velocity_ki_vertical_per_s2: float
    velocity_integral_limit_vertical_m_s2: float
    velocity_integral_limit_horizontal_m_s2: float
    velocity_integrate_below_error_m_s: float
    velocity_accel_limit_horizontal_m_s2: float
    velocity_accel_limit_vertical_m_s2: float
    velocity_feedforward_horizontal: float
    velocity_feedforward_vertical: float
    attitude_kp_roll_pitch_per_s: float
    attitude_kp_yaw_per_s: float
    rate_kp_roll_pitch_per_s: float
    rate_kp_yaw_per_s: float
    rate_ki_yaw_per_s2: float
    mixer_arm_length_m: float
    mixer_torque_per_thrust_m: float
    landing_near_ground_m: float
    landing_tilt_limit_deg: float
    landing_spool_down_per_s: float
    landing_level_within_deg: float
    landing_tilted_lift_share: float


def load_gains(path: str | Path = DEFAULT_GAINS_PATH) -> ControlGains:
    """Read a gains file; a missing or extra key is a ValueError naming the file and the key."""
    path = Path(path)
    try:
        data: dict[str, Any] = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read gains: {exc}") from None
    flat: dict[str, float] = {}
    for section, table in data.items():
        if not isinstance(table, dict):
            raise ValueError(f"{path}: [{section}] must be a table")
        for key, value in table.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{path}: {section}.{key} must be a finite number")
            flat[f"{section}_{key}"] = float(value)
    names = {f.name for f in fields(ControlGains)}
    if missing := sorted(names - flat.keys()):
        raise ValueError(f"{path}: missing gain {missing[0].replace('_', '.', 1)}")
    if extra := sorted(flat.keys() - names):
        raise ValueError(f"{path}: unknown gain {extra[0].replace('_', '.', 1)}")
    return ControlGains(**flat)


def _finite_vector(value: object) -> tuple[float, float, float] | None:
    try:
        vector = tuple(float(x) for x in value)  # type: ignore[union-attr]
    except (TypeError, ValueError, OverflowError):
        return None
    if len(vector) != 3 or not all(math.isfinite(x) for x in vector):
        return None
    return vector  # type: ignore[return-value]


def _finite_scalar(value: object) -> float | None:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return None
    return number if math.isfinite(number) else None


def _clamp(x: float, limit: float) -> float:
    return -limit if x < -limit else (limit if x > limit else x)


def sanitize_target(target: object, gains: ControlGains) -> ControlTarget:
    """Return a target that is safe to fly (see the module docstring for the rules)."""
    vel = _finite_vector(getattr(target, "vel_ned_m_s", None))
    pos = _finite_vector(getattr(target, "pos_ned_m", None))
    yaw = _finite_scalar(getattr(target, "yaw_rad", None))
    yaw_rate = _finite_scalar(getattr(target, "yaw_rate_rad_s", None))
    if vel is not None:
        speed_m_s = math.hypot(vel[0], vel[1])
        scale = min(1.0, gains.limits_horizontal_speed_m_s / speed_m_s) if speed_m_s > 0 else 1.0
        vel = (vel[0] * scale, vel[1] * scale, _clamp(vel[2], gains.limits_vertical_speed_m_s))
    if pos is not None:
        pos = tuple(_clamp(x, gains.limits_position_offset_m) for x in pos)  # type: ignore[assignment]
    if yaw is not None:
        yaw = wrap_pi(yaw)
    if yaw_rate is not None:
        yaw_rate = _clamp(yaw_rate, math.radians(gains.limits_yaw_rate_deg_s))
    return ControlTarget(vel_ned_m_s=vel, pos_ned_m=pos, yaw_rad=yaw, yaw_rate_rad_s=yaw_rate)


class CascadedController:
    """Velocity -> attitude -> rate -> per-motor thrust -> throttle, for an X quad (gcs_quad motor order).

    ``hover_throttle`` comes from the FDM's trim search; the thrust model is thrust = k * throttle^2 with
    k fitted so that hover_throttle lifts the weight, and the velocity integrators absorb what is left.
    """

    def __init__(self, gains: ControlGains, mass_kg: float, inertia_kg_m2: tuple[float, float, float],
                 hover_throttle: float) -> None:
        self.gains = gains
        self.mass_kg = mass_kg
        self.inertia_kg_m2 = inertia_kg_m2
        self.hover_throttle = hover_throttle
        self.thrust_per_throttle2_n = mass_kg * GRAVITY_M_S2 / (4.0 * hover_throttle * hover_throttle)
        self._target = ControlTarget()
        self._hold_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._hold_yaw_rad = 0.0
        self._lift_share = 0.0   # touching down: collective as a share of the weight, spooling down to idle
        self.reset_integrators()

    def reset_integrators(self) -> None:
        """Forget integrators and the slewed velocity reference (taken again from the vehicle)."""
        self._i_vel = [0.0, 0.0, 0.0]
        self._i_yaw_rate = 0.0
        self._v_ref: list[float] | None = None

    def set_target(self, target: ControlTarget, sample: FdmSample) -> None:
        """Adopt a target (sanitised); hold-position and hold-heading references are taken from ``sample``."""
        clean = sanitize_target(target, self.gains)
        if clean.pos_ned_m is None and clean.vel_ned_m_s is None:  # hold: where it is now, or where it was
            holding = self._target.pos_ned_m is None and self._target.vel_ned_m_s is None
            if not holding:
                self._hold_pos = (sample.north_m, sample.east_m, sample.down_m)
        if clean.yaw_rad is None and clean.yaw_rate_rad_s is None:
            keeping = self._target.yaw_rad is None and self._target.yaw_rate_rad_s is None
            if not keeping:
                self._hold_yaw_rad = sample.yaw_rad
        self._target = clean

    def hold_here(self, sample: FdmSample) -> None:
        """Forget the target: hold this position and heading (arming, reset)."""
        self._target = ControlTarget()
        self._hold_pos = (sample.north_m, sample.east_m, sample.down_m)
        self._hold_yaw_rad = sample.yaw_rad
        self._lift_share = 0.0
        self.reset_integrators()

    @property
    def target(self) -> ControlTarget:
        return self._target

    def _velocity_target(self, s: FdmSample) -> tuple[float, float, float]:
        g = self.gains
        t = self._target
        if t.vel_ned_m_s is not None and t.pos_ned_m is None:
            return t.vel_ned_m_s
        pn, pe, pd = t.pos_ned_m if t.pos_ned_m is not None else self._hold_pos
        vn = g.position_kp_horizontal_per_s * (pn - s.north_m)
        ve = g.position_kp_horizontal_per_s * (pe - s.east_m)
        vd = _clamp(g.position_kp_vertical_per_s * (pd - s.down_m), g.limits_vertical_speed_m_s)
        speed = math.hypot(vn, ve)
        if speed > g.limits_horizontal_speed_m_s:
            vn, ve = (vn * g.limits_horizontal_speed_m_s / speed, ve * g.limits_horizontal_speed_m_s / speed)
        return vn, ve, vd

    def wants_climb(self, s: FdmSample) -> bool:
        t = self._target
        if t.pos_ned_m is not None:
            return t.pos_ned_m[2] < s.down_m - CLIMB_INTENT_M_S
        if t.vel_ned_m_s is not None:
            return t.vel_ned_m_s[2] < -CLIMB_INTENT_M_S
        return self._hold_pos[2] < s.down_m - CLIMB_INTENT_M_S

    def update(self, s: FdmSample, dt_s: float, on_ground: bool, touching: bool = False,
               height_m: float = math.inf) -> list[float]:
        """One control step: the four throttles (front-right, aft-left, front-left, aft-right).

        ``on_ground``: standing (spin at idle unless asked to climb). ``touching``: some part touches the
        ground or a top (a touchdown in progress): unless asked to climb, level the vehicle and spool the
        collective down to idle, with the integrators cleared, so a sideways or tilted touchdown is neither
        steered nor pushed along the ground. ``height_m``: above the floor; close to it, descending or
        holding, the tilt is limited (``landing.tilt_limit_deg``) so the vehicle arrives nearly level.
        """
        g = self.gains
        if (on_ground or touching) and not self.wants_climb(s):
            self.reset_integrators()
            self._hold_yaw_rad = s.yaw_rad if self._target.yaw_rad is None else self._hold_yaw_rad
            self._hold_pos = (s.north_m, s.east_m, s.down_m)
            level = self._spool_down(s, dt_s)
            idle_share = (g.limits_ground_idle_throttle / self.hover_throttle) ** 2
            if (on_ground and level) or self._lift_share <= idle_share:   # standing level: props at idle
                self._lift_share = 0.0
                return [g.limits_ground_idle_throttle] * 4
            return self._level(s, GRAVITY_M_S2 * self._lift_share)
        if self._lift_share < 1.0 and height_m < g.landing_near_ground_m and not self.wants_climb(s):
            # bounced off the ground during a touchdown: keep level and keep spooling down, no steering
            self._spool_down(s, dt_s)
            return self._level(s, GRAVITY_M_S2 * max(self._lift_share, MIN_LIFT_FRACTION))
        self._lift_share = 1.0

        # velocity -> acceleration (NED): the target is slewed at bounded acceleration (a step becomes a
        # ramp the vehicle can follow, as PX4 does), then PI on the slewed reference plus its acceleration
        ff = self._slew_reference(self._velocity_target(s), s, dt_s)
        ref = self._v_ref
        errors = (ref[0] - s.vn_m_s, ref[1] - s.ve_m_s, ref[2] - s.vd_m_s)
        kp = (g.velocity_kp_horizontal_per_s, g.velocity_kp_horizontal_per_s, g.velocity_kp_vertical_per_s)
        ki = (g.velocity_ki_horizontal_per_s2, g.velocity_ki_horizontal_per_s2, g.velocity_ki_vertical_per_s2)
        ffw = (g.velocity_feedforward_horizontal, g.velocity_feedforward_horizontal, g.velocity_feedforward_vertical)
        acc = [ffw[axis] * ff[axis] + kp[axis] * errors[axis] + self._i_vel[axis] for axis in range(3)]

        # acceleration -> roll/pitch targets and collective thrust
        lift_m_s2 = max(GRAVITY_M_S2 - acc[2], MIN_LIFT_FRACTION * GRAVITY_M_S2)
        cy, sy = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
        a_fwd = cy * acc[0] + sy * acc[1]
        a_right = -sy * acc[0] + cy * acc[1]
        tilt_deg = g.limits_tilt_deg
        if height_m < g.landing_near_ground_m and not self.wants_climb(s):
            tilt_deg = min(tilt_deg, g.landing_tilt_limit_deg)
        a_max = lift_m_s2 * math.tan(math.radians(tilt_deg))
        a_norm = math.hypot(a_fwd, a_right)
        tilt_saturated = a_norm > a_max
        if tilt_saturated:
            a_fwd, a_right = a_fwd * a_max / a_norm, a_right * a_max / a_norm
        self._integrate(errors, ki, dt_s, tilt_saturated)
        pitch_t = -math.atan2(a_fwd, lift_m_s2)
        roll_t = math.atan2(a_right * math.cos(pitch_t), lift_m_s2)
        return self._attitude(s, dt_s, roll_t, pitch_t, lift_m_s2)

    def _integrate(self, errors: tuple[float, float, float], ki: tuple[float, float, float], dt_s: float,
                   tilt_saturated: bool) -> None:
        """Velocity integrators with anti-windup, as real controllers limit theirs.

        Each is clamped (IMAX). Horizontally they do not grow while the tilt is saturated (the vehicle cannot
        act on more) nor while the error is large (it is not tracking: pushed against a wall, held by a
        table): then they may only shrink. So 40 s against a wall leaves nothing to unwind.
        """
        g = self.gains
        vertical = self._i_vel[2] + ki[2] * errors[2] * dt_s
        self._i_vel[2] = _clamp(vertical, g.velocity_integral_limit_vertical_m_s2)
        tracking = math.hypot(errors[0], errors[1]) < g.velocity_integrate_below_error_m_s
        for axis in (0, 1):
            grown = _clamp(self._i_vel[axis] + ki[axis] * errors[axis] * dt_s, g.velocity_integral_limit_horizontal_m_s2)
            if (tracking and not tilt_saturated) or abs(grown) < abs(self._i_vel[axis]):
                self._i_vel[axis] = grown

    def _spool_down(self, s: FdmSample, dt_s: float) -> bool:
        """Lower the touchdown collective; tilted (rocking on a foot), take back enough to level first.

        Returns whether the vehicle is level.
        """
        g = self.gains
        level = math.cos(s.roll_rad) * math.cos(s.pitch_rad) >= math.cos(math.radians(g.landing_level_within_deg))
        if level:
            self._lift_share = max(0.0, self._lift_share - g.landing_spool_down_per_s * dt_s)
        else:
            self._lift_share = max(self._lift_share, g.landing_tilted_lift_share)
        return level

    def _level(self, s: FdmSample, lift_m_s2: float) -> list[float]:
        """Hold level and the current heading with this much lift (touchdown): no steering."""
        return self._attitude(s, 0.0, 0.0, 0.0, lift_m_s2)

    def _attitude(self, s: FdmSample, dt_s: float, roll_t: float, pitch_t: float, lift_m_s2: float) -> list[float]:
        """Roll/pitch targets and lift -> throttles (attitude P, rate P, yaw-rate PI, mixer)."""
        g = self.gains
        tilt_cos = max(math.cos(s.roll_rad) * math.cos(s.pitch_rad), MIN_TILT_COSINE)
        thrust_n = self.mass_kg * lift_m_s2 / tilt_cos

        # attitude -> Euler rates -> body rates
        roll_rate_t = g.attitude_kp_roll_pitch_per_s * (roll_t - s.roll_rad)
        pitch_rate_t = g.attitude_kp_roll_pitch_per_s * (pitch_t - s.pitch_rad)
        yaw_rate_t = self._yaw_rate_target(s)
        sphi, cphi = math.sin(s.roll_rad), math.cos(s.roll_rad)
        sth, cth = math.sin(s.pitch_rad), math.cos(s.pitch_rad)
        p_t = roll_rate_t - sth * yaw_rate_t
        q_t = cphi * pitch_rate_t + sphi * cth * yaw_rate_t
        r_t = -sphi * pitch_rate_t + cphi * cth * yaw_rate_t

        # rates -> torques
        ixx, iyy, izz = self.inertia_kg_m2
        torque_l = ixx * g.rate_kp_roll_pitch_per_s * (p_t - s.p_rad_s)
        torque_m = iyy * g.rate_kp_roll_pitch_per_s * (q_t - s.q_rad_s)
        r_error = r_t - s.r_rad_s
        self._i_yaw_rate = _clamp(self._i_yaw_rate + g.rate_ki_yaw_per_s2 * r_error * dt_s, 5.0)
        torque_n = izz * (g.rate_kp_yaw_per_s * r_error + self._i_yaw_rate)
        return self._mix(thrust_n, torque_l, torque_m, torque_n)

    def _slew_reference(self, vt: tuple[float, float, float], s: FdmSample, dt_s: float) -> tuple[float, ...]:
        """Move the velocity reference toward ``vt`` at bounded acceleration; return that acceleration."""
        g = self.gains
        ref = self._v_ref
        if ref is None:  # (re)starting: begin from what the vehicle is doing
            ref = self._v_ref = [s.vn_m_s, s.ve_m_s, s.vd_m_s]
        dn, de, dd = vt[0] - ref[0], vt[1] - ref[1], vt[2] - ref[2]
        step_h = g.velocity_accel_limit_horizontal_m_s2 * dt_s
        norm_h = math.hypot(dn, de)
        if norm_h > step_h:
            dn, de = dn * step_h / norm_h, de * step_h / norm_h
        dd = _clamp(dd, g.velocity_accel_limit_vertical_m_s2 * dt_s)
        ref[0] += dn
        ref[1] += de
        ref[2] += dd
        return dn / dt_s, de / dt_s, dd / dt_s

    def _yaw_rate_target(self, s: FdmSample) -> float:
        g = self.gains
        t = self._target
        limit = math.radians(g.limits_yaw_rate_deg_s)
        if t.yaw_rad is not None:
            return _clamp(g.attitude_kp_yaw_per_s * wrap_pi(t.yaw_rad - s.yaw_rad), limit)
        if t.yaw_rate_rad_s is not None:
            self._hold_yaw_rad = s.yaw_rad
            return t.yaw_rate_rad_s
        return _clamp(g.attitude_kp_yaw_per_s * wrap_pi(self._hold_yaw_rad - s.yaw_rad), limit)

    def _mix(self, thrust_n: float, torque_l: float, torque_m: float, torque_n: float) -> list[float]:
        g = self.gains
        mean_n = thrust_n / 4.0
        roll_n = torque_l / (4.0 * g.mixer_arm_length_m)
        pitch_n = torque_m / (4.0 * g.mixer_arm_length_m)
        yaw_n = _clamp(torque_n / (4.0 * g.mixer_torque_per_thrust_m), YAW_TORQUE_SHARE * mean_n)
        per_motor_n = (
            mean_n - roll_n + pitch_n + yaw_n,   # front-right, sense +1
            mean_n + roll_n - pitch_n + yaw_n,   # aft-left,    sense +1
            mean_n + roll_n + pitch_n - yaw_n,   # front-left,  sense -1
            mean_n - roll_n - pitch_n - yaw_n,   # aft-right,   sense -1
        )
        k = self.thrust_per_throttle2_n
        return [math.sqrt(t / k) if t > 0.0 else 0.0 for t in per_motor_n]
