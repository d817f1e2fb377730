"""Bridge settings (speeds, floor, fence, ceiling, link rates and timeouts): data, not code.

Defaults live in ``gcs_voice/data/settings.toml``; a user TOML file with the same tables overrides
any subset, and flags override that (``overrides`` below). Unknown keys are an error that names the
file and the key, because a typo in a safety limit must not pass silently. Every value must lie in
its range from the packaged ``[limits]`` table (``--speed 1e9`` once reached 5 m/s indoors); an error
names what the user wrote: the flag (``names``) or the file and key.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from functools import cache
from pathlib import Path
from typing import Any

from gcs_voice.errors import GcsVoiceError

__all__ = ["Settings", "SettingsError", "Limit", "load_settings", "setting_limits", "check_setting",
           "DEFAULT_SETTINGS_PATH"]

DEFAULT_SETTINGS_PATH = Path(__file__).resolve().parent / "data" / "settings.toml"
#: Integer-valued settings; every other setting is a float.
_INT_KEYS = frozenset({"gcs_system_id", "gcs_component_id", "command_retries", "data_stream_hz", "return_home_lands"})


#: the packaged file's table of [low, high] per setting; user files may not hold it
LIMITS_TABLE = "limits"
_UNITS = (("_m_s", "m/s"), ("_hz", "Hz"), ("_deg", "deg"), ("_m", "m"), ("_s", "s"))


class SettingsError(GcsVoiceError):
    """A settings file is missing, malformed or holds an unknown key or an impossible value."""


@dataclass(frozen=True)
class Limit:
    """The allowed range of one setting, both ends included."""

    low: float
    high: float
    unit: str

    def describe(self) -> str:
        return f"{self.low:g}-{self.high:g}{(' ' + self.unit) if self.unit else ''}"


@dataclass(frozen=True)
class Settings:
    """Every tunable of the action mapper and the MAVLink link (units in the names)."""

    horizontal_speed_m_s: float
    vertical_speed_m_s: float
    turn_step_deg: float
    takeoff_altitude_m: float
    return_home_lands: int
    floor_m: float
    ceiling_m: float
    fence_radius_m: float
    hard_landing_m_s: float
    battery_low_pct: float
    gcs_system_id: int
    gcs_component_id: int
    heartbeat_hz: float
    setpoint_hz: float
    link_lost_s: float
    command_timeout_s: float
    command_retries: int
    ack_settle_s: float
    mode_confirm_s: float
    arm_timeout_s: float
    arm_retry_s: float
    offboard_prestream_s: float
    takeoff_timeout_s: float
    takeoff_reached_fraction: float
    local_position_ned_hz: float
    attitude_hz: float
    extended_sys_state_hz: float
    global_position_int_hz: float
    data_stream_hz: int

    def with_overrides(self, names: Mapping[str, str] | None = None, **overrides: Any) -> "Settings":
        """A copy with the given keys replaced (None values are skipped, so unset flags change nothing).

        ``names`` says how the user wrote each key (``{"fence_radius_m": "--fence"}``) for the errors."""
        clean = {k: v for k, v in overrides.items() if v is not None}
        return _validated(_coerce(clean, "overrides", names), base=self, source="overrides", names=names)


@cache
def setting_limits() -> dict[str, Limit]:
    """Setting -> its allowed range, from the packaged file's ``[limits]`` table."""
    data = tomllib.loads(DEFAULT_SETTINGS_PATH.read_text(encoding="utf-8")).get(LIMITS_TABLE, {})
    known = {f.name for f in fields(Settings)}
    limits = {}
    for key, (low, high) in data.items():
        if key not in known or not low <= high:  # a packaging mistake, caught by the tests
            raise SettingsError(f"{DEFAULT_SETTINGS_PATH}: bad limit {key} = {[low, high]}")
        limits[key] = Limit(float(low), float(high), next((u for end, u in _UNITS if key.endswith(end)), ""))
    return limits


def check_setting(key: str, value: float, name: str | None = None) -> float:
    """``value`` if it is a finite number within ``key``'s range, else SettingsError naming ``name`` (the flag)."""
    label = name or key
    if not math.isfinite(value):
        raise SettingsError(f"{label} {value!r}: must be a finite number")
    limit = setting_limits().get(key)
    if limit is None:
        if value < 0:
            raise SettingsError(f"{label} {value:g}: must be >= 0")
    elif not limit.low <= value <= limit.high:
        raise SettingsError(f"{label} {value:g}: must be within {limit.describe()}")
    return value


def _label(source: str, key: str, names: Mapping[str, str] | None) -> str:
    """How the user wrote ``key``: its flag, else ``FILE: key``."""
    if names and key in names:
        return names[key]
    return f"{source}: {key}" if source != "overrides" else key


def _coerce(values: dict[str, Any], source: str, names: Mapping[str, str] | None = None) -> dict[str, Any]:
    known = {f.name for f in fields(Settings)}
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key not in known:
            raise SettingsError(f"{source}: unknown setting {key!r}")
        label = _label(source, key, names)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SettingsError(f"{label} must be a number, got {value!r}")
        if key in _INT_KEYS:
            if not math.isfinite(value) or float(value) != int(value):
                raise SettingsError(f"{label} must be a whole number, got {value!r}")
            out[key] = int(value)
        else:
            out[key] = float(value)
    return out


def _validated(values: dict[str, Any], base: Settings | None, source: str,
               names: Mapping[str, str] | None = None) -> Settings:
    settings = replace(base, **values) if base is not None else Settings(**values)
    for key in values:
        check_setting(key, getattr(settings, key), _label(source, key, names))
    for f in fields(Settings):  # keys set elsewhere were checked where they were set
        if not math.isfinite(getattr(settings, f.name)) or getattr(settings, f.name) < 0:
            check_setting(f.name, getattr(settings, f.name), _label(source, f.name, names))

    def said(key: str) -> str:
        if key in values and names and key in names:
            return f"{names[key]} ({getattr(settings, key):g})"
        hint = f"; {names[key]} sets it" if names and key in names else ""
        return f"{key} ({getattr(settings, key):g}{hint})"

    if settings.floor_m >= settings.ceiling_m:
        raise SettingsError(f"{source + ': ' if not names else ''}{said('floor_m')} must be below {said('ceiling_m')}")
    if settings.takeoff_altitude_m > settings.ceiling_m:
        raise SettingsError(f"{source + ': ' if not names else ''}{said('takeoff_altitude_m')} must not be above "
                            f"{said('ceiling_m')}")
    return settings


def _read_tables(path: Path, packaged: bool = False) -> dict[str, Any]:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SettingsError(f"{path}: settings file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SettingsError(f"{path}: cannot read settings file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SettingsError(f"{path}: invalid TOML ({exc})") from None
    flat: dict[str, Any] = {}
    for table, values in data.items():
        if table == LIMITS_TABLE:
            if not packaged:
                raise SettingsError(f"{path}: [{LIMITS_TABLE}] can only be changed in the packaged settings "
                                    f"({DEFAULT_SETTINGS_PATH.name})")
            continue
        if not isinstance(values, dict):
            raise SettingsError(f"{path}: {table!r} must be a table like [motion], [safety], [link], [telemetry]")
        flat.update(values)
    return _coerce(flat, str(path))


def load_settings(path: str | Path | None = None, names: Mapping[str, str] | None = None,
                  **overrides: Any) -> Settings:
    """Defaults, then the user file ``path`` (any subset of keys), then keyword ``overrides``
    (``names``: how the user wrote them, e.g. their flags, for the errors)."""
    settings = _validated(_read_tables(DEFAULT_SETTINGS_PATH, packaged=True), base=None,
                          source=str(DEFAULT_SETTINGS_PATH))
    if path is not None:
        settings = _validated(_read_tables(Path(path)), base=settings, source=str(path))
    return settings.with_overrides(names, **overrides) if overrides else settings
