"""MAVLink 2 message signing on the simulated vehicle, by the rules ArduPilot and PX4 run.

With a key (``gcs-sim --signing-key``, or a SETUP_SIGNING) the vehicle signs everything it sends, and a
message reaches a handler only when it is signed with that key and its timestamp moves its stream
(link id, system, component) forward; the stream table is shared by every link, so a packet captured on
one link and replayed on another is refused too. The few messages a firmware lets through unsigned
(RADIO_STATUS...) are data (``data/signing.toml``). The check follows the C library's
``mavlink_signature_check``: signature first, then timestamp, so a forged packet cannot move a stream.
Timestamps are 10 µs units since 2015-01-01, never behind the wall clock and never going back.
"""

from __future__ import annotations

import hashlib
import hmac
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["SimSigning", "SigningCounts", "SigningKeyError", "key_from_flag", "passphrase_key",
           "timestamp_now", "EPOCH_2015_UNIX_S"]

#: MAVLink signing time starts at 2015-01-01 00:00:00 UTC; one unit is 10 µs.
EPOCH_2015_UNIX_S = 1420070400
UNITS_PER_S = 100_000
SIGNATURE_BLOCK_LEN = 13        # link id (1) + timestamp (6) + signature (6)
KEY_LEN = 32


class SigningKeyError(ValueError):
    """``--signing-key`` cannot be used (empty passphrase, unreadable file): one line for the user."""


def passphrase_key(passphrase: str) -> bytes:
    """The 32-byte secret for a passphrase: SHA-256 of its UTF-8 bytes, as MAVProxy's ``signing setup``."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def key_from_flag(value: str, flag: str = "--signing-key") -> bytes:
    """``PASSPHRASE`` or ``@FILE`` (the file's first line: keeps the passphrase out of ``ps``) -> key."""
    passphrase = value
    if value.startswith("@"):
        path = Path(value[1:])
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise SigningKeyError(f"{flag} @{path}: no such file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise SigningKeyError(f"{flag} @{path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
        passphrase = text.splitlines()[0] if text.strip() else ""
        if not passphrase:
            raise SigningKeyError(f"{flag} @{path}: the file holds no passphrase (its first line is empty)")
    if not passphrase:
        raise SigningKeyError(f"{flag}: the passphrase is empty")
    return passphrase_key(passphrase)


def timestamp_now(unix_s: float) -> int:
    """A signing timestamp for a UNIX time: 10 µs units since 2015-01-01 (0 before then)."""
    return max(0, int((unix_s - EPOCH_2015_UNIX_S) * UNITS_PER_S))


class _ClockedSigning(mavlink.MAVLinkSigning):
    """pymavlink's signing state whose timestamp never goes back and never lags the wall clock.

    pymavlink adds 1 per packet sent and raises it to what it accepts; the floor keeps a long run from
    falling minutes behind the clock (a ground station refuses a new stream more than a minute old).
    """

    def __init__(self, clock: Callable[[], float]) -> None:
        self._clock = clock
        self._timestamp = 0
        super().__init__()

    @property
    def timestamp(self) -> int:
        return max(self._timestamp, timestamp_now(self._clock()))

    @timestamp.setter
    def timestamp(self, value: int) -> None:
        self._timestamp = max(self._timestamp, int(value))


@dataclass
class SigningCounts:
    """What the signing check did, summed over links (the exit line reports it)."""

    signed_ok: int = 0
    unsigned_allowed: int = 0      # on the firmware's list of messages that may come unsigned
    unsigned: int = 0
    bad_signature: int = 0         # signed, but not with our key (or altered)
    replayed: int = 0              # timestamp not after the last one of its stream
    old_stream: int = 0            # a new stream starting more than a minute behind
    too_many_streams: int = 0

    def refused(self) -> int:
        return (self.unsigned + self.bad_signature + self.replayed + self.old_stream + self.too_many_streams)


def _data() -> dict:
    return tomllib.loads(resources.files("sim_bridge").joinpath("data", "signing.toml").read_text(encoding="utf-8"))


class SimSigning:
    """The vehicle's signing: one key, one outgoing timestamp and one stream table for every link."""

    def __init__(self, autopilot: str, key: bytes | None = None, clock: Callable[[], float] = time.time) -> None:
        data = _data()
        self.unsigned_ok = frozenset(getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
                                     for name in data[autopilot]["unsigned_ok"])
        self.armed_refusal = str(data[autopilot]["armed_refusal"])
        self.max_streams = int(data["limits"]["max_streams"])
        self.new_stream_behind = int(data["limits"]["new_stream_behind_s"]) * UNITS_PER_S
        self.clock = clock
        self.state = _ClockedSigning(clock)
        # pymavlink's own check runs first on every link's parser: let it pass everything, decide here.
        self.state.allow_unsigned_callback = lambda _mav, _msg_id: True
        self.streams: dict[tuple[int, int, int], int] = {}
        self.counts = SigningCounts()
        self.key_changes = 0
        if key is not None:
            self.set_key(key, 0)

    @property
    def enabled(self) -> bool:
        return self.state.secret_key is not None

    def attach(self, link: Any) -> None:
        """Make ``link`` sign what it sends with the shared key and timestamp (now or once a key is set)."""
        link.mav.signing = self.state

    def set_key(self, key: bytes, initial_timestamp: int) -> None:
        """Use ``key`` from now on (all zeros with timestamp 0 turns signing off, as the spec says).

        Our timestamp starts a minute ahead of the clock, so a new stream must be stamped after this moment:
        packets captured before the key was set (before the simulator started) are refused. ArduPilot gets
        the same from its saved timestamp plus a minute; gcs-sim keeps nothing on disk.
        """
        if len(key) != KEY_LEN:
            raise ValueError(f"a signing key is {KEY_LEN} bytes, not {len(key)}")
        if not any(key) and initial_timestamp == 0:
            self.state.secret_key = None
            self.state.sign_outgoing = False
        else:
            self.state.secret_key = bytes(key)
            self.state.sign_outgoing = True
            self.state.timestamp = max(initial_timestamp, timestamp_now(self.clock()) + self.new_stream_behind)

    # ---------------------------------------------------------------- incoming
    def accept(self, msg: Any) -> bool:
        """Whether a parsed message may reach its handler (always, while no key is set)."""
        if not self.enabled:
            return True
        buf = bytes(msg.get_msgbuf())
        signed = buf[0] == mavlink.PROTOCOL_MARKER_V2 and bool(buf[2] & mavlink.MAVLINK_IFLAG_SIGNED)
        if signed and len(buf) > SIGNATURE_BLOCK_LEN:
            verdict = self._check(buf, msg.get_srcSystem(), msg.get_srcComponent())
            if verdict == "signed_ok":
                self.counts.signed_ok += 1
                return True
        else:
            verdict = "unsigned"
        if msg.get_msgId() in self.unsigned_ok:
            self.counts.unsigned_allowed += 1
            return True
        setattr(self.counts, verdict, getattr(self.counts, verdict) + 1)
        return False

    def _check(self, buf: bytes, system: int, component: int) -> str:
        assert self.state.secret_key is not None
        link_id = buf[-SIGNATURE_BLOCK_LEN]
        timestamp = int.from_bytes(buf[-12:-6], "little")
        expected = hashlib.sha256(self.state.secret_key + buf[:-6]).digest()[:6]
        if not hmac.compare_digest(expected, buf[-6:]):
            return "bad_signature"
        stream = (link_id, system, component)
        last = self.streams.get(stream)
        if last is None:
            if len(self.streams) >= self.max_streams:
                return "too_many_streams"
            if timestamp + self.new_stream_behind < self.state.timestamp:
                return "old_stream"
        elif timestamp <= last:
            return "replayed"
        self.streams[stream] = timestamp
        self.state.timestamp = timestamp          # our next one is at least this
        return "signed_ok"

    def setup_signing(self, msg: Any) -> str | None:
        """SETUP_SIGNING (it got here, so it passed ``accept``: anyone while no key is set, as on ArduPilot;
        only a sender signing with the current key afterwards). Returns what changed, for the exit line."""
        key = bytes(msg.secret_key) if isinstance(msg.secret_key, (bytes, bytearray)) else bytes(
            int(b) & 0xFF for b in msg.secret_key)
        key = key[:KEY_LEN].ljust(KEY_LEN, b"\0")
        timestamp = int(msg.initial_timestamp)
        if not any(key) and timestamp == 0:
            if not self.enabled:
                return None
            self.set_key(key, 0)
            self.key_changes += 1
            return "signing turned off by SETUP_SIGNING"
        self.set_key(key, timestamp)
        self.key_changes += 1
        return "signing key set by SETUP_SIGNING"

    def summary(self) -> str:
        """``signing on: 120 signed ok, refused 3 unsigned, 1 replayed`` (empty when signing never ran)."""
        if not self.enabled and not self.key_changes and not self.counts.refused() and not self.counts.signed_ok:
            return ""
        parts = [f"{getattr(self.counts, f.name)} {f.name.replace('_', ' ')}" for f in fields(self.counts)
                 if f.name not in ("signed_ok", "unsigned_allowed") and getattr(self.counts, f.name)]
        refused = f", refused {', '.join(parts)}" if parts else ", refused none"
        changed = f", key changed {self.key_changes}x by SETUP_SIGNING" if self.key_changes else ""
        return f"signing {'on' if self.enabled else 'off'}: {self.counts.signed_ok} signed ok{refused}{changed}"
