"""Bridge settings (speeds, floor, fence, ceiling, link rates and timeouts): data, not code.

Defaults live in ``gcs_voice/data/settings.toml``; a user TOML file with the same tables overrides
any subset, and flags override that (``overrides`` below). Unknown keys are an error that names the
file and the key, because a typo in a safety limit must not pass silently.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from gcs_voice.errors import GcsVoiceError

__all__ = ["Settings", "SettingsError", "load_settings", "DEFAULT_SETTINGS_PATH"]

DEFAULT_SETTINGS_PATH = Path(__file__).resolve().parent / "data" / "settings.toml"
#: Integer-valued settings; every other setting is a float.
_INT_KEYS = frozenset({"gcs_system_id", "gcs_component_id", "command_retries", "data_stream_hz"})


class SettingsError(GcsVoiceError):
    """A settings file is missing, malformed or holds an unknown key or an impossible value."""


@dataclass(frozen=True)
class Settings:
    """Every tunable of the action mapper and the MAVLink link (units in the names)."""

    horizontal_speed_m_s: float
    vertical_speed_m_s: float
    turn_step_deg: float
    takeoff_altitude_m: float
    floor_m: float
    ceiling_m: float
    fence_radius_m: float
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

    def with_overrides(self, **overrides: Any) -> "Settings":
        """A copy with the given keys replaced (None values are skipped, so unset flags change nothing)."""
        clean = {k: v for k, v in overrides.items() if v is not None}
        return _validated(_coerce(clean, "overrides"), base=self, source="overrides")


def _coerce(values: dict[str, Any], source: str) -> dict[str, Any]:
    known = {f.name for f in fields(Settings)}
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key not in known:
            raise SettingsError(f"{source}: unknown setting {key!r}")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SettingsError(f"{source}: setting {key!r} must be a number, got {value!r}")
        if key in _INT_KEYS:
            if float(value) != int(value):
                raise SettingsError(f"{source}: setting {key!r} must be a whole number, got {value!r}")
            out[key] = int(value)
        else:
            out[key] = float(value)
    return out


def _validated(values: dict[str, Any], base: Settings | None, source: str) -> Settings:
    settings = replace(base, **values) if base is not None else Settings(**values)
    for f in fields(Settings):
        value = getattr(settings, f.name)
        if not math.isfinite(value) or value < 0:
            raise SettingsError(f"{source}: setting {f.name!r} must be a finite number >= 0, got {value!r}")
    positive = ("setpoint_hz", "heartbeat_hz", "link_lost_s", "command_timeout_s", "horizontal_speed_m_s",
                "vertical_speed_m_s", "ceiling_m", "fence_radius_m")
    for name in positive:
        if getattr(settings, name) <= 0:
            raise SettingsError(f"{source}: setting {name!r} must be > 0")
    if settings.floor_m >= settings.ceiling_m:
        raise SettingsError(f"{source}: floor_m ({settings.floor_m}) must be below ceiling_m ({settings.ceiling_m})")
    if not 0 < settings.takeoff_reached_fraction <= 1:
        raise SettingsError(f"{source}: takeoff_reached_fraction must be in (0, 1]")
    for name in ("gcs_system_id", "gcs_component_id"):
        if not 1 <= getattr(settings, name) <= 255:
            raise SettingsError(f"{source}: {name} must be 1..255")
    return settings


def _read_tables(path: Path) -> dict[str, Any]:
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
        if not isinstance(values, dict):
            raise SettingsError(f"{path}: {table!r} must be a table like [motion], [safety], [link], [telemetry]")
        flat.update(values)
    return _coerce(flat, str(path))


def load_settings(path: str | Path | None = None, **overrides: Any) -> Settings:
    """Defaults, then the user file ``path`` (any subset of keys), then keyword ``overrides``."""
    settings = _validated(_read_tables(DEFAULT_SETTINGS_PATH), base=None, source=str(DEFAULT_SETTINGS_PATH))
    if path is not None:
        settings = _validated(_read_tables(Path(path)), base=settings, source=str(path))
    return settings.with_overrides(**overrides) if overrides else settings
