"""A pymavlink ground station on real loopback UDP, driven in lockstep with an in-process gcs-sim.

For tests and benchmarks (a 60 s flight checked in a few seconds); the simulator never imports it.

The sim sends to our socket exactly as to QGroundControl; we answer to its source port. Simulated
time only advances inside ``run``/``wait``, so a 60 s flight takes a few seconds of CPU.
"""

from __future__ import annotations

import math
import socket
from typing import Any, Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.build import build_sim
from sim_bridge.transport import UdpOutLink

_IGNORE_POSITION = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
                    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)
_IGNORE_ACCEL = (mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE)
#: type_mask values: velocity only (3527), velocity + yaw (2503), velocity + yaw rate (1479)
VELOCITY_ONLY = (_IGNORE_POSITION | _IGNORE_ACCEL | mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
                 | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)
VELOCITY_YAW = _IGNORE_POSITION | _IGNORE_ACCEL | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
VELOCITY_YAW_RATE = _IGNORE_POSITION | _IGNORE_ACCEL | mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE


class LockstepGcs:
    def __init__(self, autopilot: str = "ardupilot", room: str = "living_room", tlog: Any = None, decode: bool = True,
                 **kwargs: Any) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.server = build_sim(autopilot, room, tlog=tlog, **kwargs)
        self.link = UdpOutLink("127.0.0.1", self.sock.getsockname()[1])
        self.server.add_link(self.link)
        self.sim_addr = self.link.sock.getsockname()
        self.mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.received: list[tuple[float, Any]] = []   # (sim time, message)
        self.decode = decode                           # False: only count bytes (to time the sim alone)
        self.bytes_received = 0

    @property
    def t_s(self) -> float:
        return self.server.vehicle.time_s

    def close(self) -> None:
        self.server.close()
        self.sock.close()

    def send(self, msg: Any) -> None:
        self.sock.sendto(msg.pack(self.mav), self.sim_addr)

    def send_raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.sim_addr)

    def _drain(self) -> list[Any]:
        new = []
        while True:
            try:
                data = self.sock.recv(65535)
            except BlockingIOError:
                return new
            self.bytes_received += len(data)
            if not self.decode:
                continue
            for msg in self.parser.parse_buffer(data) or []:
                if msg.get_type() != "BAD_DATA":
                    self.received.append((self.t_s, msg))
                    new.append(msg)

    def run(self, sim_s: float, until: Callable[[Any], bool] | None = None, every: Callable[[], None] | None = None,
            every_s: float = 0.1) -> Any:
        """Step ``sim_s``; return the first message for which ``until`` is true (None if none came)."""
        end = self.t_s + sim_s
        next_every = self.t_s
        while self.t_s < end - 1e-9:
            if every is not None and self.t_s >= next_every - 1e-9:
                every()
                next_every += every_s
            self.server.step()
            for msg in self._drain():
                if until is not None and until(msg):
                    return msg
        return None

    def boot(self) -> None:
        """Run until the personality has finished booting (ready to arm), plus one tick."""
        while not self.server.autopilot.booted:
            self.run(self.server.dt_s)
        self.run(self.server.dt_s)

    def wait(self, kind: str, sim_s: float = 2.0, cond: Callable[[Any], bool] = lambda m: True, **kw: Any) -> Any:
        return self.run(sim_s, until=lambda m: m.get_type() == kind and cond(m), **kw)

    def command(self, command: int, *params: float, sim_s: float = 0.5) -> list[int]:
        """COMMAND_LONG; the results of every COMMAND_ACK for it within ``sim_s``."""
        p = list(params) + [0.0] * (7 - len(params))
        start = len(self.received)
        self.send(self.mav.command_long_encode(1, 1, command, 0, *p))
        self.run(sim_s)
        return [m.result for _t, m in self.received[start:] if m.get_type() == "COMMAND_ACK" and m.command == command]

    def setpoint(self, frame: int, type_mask: int, vx: float = 0.0, vy: float = 0.0, vz: float = 0.0,
                 yaw: float = 0.0, yaw_rate: float = 0.0, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        self.send(self.mav.set_position_target_local_ned_encode(int(self.t_s * 1000), 1, 1, frame, type_mask,
                                                                x, y, z, vx, vy, vz, 0, 0, 0, yaw, yaw_rate))

    def last(self, kind: str) -> Any:
        for _t, msg in reversed(self.received):
            if msg.get_type() == kind:
                return msg
        return None

    def of_type(self, kind: str) -> list[tuple[float, Any]]:
        return [(t, m) for t, m in self.received if m.get_type() == kind]

    def heading_deg(self) -> float:
        return math.degrees(self.server.vehicle.state.yaw_rad) % 360.0

    def texts(self) -> list[str]:
        return [m.text for _t, m in self.of_type("STATUSTEXT")]
