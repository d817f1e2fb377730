"""An inclusion fence that stops the vehicle before it, like ArduCopter's fence avoidance (AC_Avoid).

Altitude ceiling, a circle around home and a box (the room's walls, as a polygon fence would be):
each outward velocity component is limited to what can still be braked to zero before the boundary
minus the margin. Nothing here knows about MAVLink; the personality fills it from its parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Fence", "FENCE_BRAKE_ACCEL_M_S2"]

#: Deceleration assumed when stopping before a fence (AC_Avoid uses the position controller's accel).
FENCE_BRAKE_ACCEL_M_S2 = 1.5


@dataclass
class Fence:
    """Inclusion fence (NED metres from home): stop before it, like ArduCopter's fence avoidance."""

    enabled: bool = False
    margin_m: float = 0.5
    alt_max_m: float | None = None
    radius_m: float | None = None
    box_ned_m: tuple[float, float, float, float] | None = None   # north_min, north_max, east_min, east_max

    def limit(self, pos: tuple[float, float, float], vel: list[float]) -> bool:
        """Reduce the outward components of ``vel`` (in place) so the vehicle stops inside. True if changed."""
        if not self.enabled:
            return False
        changed = False

        def cap(component: int, distance_m: float, outward_sign: float) -> None:
            nonlocal changed
            allowed = math.sqrt(2.0 * FENCE_BRAKE_ACCEL_M_S2 * max(0.0, distance_m - self.margin_m))
            if vel[component] * outward_sign > allowed:
                vel[component] = outward_sign * allowed
                changed = True

        if self.alt_max_m is not None:
            cap(2, self.alt_max_m - (-pos[2]), -1.0)
        if self.box_ned_m is not None:
            n_min, n_max, e_min, e_max = self.box_ned_m
            cap(0, n_max - pos[0], 1.0)
            cap(0, pos[0] - n_min, -1.0)
            cap(1, e_max - pos[1], 1.0)
            cap(1, pos[1] - e_min, -1.0)
        if self.radius_m is not None:
            dist = math.hypot(pos[0], pos[1])
            if dist > 1e-6:
                ux, uy = pos[0] / dist, pos[1] / dist
                outward = vel[0] * ux + vel[1] * uy
                allowed = math.sqrt(2.0 * FENCE_BRAKE_ACCEL_M_S2 * max(0.0, self.radius_m - dist - self.margin_m))
                if outward > allowed:
                    vel[0] -= (outward - allowed) * ux
                    vel[1] -= (outward - allowed) * uy
                    changed = True
        return changed
