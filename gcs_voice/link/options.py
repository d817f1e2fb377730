"""Command-line flags for the link and the mapper's settings, shared by every command that flies.

``--udp PORT`` (listen like a ground station) or ``--connect STRING`` (any pymavlink connection string);
``--config FILE`` (a TOML file over the packaged settings), then single-setting flags over that.
"""

from __future__ import annotations

import argparse

from gcs_voice.link.connection import parse_connection, udp_listen
from gcs_voice.settings import Settings, load_settings

__all__ = ["add_link_arguments", "add_setting_arguments", "setting_overrides", "connection_from_args",
           "settings_from_args", "DEFAULT_UDP_PORT"]

DEFAULT_UDP_PORT = 14550
#: flag -> (setting, help)
_SETTING_FLAGS: dict[str, tuple[str, str]] = {
    "--speed": ("horizontal_speed_m_s", "horizontal speed of go_* in m/s"),
    "--vertical-speed": ("vertical_speed_m_s", "speed of up/down in m/s"),
    "--floor": ("floor_m", "'down' stops by itself this many metres above home"),
    "--ceiling": ("ceiling_m", "never climb above this many metres above home"),
    "--fence": ("fence_radius_m", "never move further than this many metres from home"),
    "--takeoff-alt": ("takeoff_altitude_m", "take_off climbs to this many metres above home"),
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


def add_setting_arguments(group: argparse._ActionsContainer) -> None:
    """One flag per flight setting (``--speed``, ``--floor``...), applied over ``--config`` and the defaults."""
    for flag, (_setting, text) in _SETTING_FLAGS.items():
        group.add_argument(flag, type=float, metavar="N", help=text)


def setting_overrides(args: argparse.Namespace) -> dict[str, float | None]:
    """Settings named by the single-setting flags (None where the flag was not given)."""
    return {setting: getattr(args, flag.lstrip("-").replace("-", "_"), None)
            for flag, (setting, _text) in _SETTING_FLAGS.items()}


def connection_from_args(args: argparse.Namespace) -> str:
    """The connection string the flags ask for (checked; LinkError names the mistake)."""
    if getattr(args, "connect", None):
        return str(parse_connection(args.connect))
    port = getattr(args, "udp", None)
    return udp_listen(DEFAULT_UDP_PORT if port is None else port)


def settings_from_args(args: argparse.Namespace) -> Settings:
    return load_settings(getattr(args, "config", None), **setting_overrides(args))

