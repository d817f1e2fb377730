"""Who may talk to the simulator: ``gcs-sim --allow HOST|NETWORK`` (repeatable).

Without ``--allow`` the UDP socket takes datagrams from any sender and the TCP port any client, as SITL
does: whoever can reach the machine can command the vehicle (unless ``--signing-key`` is set). With it,
datagrams from other addresses are dropped unread and other TCP clients are closed at once.
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Sequence

__all__ = ["PeerFilter", "AccessError"]


class AccessError(ValueError):
    """An ``--allow`` value that is neither an address, a network nor a known host name (one line)."""


class PeerFilter:
    """Callable ``filter(host) -> bool``; counts what it refused."""

    def __init__(self, specs: Sequence[str]) -> None:
        self.networks = [self._network(spec) for spec in specs]
        self.refused = 0

    @staticmethod
    def _network(spec: str) -> ipaddress.IPv4Network | ipaddress.IPv6Network:
        text = spec.strip()
        try:
            return ipaddress.ip_network(text, strict=False)
        except ValueError:
            pass
        if "/" not in text and text:
            try:
                return ipaddress.ip_network(socket.gethostbyname(text))
            except (OSError, UnicodeError, ValueError):
                pass
        raise AccessError(f"--allow {spec!r}: expected an address (127.0.0.1), a network (192.168.1.0/24) "
                          "or a host name")

    def __call__(self, host: str) -> bool:
        try:
            address = ipaddress.ip_address(host)
        except ValueError:
            self.refused += 1
            return False
        if any(address in network for network in self.networks):
            return True
        self.refused += 1
        return False

    def __str__(self) -> str:
        return ",".join(str(n) for n in self.networks)
