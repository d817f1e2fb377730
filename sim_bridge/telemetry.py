"""Telemetry: one builder per message, and a schedule of how often each one goes out.

Builders read the vehicle and the personality and return an unpacked pymavlink message; the
schedule knows the interval of every message (stream defaults, REQUEST_DATA_STREAM groups and
SET_MESSAGE_INTERVAL overrides) and says which are due at a given simulated time.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

if TYPE_CHECKING:
    from sim_bridge.autopilot.base import Autopilot

__all__ = ["Schedule", "build", "BUILDERS", "message_id"]

M = mavlink
#: Sensors reported in SYS_STATUS (present, enabled and healthy): what MAVSDK's health checks read.
SENSORS = (M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL | M.MAV_SYS_STATUS_SENSOR_3D_MAG
           | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE | M.MAV_SYS_STATUS_SENSOR_GPS
           | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | M.MAV_SYS_STATUS_AHRS | M.MAV_SYS_STATUS_SENSOR_BATTERY)


def message_id(name: str) -> int:
    """MAVLink message id by name (``ATTITUDE`` -> 30); KeyError names the unknown message."""
    return getattr(M, f"MAVLINK_MSG_ID_{name}")


def _int16(value: float) -> int:
    return int(max(-32768, min(32767, round(value))))


def _heading_cdeg(yaw_rad: float) -> int:
    return int(round(math.degrees(yaw_rad) * 100.0)) % 36000


def _heartbeat(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    base_mode, custom_mode, system_status = ap.heartbeat_fields()
    return mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, ap.mav_autopilot, base_mode, custom_mode, system_status, 3)


def _sys_status(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    fence_present, fence_enabled, fence_healthy = ap.geofence_status()
    fence = M.MAV_SYS_STATUS_GEOFENCE
    prearm = M.MAV_SYS_STATUS_PREARM_CHECK if ap.prearm_bit_present else 0
    present = SENSORS | prearm | (fence if fence_present else 0)
    enabled = SENSORS | prearm | (fence if fence_enabled else 0)
    health = SENSORS | (M.MAV_SYS_STATUS_PREARM_CHECK if ap.armable() else 0) | (fence if fence_healthy else 0)
    capacity = ap.battery_capacity_mah()
    return mav.sys_status_encode(present, enabled, health, 200, ap.battery.voltage_mv(capacity),
                                 _int16(ap.battery.current_a * 100), ap.battery_remaining_pct(), 0, 0, 0, 0, 0, 0)


def _attitude(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    s = ap.vehicle.state
    return mav.attitude_encode(ap.time_boot_ms(), s.roll_rad, s.pitch_rad, s.yaw_rad,
                               getattr(s, "roll_rate_rad_s", 0.0), getattr(s, "pitch_rate_rad_s", 0.0),
                               getattr(s, "yaw_rate_rad_s", 0.0))


def _local_position_ned(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message | None:
    if not ap.has_position():
        return None   # ArduCopter sends no LOCAL_POSITION_NED before its EKF has a position
    s = ap.vehicle.state
    p, v = s.pos_ned_m, s.vel_ned_m_s
    return mav.local_position_ned_encode(ap.time_boot_ms(), p[0], p[1], p[2], v[0], v[1], v[2])


def _global_position_int(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    s = ap.vehicle.state
    v = s.vel_ned_m_s
    return mav.global_position_int_encode(ap.time_boot_ms(), int(round(s.lat_deg * 1e7)), int(round(s.lon_deg * 1e7)),
                                          int(round(s.alt_amsl_m * 1000)), int(round(-s.pos_ned_m[2] * 1000)),
                                          _int16(v[0] * 100), _int16(v[1] * 100), _int16(v[2] * 100),
                                          _heading_cdeg(s.yaw_rad))


def _gps_raw_int(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    s = ap.vehicle.state
    v = s.vel_ned_m_s
    speed = math.hypot(v[0], v[1])
    cog = int(round(math.degrees(math.atan2(v[1], v[0])) * 100)) % 36000 if speed > 0.2 else 65535
    return mav.gps_raw_int_encode(ap.time_unix_usec(), ap.identity.get("gps_fix_type", 3),
                                  int(round(s.lat_deg * 1e7)), int(round(s.lon_deg * 1e7)),
                                  int(round(s.alt_amsl_m * 1000)), 121, 200, int(round(speed * 100)), cog, 10)


def _vfr_hud(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    s = ap.vehicle.state
    v = s.vel_ned_m_s
    speed = math.hypot(v[0], v[1])
    throttle = int(round(100 * float(getattr(s, "throttle", 0.0))))
    return mav.vfr_hud_encode(speed, speed, int(math.degrees(s.yaw_rad)) % 360, max(0, min(100, throttle)),
                              s.alt_amsl_m, -v[2])


def _extended_sys_state(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    return mav.extended_sys_state_encode(ap.identity.get("vtol_state", 0), ap.vehicle.landed_state())


def _home_position(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    lat, lon, alt = ap.home
    return mav.home_position_encode(int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000)),
                                    0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, ap.time_unix_usec())


def _autopilot_version(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    ident = ap.identity
    custom = list(bytes.fromhex(ident["flight_custom_version_hex"]))[:8]
    return mav.autopilot_version_encode(ident["capabilities"], ident["flight_sw_version"], 0, 0, 0, custom,
                                        [0] * 8, [0] * 8, 0, 0, ident.get("uid", 0))


def _position_target_local_ned(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message | None:
    target = ap.position_target()
    if target is None:
        return None
    type_mask, pos, vel, yaw, yaw_rate = target
    return mav.position_target_local_ned_encode(ap.time_boot_ms(), M.MAV_FRAME_LOCAL_NED, type_mask, *pos, *vel,
                                                0.0, 0.0, 0.0, yaw, yaw_rate)


def _mission_current(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    return mav.mission_current_encode(0, 0, M.MISSION_STATE_NO_MISSION, 0)


def _system_time(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    return mav.system_time_encode(ap.time_unix_usec(), ap.time_boot_ms())


def _battery_status(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    capacity = ap.battery_capacity_mah()
    battery = ap.battery
    cells = [battery.cell_mv(capacity)] * battery.spec.cells + [65535] * (10 - battery.spec.cells)
    return mav.battery_status_encode(0, M.MAV_BATTERY_FUNCTION_UNKNOWN, M.MAV_BATTERY_TYPE_LIPO, 32767, cells,
                                     _int16(battery.current_a * 100), int(battery.consumed_mah), -1,
                                     ap.battery_remaining_pct())


def _ekf_status_report(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    return mav.ekf_status_report_encode(ap.ekf_flags(), 0.01, 0.01, 0.01, 0.01, 0.0)


def _altitude(ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message:
    s = ap.vehicle.state
    rel = -float(s.pos_ned_m[2])
    return mav.altitude_encode(ap.time_unix_usec(), s.alt_amsl_m, s.alt_amsl_m, -float(s.pos_ned_m[2]), rel,
                               float("nan"), rel)


Builder = Callable[["Autopilot", M.MAVLink], "M.MAVLink_message | None"]
BUILDERS: dict[int, Builder] = {
    message_id("HEARTBEAT"): _heartbeat,
    message_id("SYS_STATUS"): _sys_status,
    message_id("ATTITUDE"): _attitude,
    message_id("LOCAL_POSITION_NED"): _local_position_ned,
    message_id("GLOBAL_POSITION_INT"): _global_position_int,
    message_id("GPS_RAW_INT"): _gps_raw_int,
    message_id("VFR_HUD"): _vfr_hud,
    message_id("EXTENDED_SYS_STATE"): _extended_sys_state,
    message_id("HOME_POSITION"): _home_position,
    message_id("AUTOPILOT_VERSION"): _autopilot_version,
    message_id("POSITION_TARGET_LOCAL_NED"): _position_target_local_ned,
    message_id("MISSION_CURRENT"): _mission_current,
    message_id("SYSTEM_TIME"): _system_time,
    message_id("BATTERY_STATUS"): _battery_status,
    message_id("EKF_STATUS_REPORT"): _ekf_status_report,
    message_id("ALTITUDE"): _altitude,
}


def build(msg_id: int, ap: "Autopilot", mav: M.MAVLink) -> M.MAVLink_message | None:
    """The message ``msg_id`` as the vehicle would send it now, or None if it has nothing to say."""
    builder = BUILDERS.get(msg_id)
    return None if builder is None else builder(ap, mav)


class Schedule:
    """Intervals per message id: defaults from the personality, overrides from the ground station."""

    def __init__(self) -> None:
        self._default_hz: dict[int, float] = {}
        self._override_hz: dict[int, float] = {}
        self._next_s: dict[int, float] = {}
        self._period_s: dict[int, float] = {}

    def set_default(self, msg_id: int, rate_hz: float) -> None:
        self._default_hz[msg_id] = rate_hz
        self._refresh(msg_id)

    def set_override(self, msg_id: int, rate_hz: float | None) -> None:
        """``None`` = back to the default; 0 = off."""
        if rate_hz is None:
            self._override_hz.pop(msg_id, None)
        else:
            self._override_hz[msg_id] = rate_hz
        self._refresh(msg_id)

    def rate_hz(self, msg_id: int) -> float:
        return self._override_hz.get(msg_id, self._default_hz.get(msg_id, 0.0))

    def _refresh(self, msg_id: int) -> None:
        rate = self.rate_hz(msg_id)
        if rate > 0:
            self._period_s[msg_id] = 1.0 / rate
            self._next_s.setdefault(msg_id, 0.0)
        else:
            self._period_s.pop(msg_id, None)
            self._next_s.pop(msg_id, None)

    def due(self, now_s: float) -> list[int]:
        """Message ids due at ``now_s``; each is rescheduled one period later (no catch-up bursts)."""
        due = []
        for msg_id, next_s in self._next_s.items():
            if now_s + 1e-9 >= next_s:
                due.append(msg_id)
                period = self._period_s[msg_id]
                self._next_s[msg_id] = next_s + period if now_s - next_s < period else now_s + period
        return due
