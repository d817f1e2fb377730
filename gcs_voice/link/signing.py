"""MAVLink 2 signing for the ground station: ``--signing-key PASSPHRASE|@FILE`` and ``--require-signed``.

The key is SHA-256 of the passphrase, as MAVProxy's ``signing setup PASSPHRASE`` makes it, so a vehicle
set up with MAVProxy (or ``gcs-sim --signing-key``) and gcs-voice agree on it. Everything sent is signed.
What comes back is checked as the C library does (signature first, then the stream's timestamp), so a
forged packet cannot push a stream's timestamp ahead and have the vehicle's real packets refused later;
pymavlink's own check stores the timestamp before it looks at the signature.

Timestamps are 10 µs units since 2015-01-01 (the MAVLink spec). They never lag the wall clock, never go
back, and survive restarts: the last one is kept in ``$XDG_STATE_HOME/gcs-voice/signing-timestamp``
(default ``~/.local/state``) and the next session starts after it, even if the clock went back. A
session that did not close cleanly starts a minute later, as ArduPilot does with its saved timestamp.
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from gcs_voice.errors import LinkError

if TYPE_CHECKING:
    from pymavlink import mavutil

__all__ = ["GroundSigning", "TimestampStore", "key_from_flag", "passphrase_key", "timestamp_now",
           "verify_signature", "default_timestamp_path"]

EPOCH_2015_UNIX_S = 1420070400
UNITS_PER_S = 100_000
#: a new stream may start at most this far behind our timestamp (C library and pymavlink: one minute)
NEW_STREAM_BEHIND = 60 * UNITS_PER_S
#: after an unclean exit the next session starts this far after the last saved timestamp (ArduPilot: 60 s)
CRASH_MARGIN = 60 * UNITS_PER_S
SAVE_PERIOD_S = 30.0
#: what is heard unsigned even with --require-signed: a telemetry radio's own reports (MAVProxy's rule)
UNSIGNED_OK = frozenset({mavlink.MAVLINK_MSG_ID_RADIO_STATUS})


def passphrase_key(passphrase: str) -> bytes:
    """SHA-256 of the passphrase's UTF-8 bytes: MAVProxy's ``passphrase_to_key``."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def key_from_flag(value: str, flag: str = "--signing-key") -> bytes:
    """``PASSPHRASE`` or ``@FILE`` (its first line; keeps the passphrase out of ``ps``) -> the 32-byte key."""
    passphrase = value
    if value.startswith("@"):
        path = Path(value[1:]).expanduser()
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise LinkError(f"{flag} @{path}: no such file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise LinkError(f"{flag} @{path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
        passphrase = text.splitlines()[0] if text.strip() else ""
        if not passphrase:
            raise LinkError(f"{flag} @{path}: the file holds no passphrase (its first line is empty)")
    if not passphrase:
        raise LinkError(f"{flag}: the passphrase is empty")
    return passphrase_key(passphrase)


def timestamp_now(unix_s: float | None = None) -> int:
    """10 µs units since 2015-01-01 for a UNIX time (now by default)."""
    unix_s = time.time() if unix_s is None else unix_s
    return max(0, int((unix_s - EPOCH_2015_UNIX_S) * UNITS_PER_S))


def default_timestamp_path() -> Path:
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(state) / "gcs-voice" / "signing-timestamp"


class TimestampStore:
    """The last signing timestamp used on this machine: ``<timestamp> clean|running`` in one small file."""

    def __init__(self, path: Path | None = None) -> None:
        self.path = path or default_timestamp_path()

    def floor(self) -> int:
        """The first timestamp this session may use (0 when nothing was saved or the file is unreadable)."""
        try:
            value, _, how = self.path.read_text(encoding="ascii").strip().partition(" ")
            saved = int(value)
        except (OSError, ValueError, UnicodeDecodeError):
            return 0
        return saved + (1 if how == "clean" else CRASH_MARGIN)

    def save(self, timestamp: int, clean: bool) -> None:
        """Write atomically (OSError goes to the caller, who warns once)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".tmp")
        tmp.write_text(f"{timestamp} {'clean' if clean else 'running'}\n", encoding="ascii")
        os.replace(tmp, self.path)


class _ClockedSigning(mavlink.MAVLinkSigning):
    """pymavlink's signing state whose timestamp never goes back (a lock: the link thread raises it on
    receive while an operation's thread adds 1 on send) and never lags the wall clock."""

    def __init__(self, floor: int) -> None:
        self._lock = threading.Lock()
        self._timestamp = floor
        super().__init__()

    @property
    def timestamp(self) -> int:
        return max(self._timestamp, timestamp_now())

    @timestamp.setter
    def timestamp(self, value: int) -> None:
        with self._lock:
            self._timestamp = max(self._timestamp, int(value))


def verify_signature(mav: mavlink.MAVLink, msgbuf: bytearray, src_system: int, src_component: int) -> bool:
    """``mavlink_signature_check`` of the C library: the signature first, then the stream's timestamp."""
    signing = mav.signing
    data = bytes(msgbuf)
    expected = hashlib.sha256(signing.secret_key + data[:-6]).digest()[:6]
    if not hmac.compare_digest(expected, data[-6:]):
        return False
    timestamp = int.from_bytes(data[-12:-6], "little")
    stream = (data[-13], src_system, src_component)
    last = signing.stream_timestamps.get(stream)
    if last is None:
        if timestamp + NEW_STREAM_BEHIND < signing.timestamp:
            return False
    elif timestamp <= last:
        return False
    signing.stream_timestamps[stream] = timestamp
    signing.timestamp = timestamp
    return True


class GroundSigning:
    """Signing on one pymavlink connection: ``attach(conn)`` once, ``tick()`` now and then, ``close()``."""

    def __init__(self, key: bytes, require_signed: bool = False, store: TimestampStore | None = None,
                 on_event: Callable[[str], None] = lambda _line: None) -> None:
        self.key = key
        self.require_signed = require_signed
        self.store = store or TimestampStore()
        self.on_event = on_event
        self.state: _ClockedSigning | None = None
        self._next_save_s = 0.0
        self._save_failed = False
        self._warned_unsigned = self._warned_other_key = False

    def attach(self, conn: mavutil.mavfile) -> None:
        self.state = _ClockedSigning(self.store.floor())
        conn.mav.signing = self.state
        conn.setup_signing(self.key, sign_outgoing=True, allow_unsigned_callback=self._allow_unsigned)
        conn.mav.check_signature = functools.partial(verify_signature, conn.mav)
        self._save(clean=False)

    def _allow_unsigned(self, _mav: mavlink.MAVLink, msg_id: int) -> bool:
        """Called for unsigned packets and packets not signed with our key (pymavlink's callback)."""
        return not self.require_signed or msg_id in UNSIGNED_OK

    def observe(self, msg: mavlink.MAVLink_message, vehicle_system_id: int | None) -> None:
        """A message that got through: say once if the vehicle does not sign with our key; save now and then."""
        if self.state is None:
            return
        if vehicle_system_id is not None and msg.get_srcSystem() == vehicle_system_id and not msg.get_signed():
            header_signed = bool(msg.get_header().incompat_flags & mavlink.MAVLINK_IFLAG_SIGNED)
            if header_signed and not self._warned_other_key:
                self._warned_other_key = True
                self.on_event("the vehicle signs with another key: it will ignore our commands (check --signing-key)")
            elif not header_signed and not self._warned_unsigned:
                self._warned_unsigned = True
                self.on_event("the vehicle's packets are not signed (it has no key): --require-signed would refuse "
                              "them; anyone on the link can still command it")
        if time.monotonic() >= self._next_save_s:
            self._save(clean=False)

    def refused(self) -> int:
        """Packets refused so far (unsigned, other key, replayed)."""
        return 0 if self.state is None else int(self.state.reject_count)

    def diagnosis(self) -> str:
        """For 'no vehicle heard': why packets may have been dropped (empty when none were)."""
        count = self.refused()
        if not count:
            return ""
        return (f"; {count} packets were refused as unsigned, signed with another key or replayed "
                f"({'--require-signed' if self.require_signed else 'signing'})")

    def close(self) -> None:
        self._save(clean=True)

    def _save(self, clean: bool) -> None:
        if self.state is None:
            return
        self._next_save_s = time.monotonic() + SAVE_PERIOD_S
        try:
            self.store.save(self.state.timestamp, clean)
        except OSError as exc:
            if not self._save_failed:
                self._save_failed = True
                self.on_event(f"cannot keep the signing timestamp in {self.store.path} ({exc.strerror or exc}); "
                              "a clock set back before the next session could have old packets accepted")
