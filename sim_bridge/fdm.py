"""JSBSim wrapper: loads the project's quadrotor airframe quietly and converts its state to SI/NED.

Everything JSBSim-specific (property names, feet, pounds, slugs, geodetic position) stays in this module;
the controller and the room only see ``FdmSample`` (SI, NED relative to home, see ``sim_bridge.frames``).
The position reference point is the landing gear: ``down_m`` is 0 when the vehicle stands on the floor.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Iterator

import numpy as np

from sim_bridge.frames import (
    FT_TO_M, GRAVITY_M_S2, LBF_TO_N, M_TO_FT, N_TO_LBF, SLUG_FT2_TO_KG_M2,
    geodetic_to_ned_m, ned_to_geodetic, wrap_pi,
)

__all__ = ["RigidBodyState", "FdmSample", "QuadFdm", "AIRCRAFT_DIR", "AIRFRAME_NAME"]

AIRCRAFT_DIR = Path(__file__).resolve().parent / "data" / "aircraft"
AIRFRAME_NAME = "gcs_quad"
MOTOR_COUNT = 4
GEAR_HEIGHT_M = 0.1524        # CG above the gear contact points (gcs_quad.xml <ground_reactions>)
GROUND_SETTLE_S = 0.5         # let the gear springs settle after placing the vehicle on the floor
HOVER_TRIM_ALT_M = 30.0       # trim search happens this high up, clear of the ground
HOVER_TRIM_S = 4.0
HOVER_TRIM_AVERAGE_S = 1.0

_log = logging.getLogger(__name__)
_THROTTLE_PROPS = [f"fcs/throttle-cmd-norm[{i}]" for i in range(MOTOR_COUNT)]
_CONTACT_PROPS = [f"external_reactions/contact_{axis}/magnitude" for axis in ("n", "e", "d")]
FOOT_COUNT = 4                # gcs_quad.xml: contact units 0-3 are the feet, 4.. the frame (motor pods, top)
FRAME_CONTACT_COUNT = 5
_WOW_PROPS = [f"gear/unit[{i}]/WOW" for i in range(FOOT_COUNT)]
_FRAME_WOW_PROPS = [f"contact/unit[{i}]/WOW" for i in range(FOOT_COUNT, FOOT_COUNT + FRAME_CONTACT_COUNT)]


@dataclass
class RigidBodyState:
    """The vehicle as the MAVLink layer sees it. SI units, NED relative to home on the floor.

    pos_ned_m: gear position (down = 0 on the home floor); vel_ned_m_s; roll/pitch/yaw_rad (yaw in
    [-pi, pi), 0 = north, clockwise positive); roll/pitch/yaw_rate_rad_s: body rates p, q, r;
    alt_amsl_m = home_alt_m - down; throttle: mean motor command 0..1.
    """

    t_s: float = 0.0
    pos_ned_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    vel_ned_m_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    roll_rate_rad_s: float = 0.0
    pitch_rate_rad_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    on_ground: bool = True
    armed: bool = False
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_amsl_m: float = 0.0
    throttle: float = 0.0


@dataclass(slots=True)
class FdmSample:
    """One JSBSim state read as plain floats (cheap: read every physics step)."""

    north_m: float
    east_m: float
    down_m: float
    vn_m_s: float
    ve_m_s: float
    vd_m_s: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    p_rad_s: float
    q_rad_s: float
    r_rad_s: float
    gear_contacts: int
    lat_deg: float
    lon_deg: float
    frame_contacts: int = 0   # frame points (not feet) touching the ground: tipped over, or landing on an arm


def _flush_c_stdio() -> None:
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


def _quiet_logger(jsbsim: ModuleType) -> contextlib.AbstractContextManager[None]:
    """JSBSim >= 1.3 prints through a per-thread Python logger: swap in one that keeps messages at debug."""
    class _ToPythonLogging(jsbsim.FGLogger):
        def message(self, message: str) -> None:
            if message.strip():
                _log.debug("jsbsim: %s", message.strip())

    @contextlib.contextmanager
    def swapped() -> Iterator[None]:
        previous = jsbsim.get_logger()
        jsbsim.set_logger(_ToPythonLogging())
        try:
            yield
        finally:
            jsbsim.set_logger(previous)

    return swapped()


@contextlib.contextmanager
def _quiet_fds() -> Iterator[None]:
    """Silence C++ stdout/stderr (JSBSim's banner and load chatter) by redirecting fds 1 and 2."""
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no real fds (embedded interpreter): nothing to silence
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        _flush_c_stdio()  # JSBSim's std::cout is buffered by C stdio: flush it into /dev/null, not later
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


def _quiet(jsbsim: ModuleType) -> contextlib.AbstractContextManager[None]:
    """JSBSim >= 1.3: swap its logger (thread-local, harmless); older: redirect the process's fds briefly."""
    return _quiet_logger(jsbsim) if hasattr(jsbsim, "set_logger") else _quiet_fds()


class QuadFdm:
    """One JSBSim instance of ``gcs_quad`` at a fixed physics rate, driven one step at a time."""

    def __init__(self, physics_hz: float, home_lat_deg: float, home_lon_deg: float, home_alt_m: float) -> None:
        import jsbsim  # heavy: only when a simulator is built

        self.dt_s = 1.0 / physics_hz
        self.home_lat_deg = home_lat_deg
        self.home_lon_deg = home_lon_deg
        self.home_alt_m = home_alt_m
        jsbsim_root = Path(jsbsim.__file__).resolve().parent
        self._quiet = lambda: _quiet(jsbsim)
        with self._quiet():
            fdm = jsbsim.FGFDMExec(None)
            fdm.set_debug_level(0)
            ok = fdm.load_model_with_paths(
                AIRFRAME_NAME, str(AIRCRAFT_DIR), str(jsbsim_root / "engine"), str(jsbsim_root / "systems"))
        if not ok:
            raise RuntimeError(f"JSBSim could not load {AIRCRAFT_DIR / AIRFRAME_NAME}")
        fdm.set_dt(self.dt_s)
        self._fdm = fdm
        self._throttles = [0.0] * MOTOR_COUNT
        self.place((0.0, 0.0, 0.0), 0.0)  # mass and inertia properties are filled by the first run_ic
        self.mass_kg = fdm["inertia/weight-lbs"] * LBF_TO_N / GRAVITY_M_S2
        self.inertia_kg_m2 = (
            fdm["inertia/ixx-slugs_ft2"] * SLUG_FT2_TO_KG_M2,
            fdm["inertia/iyy-slugs_ft2"] * SLUG_FT2_TO_KG_M2,
            fdm["inertia/izz-slugs_ft2"] * SLUG_FT2_TO_KG_M2,
        )

    # ---- placing -------------------------------------------------------------------------------
    def place(self, pos_ned_m: tuple[float, float, float], yaw_rad: float) -> None:
        """Put the vehicle at rest at a NED position (gear reference) and heading, motors off."""
        fdm = self._fdm
        lat_deg, lon_deg = ned_to_geodetic(pos_ned_m[0], pos_ned_m[1], self.home_lat_deg, self.home_lon_deg)
        on_floor = pos_ned_m[2] >= -1e-3
        fdm["ic/lat-geod-deg"] = lat_deg
        fdm["ic/long-gc-deg"] = lon_deg
        fdm["ic/terrain-elevation-ft"] = self.home_alt_m * M_TO_FT
        fdm["ic/h-agl-ft"] = (GEAR_HEIGHT_M + max(0.0, -pos_ned_m[2])) * M_TO_FT
        for name in ("ic/u-fps", "ic/v-fps", "ic/w-fps", "ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec",
                     "ic/phi-rad", "ic/theta-rad"):
            fdm[name] = 0.0
        fdm["ic/psi-true-rad"] = wrap_pi(yaw_rad) % (2.0 * math.pi)
        self.set_throttles((0.0,) * MOTOR_COUNT)
        self.set_contact_force_ned_n(0.0, 0.0, 0.0)
        with self._quiet():
            fdm.run_ic()
        if on_floor:
            for _ in range(round(GROUND_SETTLE_S / self.dt_s)):
                fdm.run()

    # ---- stepping ------------------------------------------------------------------------------
    def set_throttles(self, throttles: tuple[float, ...] | list[float]) -> None:
        """ESC commands 0..1 (clipped), motor order front-right, aft-left, front-left, aft-right."""
        fdm = self._fdm
        for i, prop in enumerate(_THROTTLE_PROPS):
            u = throttles[i]
            u = 0.0 if not u > 0.0 else (1.0 if u > 1.0 else u)  # NaN -> 0
            self._throttles[i] = u
            fdm[prop] = u

    @property
    def mean_throttle(self) -> float:
        return sum(self._throttles) / MOTOR_COUNT

    def set_contact_force_ned_n(self, north_n: float, east_n: float, down_n: float) -> None:
        """External force at the CG in the local NED frame (newtons), held until changed."""
        fdm = self._fdm
        for prop, force_n in zip(_CONTACT_PROPS, (north_n, east_n, down_n)):
            fdm[prop] = force_n * N_TO_LBF

    def run_step(self) -> None:
        self._fdm.run()

    @property
    def sim_time_s(self) -> float:
        return self._fdm.get_sim_time()

    def sample(self) -> FdmSample:
        fdm = self._fdm
        lat_deg = fdm["position/lat-geod-deg"]
        lon_deg = fdm["position/long-gc-deg"]
        north_m, east_m = geodetic_to_ned_m(lat_deg, lon_deg, self.home_lat_deg, self.home_lon_deg)
        return FdmSample(
            north_m=north_m,
            east_m=east_m,
            down_m=GEAR_HEIGHT_M - fdm["position/h-agl-ft"] * FT_TO_M,
            vn_m_s=fdm["velocities/v-north-fps"] * FT_TO_M,
            ve_m_s=fdm["velocities/v-east-fps"] * FT_TO_M,
            vd_m_s=fdm["velocities/v-down-fps"] * FT_TO_M,
            roll_rad=fdm["attitude/phi-rad"],
            pitch_rad=fdm["attitude/theta-rad"],
            yaw_rad=wrap_pi(fdm["attitude/psi-rad"]),
            p_rad_s=fdm["velocities/p-rad_sec"],
            q_rad_s=fdm["velocities/q-rad_sec"],
            r_rad_s=fdm["velocities/r-rad_sec"],
            gear_contacts=sum(1 for prop in _WOW_PROPS if fdm[prop] > 0.5),
            lat_deg=lat_deg,
            lon_deg=lon_deg,
            frame_contacts=sum(1 for prop in _FRAME_WOW_PROPS if fdm[prop] > 0.5),
        )

    # ---- trim ----------------------------------------------------------------------------------
    def find_hover_throttle(self, initial_guess: float = 0.4) -> float:
        """Trim search: fly a vertical PI loop high above ground, return the mean throttle that holds.

        The shipped motor/propeller model decides the hover point (about 0.42 for gcs_quad); it is
        measured here rather than assumed, so an edited airframe still hovers.
        """
        self.place((0.0, 0.0, -HOVER_TRIM_ALT_M), 0.0)
        kp_per_m_s, ki_per_m = 0.15, 0.2
        integral = initial_guess
        steps = round(HOVER_TRIM_S / self.dt_s)
        average_from = steps - round(HOVER_TRIM_AVERAGE_S / self.dt_s)
        total = 0.0
        for k in range(steps):
            vd_m_s = self._fdm["velocities/v-down-fps"] * FT_TO_M
            integral += ki_per_m * vd_m_s * self.dt_s
            u = integral + kp_per_m_s * vd_m_s
            self.set_throttles((u,) * MOTOR_COUNT)
            self._fdm.run()
            if k >= average_from:
                total += self.mean_throttle
        hover = total / (steps - average_from)
        if not 0.05 < hover < 0.95:
            raise RuntimeError(f"gcs_quad cannot hover (trim throttle {hover:.2f})")
        return hover
