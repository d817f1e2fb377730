"""A small, real autopilot parameter set, loaded from ``data/params_<autopilot>.toml``.

Why a store and not a dict: the MAVLink parameter protocol needs a stable index per name, a
``param_count`` that never changes, the MAV_PARAM_TYPE of each value and the autopilot's way of
putting integers into PARAM_VALUE's float field (ArduPilot casts, PX4 copies the bytes).
"""

from __future__ import annotations

import math
import struct
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["Param", "ParamStore", "ParamsError", "load_params"]

#: MAV_PARAM_TYPE by the short names used in the data files.
PARAM_TYPES: dict[str, int] = {
    "UINT8": mavlink.MAV_PARAM_TYPE_UINT8,
    "INT8": mavlink.MAV_PARAM_TYPE_INT8,
    "UINT16": mavlink.MAV_PARAM_TYPE_UINT16,
    "INT16": mavlink.MAV_PARAM_TYPE_INT16,
    "UINT32": mavlink.MAV_PARAM_TYPE_UINT32,
    "INT32": mavlink.MAV_PARAM_TYPE_INT32,
    "REAL32": mavlink.MAV_PARAM_TYPE_REAL32,
}
_INT_RANGES: dict[int, tuple[int, int]] = {
    mavlink.MAV_PARAM_TYPE_UINT8: (0, 255),
    mavlink.MAV_PARAM_TYPE_INT8: (-128, 127),
    mavlink.MAV_PARAM_TYPE_UINT16: (0, 65535),
    mavlink.MAV_PARAM_TYPE_INT16: (-32768, 32767),
    mavlink.MAV_PARAM_TYPE_UINT32: (0, 2**32 - 1),
    mavlink.MAV_PARAM_TYPE_INT32: (-(2**31), 2**31 - 1),
}
_STRUCT_FOR_TYPE = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B", mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H", mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I", mavlink.MAV_PARAM_TYPE_INT32: "<i",
}


class ParamsError(ValueError):
    """A parameter file is missing or malformed (the message names the file and the entry)."""


@dataclass
class Param:
    name: str
    value: float
    mav_type: int
    doc: str

    @property
    def is_integer(self) -> bool:
        return self.mav_type != mavlink.MAV_PARAM_TYPE_REAL32


class ParamStore:
    """Ordered parameters with MAVLink encoding; ``bytewise`` is PX4's integer encoding."""

    def __init__(self, params: list[Param], bytewise: bool) -> None:
        self._params = params
        self._index = {p.name: i for i, p in enumerate(params)}
        self.bytewise = bytewise
        self._listeners: list[Callable[[str, float], None]] = []

    def __len__(self) -> int:
        return len(self._params)

    def __contains__(self, name: str) -> bool:
        return name in self._index

    def names(self) -> list[str]:
        return [p.name for p in self._params]

    def get(self, name: str) -> float:
        return self._params[self._index[name]].value

    def param(self, name: str) -> Param:
        return self._params[self._index[name]]

    def at(self, index: int) -> Param | None:
        return self._params[index] if 0 <= index < len(self._params) else None

    def index_of(self, name: str) -> int:
        return self._index.get(name, -1)

    def on_change(self, listener: Callable[[str, float], None]) -> None:
        """Call ``listener(name, value)`` after every successful set (stream rates, limits)."""
        self._listeners.append(listener)

    def set(self, name: str, value: float) -> bool:
        """Set by value (already decoded); integers are rounded and range-checked. False if refused."""
        index = self._index.get(name)
        if index is None or not math.isfinite(value):
            return False
        param = self._params[index]
        if param.is_integer:
            low, high = _INT_RANGES[param.mav_type]
            value = float(round(value))
            if not low <= value <= high:
                return False
        param.value = float(value)
        for listener in self._listeners:
            listener(name, param.value)
        return True

    def encode(self, param: Param) -> float:
        """The float that goes into PARAM_VALUE.param_value."""
        if param.is_integer and self.bytewise:
            raw = struct.pack(_STRUCT_FOR_TYPE[param.mav_type], int(param.value)).ljust(4, b"\0")
            return struct.unpack("<f", raw)[0]
        return float(param.value)

    def decode(self, wire_value: float, mav_type: int, name: str) -> float:
        """The value a PARAM_SET means. PX4 (bytewise) reads the four bytes as the parameter's own type, as
        its param_set does, whatever type the message declares: a float NaN declared INT8 must not become 0."""
        param = self.param(name)
        mav_type = param.mav_type
        if self.bytewise and mav_type in _STRUCT_FOR_TYPE:
            raw = struct.pack("<f", wire_value)
            size = struct.calcsize(_STRUCT_FOR_TYPE[mav_type])
            return float(struct.unpack(_STRUCT_FOR_TYPE[mav_type], raw[:size])[0])
        return float(wire_value)


def _load_file(path: Path | None, autopilot: str) -> tuple[str, dict]:
    if path is None:
        ref = resources.files("sim_bridge").joinpath("data", f"params_{autopilot}.toml")
        label = f"params_{autopilot}.toml"
        try:
            text = ref.read_text(encoding="utf-8")
        except FileNotFoundError as exc:
            raise ParamsError(f"no parameter set for autopilot {autopilot!r}") from exc
    else:
        label = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ParamsError(f"{label}: cannot read: {exc.strerror}") from exc
    try:
        return label, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParamsError(f"{label}: invalid TOML: {exc}") from exc


def load_params(autopilot: str, path: Path | None = None) -> ParamStore:
    """Load the parameter set of ``autopilot`` (``ardupilot`` or ``px4``) from package data."""
    label, data = _load_file(path, autopilot)
    encoding = data.get("encoding", "cast")
    if encoding not in ("cast", "bytewise"):
        raise ParamsError(f"{label}: encoding must be 'cast' or 'bytewise', not {encoding!r}")
    table = data.get("params")
    if not isinstance(table, dict) or not table:
        raise ParamsError(f"{label}: needs a non-empty [params] table")
    params = []
    for name, entry in table.items():
        if len(name) > 16:
            raise ParamsError(f"{label}: {name}: names are at most 16 characters")
        if not isinstance(entry, dict) or "value" not in entry or entry.get("type") not in PARAM_TYPES:
            raise ParamsError(f"{label}: {name}: needs value and type (one of {', '.join(PARAM_TYPES)})")
        params.append(Param(name, float(entry["value"]), PARAM_TYPES[entry["type"]], str(entry.get("doc", ""))))
    return ParamStore(params, bytewise=encoding == "bytewise")
