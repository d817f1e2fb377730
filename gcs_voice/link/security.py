"""Who the link trusts: MAVLink 2 signing and the vehicle lock, as flags and as hooks on the connection.

``--signing-key PASSPHRASE|@FILE`` signs everything sent (``link.signing``); ``--require-signed`` also
refuses what the vehicle does not sign with that key; ``--lock-vehicle`` keeps to the first vehicle heard
(``link.vehicle_lock``). ``VehicleLink`` calls ``attach`` once the connection is open, ``observe`` for
each message it takes, ``close`` at the end: nothing else in the link knows about either.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gcs_voice.errors import LinkError
from gcs_voice.link.signing import GroundSigning, TimestampStore, key_from_flag
from gcs_voice.link.vehicle_lock import VehicleLock

if TYPE_CHECKING:  # annotations only: mavutil is imported by link.connection, after MAVLINK20 is set
    from pymavlink import mavutil
    from pymavlink.dialects.v20 import common as mavlink

__all__ = ["LinkSecurity", "SecurityHooks", "add_security_arguments", "security_from_args"]


@dataclass(frozen=True)
class LinkSecurity:
    """``key``: 32 bytes (SHA-256 of the passphrase) or None; ``timestamp_path``: None = the default state file."""

    key: bytes | None = None
    require_signed: bool = False
    lock_vehicle: bool = False
    timestamp_path: Path | None = None

    def __post_init__(self) -> None:
        if self.require_signed and self.key is None:
            raise LinkError("--require-signed needs --signing-key: without a key nothing can be checked")

    def attach(self, conn: mavutil.mavfile, on_event: Callable[[str], None]) -> "SecurityHooks":
        return SecurityHooks(self, conn, on_event)


class SecurityHooks:
    """What ``LinkSecurity`` does on one open connection."""

    def __init__(self, security: LinkSecurity, conn: mavutil.mavfile, on_event: Callable[[str], None]) -> None:
        self.on_event = on_event
        self.signing: GroundSigning | None = None
        self.lock: VehicleLock | None = VehicleLock(conn) if security.lock_vehicle else None
        if security.key is not None:
            self.signing = GroundSigning(security.key, security.require_signed,
                                         TimestampStore(security.timestamp_path), on_event)
            self.signing.attach(conn)

    def observe(self, msg: mavlink.MAVLink_message, vehicle_system_id: int | None) -> None:
        if self.lock is not None:
            line = self.lock.observe(msg, vehicle_system_id)
            if line:
                self.on_event(line)
        if self.signing is not None:
            self.signing.observe(msg, vehicle_system_id)

    def diagnosis(self) -> str:
        return self.signing.diagnosis() if self.signing is not None else ""

    def close(self) -> None:
        if self.signing is not None:
            self.signing.close()


def add_security_arguments(group: argparse._ActionsContainer) -> None:
    group.add_argument("--signing-key", metavar="PASSPHRASE|@FILE",
                       help="sign everything sent with MAVLink 2 signing; the key is SHA-256 of PASSPHRASE, as "
                            "MAVProxy's 'signing setup' makes it. @FILE reads the passphrase from the file's first "
                            "line (a passphrase on the command line shows in 'ps')")
    group.add_argument("--require-signed", action="store_true",
                       help="with --signing-key: refuse every packet the vehicle does not sign with that key "
                            "(a telemetry radio's RADIO_STATUS excepted)")
    group.add_argument("--lock-vehicle", action="store_true",
                       help="once the vehicle is heard, hear and send to it alone: on UDP, datagrams from other "
                            "addresses are dropped and nobody else gets our setpoints (see docs/link.md)")


def security_from_args(args: argparse.Namespace) -> LinkSecurity:
    """The flags as a LinkSecurity (LinkError, one line, for an empty passphrase or a missing @FILE)."""
    value = getattr(args, "signing_key", None)
    key = None if value is None else key_from_flag(value)
    return LinkSecurity(key=key, require_signed=bool(getattr(args, "require_signed", False)),
                        lock_vehicle=bool(getattr(args, "lock_vehicle", False)))
