"""A scripted MAVLink vehicle on 127.0.0.1 for the link's wire tests (until/besides the real simulator).

It answers the way the captured SITLs did (../shared/tlogs): ArduCopter ACKs once and refuses ARM a
given number of times with "Arm: ..." texts; PX4 ACKs DO_SET_MODE twice (first always ACCEPTED) and
refuses OFFBOARD unless setpoints arrived in the last 0.5 s. Its height follows NAV_TAKEOFF/NAV_LAND.
Everything the link sends is recorded with its arrival time, so tests assert on the wire.
"""

from __future__ import annotations

import math
import os
import threading
import time
from typing import Any

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

from gcs_voice.session.sim_process import free_udp_port  # noqa: E402

PX4_OFFBOARD = 393216
PX4_HOLD = 50593792
PX4_LAND = 100925440
HOME_AMSL_M = 488.0


class ScriptedVehicle:
    def __init__(self, autopilot: str = "ardupilot", arm_refusals: int = 0, heading_deg: float = 0.0,
                 mav_type: int = mavlink.MAV_TYPE_QUADROTOR, mode_after_arm: int | None = None,
                 custom_mode: int | None = None) -> None:
        self.port = free_udp_port()
        self.px4 = autopilot == "px4"
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=1, source_component=1,
                                               dialect="ardupilotmega")
        self.custom_mode = custom_mode if custom_mode is not None else (PX4_HOLD if self.px4 else 0)
        self.armed = False
        self.arm_refusals = arm_refusals
        self.height_m = 0.0
        self.target_height_m = 0.0
        self.heading_deg = heading_deg
        self.sending = True
        self._sender = (255, 190)  # whoever sent the last COMMAND_LONG: its ACKs go back to it
        self.mav_type = mav_type
        self.mode_after_arm = mode_after_arm  # e.g. ArduCopter's RC switch putting STABILIZE back
        self.received: list[tuple[float, Any]] = []
        self.lock = threading.Lock()
        self._running = True
        self._thread = threading.Thread(target=self._loop, daemon=True)

    @property
    def connection(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    def __enter__(self) -> "ScriptedVehicle":
        self._thread.start()
        return self

    def __exit__(self, *_exc: Any) -> None:
        self._running = False
        self._thread.join(timeout=2)
        self.conn.close()

    def messages(self, kind: str) -> list[tuple[float, Any]]:
        with self.lock:
            return [(t, m) for t, m in self.received if m.get_type() == kind]

    def send_raw(self, data: bytes) -> None:
        self.conn.write(data)

    def _send(self, msg: Any) -> None:
        if self.sending:
            self.conn.mav.send(msg)

    def _loop(self) -> None:
        next_beat = next_telemetry = 0.0
        while self._running:
            msg = self.conn.recv_match(blocking=True, timeout=0.01)
            while msg is not None:
                if msg.get_type() != "BAD_DATA":
                    with self.lock:
                        self.received.append((time.monotonic(), msg))
                    if msg.get_type() == "COMMAND_LONG":
                        self._sender = (msg.get_srcSystem(), msg.get_srcComponent())
                        self._command(msg)
                msg = self.conn.recv_match(blocking=False)
            now = time.monotonic()
            if now >= next_telemetry:
                next_telemetry = now + 0.1
                self._telemetry()
            if now >= next_beat:
                next_beat = now + 1.0
                self._heartbeat()

    def _heartbeat(self) -> None:
        autopilot = mavlink.MAV_AUTOPILOT_PX4 if self.px4 else mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        self._send(self.conn.mav.heartbeat_encode(self.mav_type, autopilot, base, self.custom_mode,
                                                  mavlink.MAV_STATE_STANDBY))

    def _telemetry(self) -> None:
        step = max(-0.5, min(0.5, self.target_height_m - self.height_m))  # 5 m/s at 10 Hz: quick tests
        self.height_m += step
        if self.height_m <= 0.0 and self.custom_mode in (9, PX4_LAND):
            self.armed = False
        self._send(self.conn.mav.local_position_ned_encode(0, 0.0, 0.0, -self.height_m, 0.0, 0.0, 0.0))
        self._send(self.conn.mav.attitude_encode(0, 0.0, 0.0, math.radians(self.heading_deg), 0.0, 0.0, 0.0))
        landed = mavlink.MAV_LANDED_STATE_IN_AIR if self.height_m > 0.2 else mavlink.MAV_LANDED_STATE_ON_GROUND
        self._send(self.conn.mav.extended_sys_state_encode(0, landed))

    def _ack(self, command: int, result: int) -> None:
        # addressed back to the sender, as ArduCopter and PX4 do (../shared/tlogs/ARDUCOPTER.md)
        self._send(self.conn.mav.command_ack_encode(command, result, 0, 0, *self._sender))

    def _text(self, severity: int, text: str) -> None:
        self._send(self.conn.mav.statustext_encode(severity, text.encode()))

    def _setpoints_recent(self) -> bool:
        cutoff = time.monotonic() - 0.5
        return any(t > cutoff for t, _ in self.messages("SET_POSITION_TARGET_LOCAL_NED"))

    def _command(self, msg: Any) -> None:
        cmd = msg.command
        if cmd == mavlink.MAV_CMD_DO_SET_MODE:
            if self.px4:
                self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)  # mavlink module's own ACK
                wanted = int(msg.param3) << 24 | int(msg.param2) << 16
                if wanted == PX4_OFFBOARD and not self._setpoints_recent():
                    self._ack(cmd, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
                    self._text(2, "Switching to Offboard is currently not available\t")
                    return
                self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
                self.custom_mode = wanted
            else:
                self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
                self.custom_mode = int(msg.param2)
            self._heartbeat()
        elif cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 0 and self.height_m > 0.2:  # autopilots refuse to disarm in flight (unless forced)
                self._ack(cmd, mavlink.MAV_RESULT_FAILED)
            elif msg.param1 == 0:
                self.armed = False
                self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
            elif self.px4 and self.custom_mode == PX4_OFFBOARD and not self._setpoints_recent():
                self._ack(cmd, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)  # EVENT "No offboard signal"
                self._text(2, "Arming denied: Resolve system health failures first\t")
            elif self.arm_refusals > 0:
                self.arm_refusals -= 1
                self._text(2, "Arm: Need Position Estimate")
                self._ack(cmd, mavlink.MAV_RESULT_FAILED)
            else:
                self.armed = True
                self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
                self._text(6, "Arming motors")
                if self.mode_after_arm is not None:
                    self.custom_mode, self.mode_after_arm = self.mode_after_arm, None
                    self._heartbeat()
        elif cmd == mavlink.MAV_CMD_NAV_TAKEOFF:
            ok = self.armed and math.isfinite(msg.param7)
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED if ok else mavlink.MAV_RESULT_FAILED)
            if ok:
                self.target_height_m = msg.param7 - HOME_AMSL_M if self.px4 else msg.param7
        elif cmd == mavlink.MAV_CMD_NAV_LAND:
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
            self.custom_mode = PX4_LAND if self.px4 else 9
            self.target_height_m = 0.0
            self._heartbeat()
        elif cmd == mavlink.MAV_CMD_REQUEST_MESSAGE and int(msg.param1) == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
            self._send(self.conn.mav.home_position_encode(0, 0, int(HOME_AMSL_M * 1000), 0.0, 0.0, 0.0,
                                                          [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0))
        elif cmd == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
        else:
            self._ack(cmd, mavlink.MAV_RESULT_UNSUPPORTED)
