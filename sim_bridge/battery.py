"""The flight battery: charge used while the motors run, and what SYS_STATUS / BATTERY_STATUS report.

Linear in charge (``battery.toml``): enough for a ground station to see the battery drain and the autopilot's
low-battery warning, not a cell model. Capacity is the personality's parameter, read at each step.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["BatterySpec", "Battery", "load_battery_spec"]

SPEC_PATH = Path(__file__).resolve().parent / "data" / "battery.toml"


@dataclass(frozen=True)
class BatterySpec:
    cells: int = 3
    full_cell_v: float = 4.2
    empty_cell_v: float = 3.5
    idle_current_a: float = 0.3
    flying_current_a: float = 12.0
    low_pct: float = 20.0


def load_battery_spec(path: Path = SPEC_PATH) -> BatterySpec:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    return BatterySpec(int(data["cells"]), float(data["full_cell_v"]), float(data["empty_cell_v"]),
                       float(data["idle_current_a"]), float(data["flying_current_a"]), float(data["low_pct"]))


@dataclass
class Battery:
    spec: BatterySpec = field(default_factory=load_battery_spec)
    consumed_mah: float = 0.0
    current_a: float = 0.0
    _last_s: float | None = None

    def step(self, now_s: float, armed: bool) -> None:
        """Draw the current of this moment since the last step (simulated seconds)."""
        self.current_a = self.spec.flying_current_a if armed else self.spec.idle_current_a
        if self._last_s is not None and now_s > self._last_s:
            self.consumed_mah += self.current_a * (now_s - self._last_s) * 1000.0 / 3600.0
        self._last_s = now_s

    def remaining_pct(self, capacity_mah: float) -> int:
        """0-100; 100 when the capacity is unknown (<= 0), as an autopilot without one reports no drain."""
        if capacity_mah <= 0:
            return 100
        return int(max(0.0, min(100.0, 100.0 * (1.0 - self.consumed_mah / capacity_mah))))

    def cell_mv(self, capacity_mah: float) -> int:
        s = self.spec
        return int(round(1000 * (s.empty_cell_v + (s.full_cell_v - s.empty_cell_v) * self.remaining_pct(capacity_mah)
                                 / 100.0)))

    def voltage_mv(self, capacity_mah: float) -> int:
        return self.cell_mv(capacity_mah) * self.spec.cells
