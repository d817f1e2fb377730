"""A second ground station that behaves like QGroundControl on the wire (tests/test_two_stations.py,
tools/flight/soak_two_stations.py).

pymavlink, system 255 component 190 (QGroundControl's and Mission Planner's identity), a GCS HEARTBEAT at
1 Hz, a parameter read every 2 s (QGroundControl refreshes parameters it shows), and its own mode changes
(DO_SET_MODE, as QGroundControl sends them). It records every COMMAND_ACK it hears with its addressee,
the commands it sent, the vehicle's mode and its local position (what QGroundControl's map would show).
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

QGC_SYSTEM, QGC_COMPONENT = 255, 190


class QgcLikeStation:
    """``with QgcLikeStation("udpin:127.0.0.1:PORT") as qgc:`` ... ``qgc.set_mode(...)``."""

    def __init__(self, connection: str, system: int = QGC_SYSTEM, component: int = QGC_COMPONENT) -> None:
        self.conn = mavutil.mavlink_connection(connection, source_system=system, source_component=component)
        self.identity = (system, component)
        self.lock = threading.Lock()
        self.changed = threading.Condition(self.lock)
        #: (monotonic time, command, result, target_system, target_component) of every COMMAND_ACK heard
        self.acks: list[tuple[float, int, int, int, int]] = []
        #: (monotonic time, command) of every COMMAND_LONG this station sent
        self.sent: list[tuple[float, int]] = []
        self.param_values = 0
        self.vehicle: tuple[int, int] | None = None
        self.mode: int | None = None
        self.armed = False
        self.position: tuple[float, float, float] | None = None
        self._running = False
        self._thread = threading.Thread(target=self._loop, name="qgc-like", daemon=True)

    def __enter__(self) -> "QgcLikeStation":
        self._running = True
        self._thread.start()
        return self

    def __exit__(self, *_exc: Any) -> None:
        self._running = False
        self._thread.join(timeout=2)
        self.conn.close()

    # ---- what a test asks ---------------------------------------------------------------------------
    def wait_for(self, predicate: Callable[["QgcLikeStation"], bool], timeout_s: float, what: str) -> None:
        with self.changed:
            if not self.changed.wait_for(lambda: predicate(self), timeout_s):
                raise AssertionError(f"QGroundControl-like station: {what} not within {timeout_s:g} s")

    def set_mode(self, custom_mode: int, sub_mode: int = 0) -> None:
        """DO_SET_MODE with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED: ArduPilot's mode number, or PX4's main and sub."""
        self.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode, sub_mode)

    def command(self, command: int, *params: float) -> None:
        system, component = self.vehicle or (1, 1)
        padded = (list(params) + [0.0] * 7)[:7]
        with self.lock:
            self.sent.append((time.monotonic(), command))
        self.conn.mav.send(self.conn.mav.command_long_encode(system, component, command, 0, *padded))

    def acks_to(self, identity: tuple[int, int]) -> list[tuple[float, int, int, int, int]]:
        with self.lock:
            return [a for a in self.acks if (a[3], a[4]) == identity]

    # ---- the station's own thread -------------------------------------------------------------------
    def _loop(self) -> None:
        next_beat = next_param = time.monotonic()
        while self._running:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            while msg is not None:
                self._take(msg)
                msg = self.conn.recv_match(blocking=False)
            now = time.monotonic()
            if now >= next_beat:
                next_beat = now + 1.0
                self.conn.mav.send(self.conn.mav.heartbeat_encode(
                    mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))
            if now >= next_param and self.vehicle is not None:
                next_param = now + 2.0
                self.conn.mav.send(self.conn.mav.param_request_read_encode(*self.vehicle, b"", 0))

    def _take(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA" or msg.get_srcSystem() == self.identity[0]:
            return
        with self.changed:
            if kind == "HEARTBEAT" and msg.type != mavlink.MAV_TYPE_GCS and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                self.vehicle = (msg.get_srcSystem(), msg.get_srcComponent())
                self.mode = int(msg.custom_mode)
                self.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            elif kind == "COMMAND_ACK":
                self.acks.append((time.monotonic(), int(msg.command), int(msg.result),
                                  int(getattr(msg, "target_system", 0)), int(getattr(msg, "target_component", 0))))
            elif kind == "PARAM_VALUE":
                self.param_values += 1
            elif kind == "LOCAL_POSITION_NED":
                self.position = (float(msg.x), float(msg.y), float(msg.z))
            else:
                return
            self.changed.notify_all()
