"""Collisions, from what the vehicle says: SITL's "SIM Hit sofa at 1.20 m/s" and "SIM Hit ground at ...".

ArduPilot SITL (and the bundled simulator in its ArduPilot personality) says "SIM Hit ground" at every
touchdown, a normal landing included (../shared/tlogs/README.md: "SIM Hit ground at 0.496600 m/s" after
NAV_LAND). So a hit on the ground is a collision only when nobody was landing (no ``land`` since the
last take-off and the vehicle not in a landing mode) or when it came faster than ``hard_landing_m_s``.
Any other obstacle is always a collision. ``CollisionWatch`` is a bus subscriber that says each one as
a ``collision`` event when it happens, so the live view, the log and the summaries all see it.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from gcs_voice.session.events import Event, EventBus

__all__ = ["Hit", "parse_hit", "CollisionWatch", "collisions_in"]

_HIT = re.compile(r"^(?:SIM )?Hit (?P<what>.+?)(?: at (?P<speed>[-+0-9.eE]+) m/s)?\s*$")
#: a mode whose name holds one of these is the autopilot landing by itself (LAND, RTL, AUTO.RTL...)
_LANDING_MODE_WORDS = ("LAND", "RTL")


@dataclass(frozen=True)
class Hit:
    """What the vehicle hit, and how fast (None when the text does not say)."""

    obstacle: str
    speed_m_s: float | None


def parse_hit(text: str) -> Hit | None:
    """The hit in a STATUSTEXT ("SIM Hit sofa at 1.20 m/s", "Hit ground"), or None for any other text."""
    match = _HIT.match(text.strip())
    if match is None:
        return None
    try:
        speed = float(match["speed"]) if match["speed"] else None
    except ValueError:
        speed = None
    return Hit(match["what"].strip(), speed)


class CollisionWatch:
    """Subscribe to a session's bus: turns the vehicle's hit texts into ``collision`` events."""

    def __init__(self, bus: EventBus, hard_landing_m_s: float, mode: Callable[[], str | None] = lambda: None) -> None:
        self.bus = bus
        self.hard_landing_m_s = hard_landing_m_s
        self.mode = mode
        self.landing = False  # a land was commanded since the last take-off
        self.count = 0

    def __call__(self, event: Event) -> None:
        if event.kind == "command" and event.data.get("action") in ("land", "take_off"):
            self.landing = event.data["action"] == "land"
            return
        if event.kind != "vehicle":
            return
        hit = parse_hit(str(event.data.get("text", "")))
        if hit is None:
            return
        if hit.obstacle.lower() == "ground":
            mode = (self.mode() or "").upper()
            landing = self.landing or any(word in mode for word in _LANDING_MODE_WORDS)
            if landing and (hit.speed_m_s is None or hit.speed_m_s <= self.hard_landing_m_s):
                return  # a touchdown
        self.count += 1
        speed = f" at {hit.speed_m_s:.2f} m/s" if hit.speed_m_s is not None else ""
        self.bus.emit("collision", f"COLLISION: the vehicle hit {hit.obstacle}{speed}", obstacle=hit.obstacle,
                      speed_m_s=hit.speed_m_s, text=event.data.get("text"))


def collisions_in(events: list[dict]) -> list[dict]:
    """The ``collision`` records of a session (events as dicts, e.g. ``SessionResult.events``)."""
    return [e for e in events if e.get("kind") == "collision"]
