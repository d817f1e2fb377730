"""Sockets as SITL offers them: UDP out to a ground station, a TCP server for several clients, a tlog.

Each link owns its own MAVLink parser (so interleaved peers never corrupt each other's frames) and
its own sequence counter. Everything here is non-blocking: a slow or silent peer can never stall
the physics loop.
"""

from __future__ import annotations

import errno
import select
import socket
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["Link", "UdpOutLink", "TcpClientLink", "TcpServer", "TlogWriter", "parse_endpoint", "TransportError"]

#: How much one poll reads from one link at most, so a flood cannot starve the physics.
MAX_DATAGRAMS_PER_POLL = 64
MAX_TCP_BYTES_PER_POLL = 65536
#: A TCP client whose unsent backlog grows beyond this is too slow and is dropped.
MAX_TCP_BACKLOG_BYTES = 1 << 20


class TransportError(ValueError):
    """A transport flag is malformed or its socket cannot be opened (one line for the user)."""


@dataclass
class LinkStats:
    """Counters per link; summed into the STATUSTEXT summary and the exit line."""

    packets_in: int = 0
    packets_out: int = 0
    bytes_in: int = 0
    bad_frames: int = 0          # bad CRC, truncated or garbage (pymavlink 'BAD_DATA')
    unknown_messages: int = 0     # valid framing, message id not in the dialect
    dropped_in: int = 0           # datagrams left unread because of a flood (counted when seen)
    send_errors: int = 0


@dataclass
class Link:
    """One peer. ``mav`` parses what it sends us and numbers what we send it."""

    name: str
    mav: mavlink.MAVLink = field(init=False)
    stats: LinkStats = field(default_factory=LinkStats)
    closed: bool = False
    #: (system, component) of every sender heard on this link (PX4 routes its ACKs by this)
    seen: set = field(default_factory=set)

    def __post_init__(self) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.mav.robust_parsing = True

    def send_bytes(self, data: bytes) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def fileno(self) -> int:  # pragma: no cover - overridden
        raise NotImplementedError

    def read(self) -> list[bytes]:  # pragma: no cover - overridden
        raise NotImplementedError

    def close(self) -> None:
        self.closed = True


def parse_endpoint(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``HOST:PORT`` or ``PORT`` -> (host, port); raises TransportError with the offending text."""
    host, _, port_text = text.rpartition(":")
    host = host or default_host
    try:
        port = int(port_text)
    except ValueError:
        raise TransportError(f"{text!r}: expected HOST:PORT with a numeric port") from None
    if not 0 <= port <= 65535:
        raise TransportError(f"{text!r}: port must be 0-65535")
    return host, port


class UdpOutLink(Link):
    """Sends to a fixed ground-station address from an ephemeral port; accepts datagrams from anyone."""

    def __init__(self, host: str, port: int) -> None:
        super().__init__(name=f"udp:{host}:{port}")
        try:
            self.dest = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
        except (socket.gaierror, UnicodeError) as exc:
            raise TransportError(f"udp:{host}:{port}: unknown host") from exc
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)   # absorb bursts (kernel caps it)
        self.sock.bind(("127.0.0.1" if self.dest[0].startswith("127.") else "0.0.0.0", 0))
        #: ``gcs-sim --allow``: datagrams from a host it refuses are dropped unread (None = anyone)
        self.peer_filter: Callable[[str], bool] | None = None

    def fileno(self) -> int:
        return self.sock.fileno()

    def send_bytes(self, data: bytes) -> None:
        try:
            self.sock.sendto(data, self.dest)
            self.stats.packets_out += 1
        except OSError:
            # Nobody listening yet (ICMP port unreachable) or a full buffer: like a radio, drop it.
            self.stats.send_errors += 1

    def read(self) -> list[bytes]:
        chunks = []
        for _ in range(MAX_DATAGRAMS_PER_POLL):
            try:
                data, sender = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                # ECONNREFUSED from an earlier sendto surfaces here on Linux; not a datagram.
                continue
            if self.peer_filter is None or self.peer_filter(sender[0]):
                chunks.append(data)
        return chunks

    def close(self) -> None:
        super().close()
        self.sock.close()


class TcpClientLink(Link):
    """One accepted TCP client; a stream, so partial frames carry over between reads."""

    def __init__(self, sock: socket.socket, peer: tuple[str, int]) -> None:
        super().__init__(name=f"tcp:{peer[0]}:{peer[1]}")
        self.sock = sock
        self.sock.setblocking(False)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._backlog = bytearray()

    def fileno(self) -> int:
        return self.sock.fileno()

    def send_bytes(self, data: bytes) -> None:
        if self.closed:
            return
        self._backlog += data
        self.stats.packets_out += 1
        self.flush()

    def flush(self) -> None:
        while self._backlog and not self.closed:
            try:
                sent = self.sock.send(self._backlog)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self.close()
                return
            del self._backlog[:sent]
        if len(self._backlog) > MAX_TCP_BACKLOG_BYTES:
            self.stats.send_errors += 1
            self.close()

    def read(self) -> list[bytes]:
        if self.closed:
            return []
        try:
            data = self.sock.recv(MAX_TCP_BYTES_PER_POLL)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError:
            self.close()
            return []
        if not data:
            self.close()
            return []
        return [data]

    def close(self) -> None:
        if not self.closed:
            super().close()
            self.sock.close()


class TcpServer:
    """Listens like SITL's SERIAL0 TCP port; every accepted client becomes a TcpClientLink."""

    def __init__(self, host: str, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            reason = "address in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc))
            raise TransportError(f"tcp:{host}:{port}: {reason}") from exc
        self.sock.listen(8)
        self.sock.setblocking(False)
        self.host, self.port = self.sock.getsockname()[:2]
        #: ``gcs-sim --allow``: a client from a host it refuses is closed at once (None = anyone)
        self.peer_filter: Callable[[str], bool] | None = None

    def fileno(self) -> int:
        return self.sock.fileno()

    def accept(self) -> list[TcpClientLink]:
        clients = []
        while True:
            try:
                conn, peer = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            if self.peer_filter is not None and not self.peer_filter(peer[0]):
                conn.close()
                continue
            clients.append(TcpClientLink(conn, peer))
        return clients

    def close(self) -> None:
        self.sock.close()


def wait_readable(fds: list, timeout_s: float) -> None:
    """Sleep until one of ``fds`` is readable or ``timeout_s`` passes (the real-time pacing wait)."""
    if timeout_s <= 0:
        return
    open_fds = [fd for fd in fds if not getattr(fd, "closed", False) and fd.fileno() >= 0]
    try:
        select.select(open_fds, [], [], timeout_s)
    except (OSError, ValueError):     # a socket closed under us: just pace, the next poll forgets it
        time.sleep(timeout_s)


class TlogWriter:
    """``.tlog``: per packet an 8-byte big-endian microsecond UNIX time, then the raw MAVLink bytes."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._file: BinaryIO | None = open(path, "wb")
        except OSError as exc:
            raise TransportError(f"--tlog {path}: {exc.strerror}") from exc
        self.records = 0

    def write(self, time_us: int, packet: bytes) -> None:
        if self._file is not None:
            self._file.write(struct.pack(">Q", time_us) + packet)
            self.records += 1

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
