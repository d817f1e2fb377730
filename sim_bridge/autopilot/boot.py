"""A realistic cold start (``gcs-sim --cold-start``): the boot timeline of the real autopilot, scaled.

The timeline is data (``[cold_start]`` in ``sim_bridge/data/autopilot_<name>.toml``), taken from the
captures in ../shared/tlogs: when initialisation ends, when the EKF is aligned, has an origin and uses
GPS; which STATUSTEXTs come when; which "Arm: ..." refusals each phase gives. Times are seconds from
power-on at real speed; ``scale`` multiplies them (0.1: ArduCopter has a position after 4.1 s instead of
41 s) so tests can fly the same sequence quickly. Without ``--cold-start`` nothing here is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["ColdBoot", "BootError"]


class BootError(ValueError):
    """The [cold_start] table is malformed (a packaging bug, said in one line)."""


@dataclass
class _Refusal:
    until_s: float
    all_modes: bool
    texts: tuple[str, ...]


@dataclass
class ColdBoot:
    """Where the boot is at a given simulated time; ``texts_due`` hands out the boot texts once each."""

    scale: float
    init_end_s: float
    position_s: float
    mode_resets_s: tuple[float, ...]
    prearm_report_s: float
    prearm_text: str
    velocity_only_sink_m_s: float
    _texts: list[tuple[float, str]] = field(default_factory=list)
    _refusals: list[_Refusal] = field(default_factory=list)
    _ekf_flags: list[tuple[float, int]] = field(default_factory=list)

    @classmethod
    def from_data(cls, data: dict, scale: float) -> "ColdBoot":
        if not (math.isfinite(scale) and scale > 0):
            raise BootError(f"boot scale must be a positive number, got {scale!r}")
        try:
            s = float(scale)
            boot = cls(
                scale=s,
                init_end_s=float(data["init_end_s"]) * s,
                position_s=float(data.get("position_s", data["init_end_s"])) * s,
                mode_resets_s=tuple(float(t) * s for t in data.get("mode_resets_s", [])),
                prearm_report_s=float(data.get("prearm_report_s", 0.0)) * s,
                prearm_text=str(data.get("prearm_text", "")),
                velocity_only_sink_m_s=float(data.get("velocity_only_sink_m_s", 0.0)),
            )
            boot._texts = sorted((float(t) * s, str(text)) for t, text in data.get("texts", []))
            boot._refusals = [_Refusal(float(r["until_s"]) * s, bool(r.get("all_modes", True)), tuple(r["texts"]))
                              for r in data.get("refusals", [])]
            boot._ekf_flags = sorted((float(t) * s, int(flags)) for t, flags in data.get("ekf_flags", []))
        except (KeyError, TypeError, ValueError) as exc:
            raise BootError(f"[cold_start] table: {exc}") from None
        return boot

    def texts_due(self, now_s: float) -> list[str]:
        """Boot STATUSTEXTs whose time has come (each returned once)."""
        due = [text for t, text in self._texts if t <= now_s]
        self._texts = [(t, text) for t, text in self._texts if t > now_s]
        return due

    def has_position(self, now_s: float) -> bool:
        """The EKF has a horizontal position (ArduCopter: "EKF3 IMU0 is using GPS")."""
        return now_s >= self.position_s

    def ekf_flags(self, now_s: float) -> int | None:
        """EKF_STATUS_REPORT.flags now, or None when the timeline has none (PX4)."""
        flags = None
        for t, value in self._ekf_flags:
            if t <= now_s:
                flags = value
        return flags

    def arm_refusals(self, now_s: float, needs_position: bool) -> tuple[str, ...]:
        """The "Arm: ..." texts an ARM gets now (empty: the checks pass) in a mode that needs a position or not."""
        for refusal in self._refusals:
            if now_s < refusal.until_s and (refusal.all_modes or needs_position):
                return refusal.texts
        return ()
