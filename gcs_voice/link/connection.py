"""MAVLink connection strings, in pymavlink's own syntax (``mavutil.mavlink_connection``).

Accepted: ``udpin:HOST:PORT`` (listen, like a ground station), ``udpout:HOST:PORT`` (send to),
``tcp:HOST:PORT`` (connect), ``tcpin:HOST:PORT`` (listen), or a serial device with an optional baud rate
(``/dev/ttyACM0``, ``/dev/ttyUSB0,57600``, ``COM3,115200``). ``--udp PORT`` is ``udpin:0.0.0.0:PORT``.
MAVSDK's URL form (``udpin://0.0.0.0:14540``) is refused with a hint rather than guessed at.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

from gcs_voice.errors import LinkError

__all__ = ["ConnectionSpec", "parse_connection", "udp_listen", "open_connection", "DEFAULT_SERIAL_BAUD"]

DEFAULT_SERIAL_BAUD = 57600
_NETWORK_KINDS = ("udpin", "udpout", "tcp", "tcpin")
_SERIAL_RE = re.compile(r"^(/dev/[\w./-]+|COM\d+)(?:,(\d+))?$", re.IGNORECASE)


@dataclass(frozen=True)
class ConnectionSpec:
    """A validated connection: ``kind`` is udpin/udpout/tcp/tcpin/serial; ``device`` what mavutil opens."""

    kind: str
    device: str
    host: str = ""
    port: int = 0
    baud: int = DEFAULT_SERIAL_BAUD

    def __str__(self) -> str:
        return self.device if self.kind != "serial" else f"{self.device},{self.baud}"


def udp_listen(port: int | str) -> str:
    """The connection string for ``--udp PORT``: listen on every interface like a ground station."""
    return f"udpin:0.0.0.0:{_port(str(port), f'--udp {port}')}"


def _port(text: str, spec: str) -> int:
    if not text.isdigit() or not 0 <= int(text) <= 65535:
        raise LinkError(f"bad port {text!r} in {spec!r}: want a number 0-65535")
    return int(text)


def parse_connection(spec: str) -> ConnectionSpec:
    """Check ``spec`` and say in one line what is wrong with it."""
    spec = spec.strip()
    if "://" in spec:
        kind, _, rest = spec.partition("://")
        raise LinkError(
            f"{spec!r} is MAVSDK's URL form; gcs-voice takes pymavlink strings: write {kind}:{rest or 'HOST:PORT'}"
        )
    serial = _SERIAL_RE.match(spec)
    if serial:
        baud = int(serial.group(2)) if serial.group(2) else DEFAULT_SERIAL_BAUD
        if baud <= 0:
            raise LinkError(f"bad baud rate in {spec!r}")
        return ConnectionSpec("serial", serial.group(1), baud=baud)
    kind, sep, rest = spec.partition(":")
    if not sep or kind not in _NETWORK_KINDS:
        raise LinkError(
            f"unknown connection {spec!r}: use udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
            "tcpin:HOST:PORT or a serial device like /dev/ttyUSB0,57600"
        )
    host, sep, port_text = rest.rpartition(":")
    if not sep or not host:
        raise LinkError(f"{spec!r} needs HOST:PORT after {kind}:, e.g. {kind}:127.0.0.1:14550")
    port = _port(port_text, spec)
    if port == 0 and kind in ("udpout", "tcp"):
        raise LinkError(f"{spec!r}: port 0 is only meaningful for listening")
    return ConnectionSpec(kind, f"{kind}:{host}:{port}", host=host, port=port)


def open_connection(spec: str | ConnectionSpec, source_system: int, source_component: int):
    """Open the link with pymavlink (MAVLink 2, ardupilotmega dialect); LinkError when it cannot."""
    parsed = spec if isinstance(spec, ConnectionSpec) else parse_connection(spec)
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    try:
        conn = mavutil.mavlink_connection(
            parsed.device, baud=parsed.baud, source_system=source_system, source_component=source_component,
            dialect="ardupilotmega", autoreconnect=True, retries=0,
        )
    except Exception as exc:  # sockets, serial ports: the OS says why
        raise LinkError(f"cannot open {parsed}: {exc}") from None
    conn.mav.robust_parsing = True
    return conn
