"""``--lock-vehicle``: once the vehicle is heard, hear and talk to that vehicle only.

A ``udpin`` link is a server: pymavlink's ``mavudp`` adds every address a datagram comes from to its
clients and writes every packet (our setpoints included) to all of them, so any host that sends one
datagram gets a copy of the stream and can feed us telemetry. Locked, the socket is connected to the
address the vehicle's first HEARTBEAT came from: the kernel drops datagrams from anyone else, and we
write to that address alone. The state tracker already keeps to the first flight controller's system
id on every transport; the lock adds the address on UDP.

The first vehicle heard wins: a host that sends a flight controller's HEARTBEAT before the real vehicle
does would be locked on instead. With ``--signing-key`` and ``--require-signed`` only a vehicle that
signs with our key can be heard at all. A vehicle that comes back from another address (a restarted
simulator on a new port) is not heard again until gcs-voice restarts.
"""

from __future__ import annotations

import time
from collections import deque
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: mavutil is imported by link.connection, after MAVLINK20 is set
    from pymavlink import mavutil
    from pymavlink.dialects.v20 import common as mavlink

__all__ = ["VehicleLock"]

UDP_MAX_PACKET_LEN = 65535


class VehicleLock:
    """Installed on an open pymavlink connection; ``observe`` each message taken, it locks once."""

    def __init__(self, conn: mavutil.mavfile) -> None:
        from pymavlink import mavutil

        self.conn = conn
        self.udp = isinstance(conn, mavutil.mavudp)
        self.system_id: int | None = None
        self.address: tuple[str, int] | None = None
        self._queue: deque = deque()
        if self.udp:
            conn.recv_msg = self._recv_msg       # the same reading, but each message knows its sender

    @property
    def locked(self) -> bool:
        return self.system_id is not None

    def _recv_msg(self) -> mavlink.MAVLink_message | None:
        """``mavudp.recv`` + ``mavfile.recv_msg`` for one datagram, remembering who sent each message."""
        conn = self.conn
        if self._queue:
            return self._queue.popleft()
        conn.pre_message()
        try:
            data, sender = conn.port.recvfrom(UDP_MAX_PACKET_LEN)
        except OSError:             # nothing waiting, or ECONNREFUSED from an earlier send
            return None
        if self.address is not None and sender != self.address:
            return None             # queued before the socket was connected to the vehicle
        if conn.udp_server:
            conn.clients.add(sender)
            conn.clients_last_alive[sender] = time.time()
        elif conn.broadcast:
            conn.last_address = sender
        if conn.first_byte:
            conn.auto_mavlink_version(data)
        msgs = conn.mav.parse_buffer(data) or []
        for msg in msgs:
            msg._gcs_sender = sender
            conn.post_message(msg)
        self._queue.extend(msgs[1:])
        return msgs[0] if msgs else None

    def observe(self, msg: mavlink.MAVLink_message, vehicle_system_id: int | None) -> str | None:
        """Lock on the message that made the tracker pick its vehicle; returns the line to tell the user."""
        if self.locked or vehicle_system_id is None or msg.get_type() != "HEARTBEAT" \
                or msg.get_srcSystem() != vehicle_system_id:
            return None
        self.system_id = vehicle_system_id
        sender = getattr(msg, "_gcs_sender", None)
        if not self.udp or sender is None:
            return f"locked to vehicle system {vehicle_system_id}: other system ids are ignored"
        self.address = sender
        self.conn.port.connect(sender)
        if self.conn.udp_server:
            self.conn.clients.intersection_update({sender})
            self.conn.clients.add(sender)
        return (f"locked to vehicle system {vehicle_system_id} at {sender[0]}:{sender[1]}: datagrams from other "
                "addresses are dropped and nothing is sent to them")
