"""Autopilot personalities: how the simulated vehicle behaves on the wire (ArduCopter or PX4)."""

from __future__ import annotations

from sim_bridge.autopilot.base import Autopilot

__all__ = ["Autopilot", "PERSONALITIES", "personality_class"]

#: --autopilot NAME -> class; imported on use.
PERSONALITIES = {"ardupilot": ("sim_bridge.autopilot.ardupilot", "ArduCopter"), "px4": ("sim_bridge.autopilot.px4", "PX4")}


def personality_class(name: str) -> type[Autopilot]:
    import importlib

    module_name, class_name = PERSONALITIES[name]
    return getattr(importlib.import_module(module_name), class_name)
