"""Command-line flags for the link and the mapper's settings, shared by every command that flies.

``--udp PORT`` (listen like a ground station) or ``--connect STRING`` (any pymavlink connection string);
``--config FILE`` (a TOML file over the packaged settings), then single-setting flags over that. Each
setting flag is checked against the setting's range (packaged ``[limits]``) while the flags are parsed,
its help states the range, and a mistake names the flag, not the setting behind it.
"""

from __future__ import annotations

import argparse

from gcs_voice.link.connection import parse_connection, udp_listen
from gcs_voice.settings import Settings, load_settings, setting_limits

__all__ = ["add_link_arguments", "add_setting_arguments", "setting_overrides", "setting_flag_names",
           "setting_type", "range_help", "connection_from_args", "settings_from_args", "DEFAULT_UDP_PORT"]

DEFAULT_UDP_PORT = 14550
#: flag -> (setting, help)
_SETTING_FLAGS: dict[str, tuple[str, str]] = {
    "--speed": ("horizontal_speed_m_s", "horizontal speed of go_*"),
    "--vertical-speed": ("vertical_speed_m_s", "speed of up/down"),
    "--floor": ("floor_m", "'down' stops by itself this high above home, or above what a downward "
                           "rangefinder sees (a table), whichever is nearer"),
    "--ceiling": ("ceiling_m", "never climb above this height above home"),
    "--fence": ("fence_radius_m", "never move further than this from home"),
    "--takeoff-alt": ("takeoff_altitude_m", "take_off climbs to this height above home"),
    "--gcs-system-id": ("gcs_system_id", "our MAVLink system id (default 255: what ArduPilot's MAV_GCS_SYSID "
                                         "counts as its ground station)"),
    "--gcs-component-id": ("gcs_component_id", "our MAVLink component id (default 231; QGroundControl and "
                                               "Mission Planner are 190, MAVProxy 230)"),
}


def add_link_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("vehicle link")
    where = group.add_mutually_exclusive_group()
    where.add_argument("--udp", metavar="PORT", help=f"listen for the vehicle on UDP PORT, like a ground station "
                                                     f"(default {DEFAULT_UDP_PORT})")
    where.add_argument("--connect", metavar="STRING",
                       help="pymavlink connection string: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
                            "tcpin:HOST:PORT, or a serial device[,baud] such as /dev/ttyUSB0,57600")
    group.add_argument("--config", metavar="FILE", help="TOML settings file over the packaged defaults")
    group.add_argument("--tlog", metavar="FILE", help="record every packet sent and received to this .tlog")
    from gcs_voice.link.security import add_security_arguments

    add_security_arguments(group)
    add_setting_arguments(group)


def setting_type(setting: str):
    """An argparse ``type`` that reads a number within ``setting``'s range (argparse names the flag)."""
    limit = setting_limits().get(setting)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if limit is not None and not limit.low <= value <= limit.high:  # NaN fails this too
            raise argparse.ArgumentTypeError(f"{text} is outside the allowed {limit.describe()}")
        return value

    parse.__name__ = setting  # argparse's fallback message says "invalid <name> value"
    return parse


def range_help(setting: str) -> str:
    """`` (0.05-2 m/s)`` for a help text: the range the flag accepts."""
    limit = setting_limits().get(setting)
    return f" ({limit.describe()})" if limit is not None else ""


def add_setting_arguments(group: argparse._ActionsContainer) -> None:
    """One flag per flight setting (``--speed``, ``--floor``...), applied over ``--config`` and the defaults."""
    for flag, (setting, text) in _SETTING_FLAGS.items():
        group.add_argument(flag, type=setting_type(setting), metavar="N", help=text + range_help(setting))


def setting_overrides(args: argparse.Namespace) -> dict[str, float | None]:
    """Settings named by the single-setting flags (None where the flag was not given)."""
    return {setting: getattr(args, flag.lstrip("-").replace("-", "_"), None)
            for flag, (setting, _text) in _SETTING_FLAGS.items()}


def setting_flag_names() -> dict[str, str]:
    """Setting -> its flag, so that errors about a value name what the user typed."""
    return {setting: flag for flag, (setting, _text) in _SETTING_FLAGS.items()}


def connection_from_args(args: argparse.Namespace) -> str:
    """The connection string the flags ask for (checked; LinkError names the mistake)."""
    if getattr(args, "connect", None):
        return str(parse_connection(args.connect))
    port = getattr(args, "udp", None)
    return udp_listen(DEFAULT_UDP_PORT if port is None else port)


def settings_from_args(args: argparse.Namespace) -> Settings:
    return load_settings(getattr(args, "config", None), names=setting_flag_names(), **setting_overrides(args))

