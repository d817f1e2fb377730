"""Units and frames at one boundary: JSBSim speaks feet, pounds and geodetic degrees; we speak SI and NED.

NED here is a local tangent plane at *home*: north, east, down in metres, origin on the floor under the
home spot. The room files use a z-up frame (x north, y east, z height above the floor), because furniture
heights read naturally that way; ``room_to_ned`` / ``ned_to_room`` are the only conversions between them.
"""

from __future__ import annotations

import math

__all__ = [
    "FT_TO_M", "M_TO_FT", "LBF_TO_N", "N_TO_LBF", "GRAVITY_M_S2",
    "WGS84_A_M", "WGS84_E2", "wrap_pi", "geodetic_to_ned_m", "ned_to_geodetic", "room_to_ned", "ned_to_room",
]

FT_TO_M = 0.3048
M_TO_FT = 1.0 / FT_TO_M
LBF_TO_N = 4.4482216152605
N_TO_LBF = 1.0 / LBF_TO_N
GRAVITY_M_S2 = 9.80665

WGS84_A_M = 6378137.0            # semi-major axis
WGS84_E2 = 6.69437999014e-3      # first eccentricity squared


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def _radii_m(lat_deg: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature at a latitude (WGS84)."""
    s = math.sin(math.radians(lat_deg))
    w = 1.0 - WGS84_E2 * s * s
    prime_m = WGS84_A_M / math.sqrt(w)
    meridian_m = WGS84_A_M * (1.0 - WGS84_E2) / (w * math.sqrt(w))
    return meridian_m, prime_m


def geodetic_to_ned_m(lat_deg: float, lon_deg: float, home_lat_deg: float, home_lon_deg: float) -> tuple[float, float]:
    """North/east metres of a point from home: flat earth with WGS84 radii (mm-accurate over a few km)."""
    meridian_m, prime_m = _radii_m(home_lat_deg)
    north_m = math.radians(lat_deg - home_lat_deg) * meridian_m
    east_m = math.radians(lon_deg - home_lon_deg) * prime_m * math.cos(math.radians(home_lat_deg))
    return north_m, east_m


def ned_to_geodetic(north_m: float, east_m: float, home_lat_deg: float, home_lon_deg: float) -> tuple[float, float]:
    """Inverse of ``geodetic_to_ned_m``: latitude and longitude in degrees."""
    meridian_m, prime_m = _radii_m(home_lat_deg)
    lat_deg = home_lat_deg + math.degrees(north_m / meridian_m)
    lon_deg = home_lon_deg + math.degrees(east_m / (prime_m * math.cos(math.radians(home_lat_deg))))
    return lat_deg, lon_deg


def room_to_ned(room_xyz_m: tuple[float, float, float], home_room_xy_m: tuple[float, float]) -> tuple[float, float, float]:
    """Room frame (x north, y east, z up from the floor) to NED relative to home on the floor."""
    x, y, z = room_xyz_m
    return (x - home_room_xy_m[0], y - home_room_xy_m[1], -z)


def ned_to_room(ned_m: tuple[float, float, float], home_room_xy_m: tuple[float, float]) -> tuple[float, float, float]:
    """NED relative to home back to the room frame."""
    n, e, d = ned_m
    return (n + home_room_xy_m[0], e + home_room_xy_m[1], -d)

SLUG_FT2_TO_KG_M2 = 1.3558179483314
__all__.append("SLUG_FT2_TO_KG_M2")
