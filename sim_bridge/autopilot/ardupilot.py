"""ArduCopter's rules on the wire (../shared/tlogs/ARDUCOPTER.md is the reference for every choice here).

Refusals are MAV_RESULT_FAILED; arm refusals carry a CRITICAL "Arm: ..." text, takeoff refusals none.
The SET_MODE message gets no COMMAND_ACK; every mode change sends an extra HEARTBEAT. GUIDED velocity
setpoints time out after GUID_TIMEOUT into a hold (mode unchanged), a body-frame yaw is relative to
the current heading, and a setpoint that ignores yaw and yaw rate turns the nose toward the travel.
"""

from __future__ import annotations

import math
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.autopilot.base import FORCE_MAGIC, INT32_MAX, INT32_MIN, Autopilot, CommandContext
from sim_bridge.setpoints import FrameRules
from sim_bridge.vehicle import Behaviour, VehicleEvent

__all__ = ["ArduCopter"]

MODE_NUMBERS: dict[str, int] = {name: number for number, name in mavutil.mode_mapping_acm.items()}
STABILIZE, ALT_HOLD, GUIDED, LOITER, RTL, LAND, POSHOLD, BRAKE = (
    MODE_NUMBERS[n] for n in ("STABILIZE", "ALT_HOLD", "GUIDED", "LOITER", "RTL", "LAND", "POSHOLD", "BRAKE"))
#: The modes gcs-sim flies; other ArduCopter modes exist but are refused as not simulated.
SIMULATED_MODES = frozenset({STABILIZE, ALT_HOLD, GUIDED, LOITER, RTL, LAND, POSHOLD, BRAKE})
ARMABLE_MODES = frozenset({STABILIZE, ALT_HOLD, GUIDED, LOITER, POSHOLD})
#: Modes in which the horizontal position controller runs: HEARTBEAT base_mode has GUIDED_ENABLED (8).
POSITION_CONTROLLED_MODES = frozenset({GUIDED, LOITER, RTL, LAND, POSHOLD, BRAKE})
ALWAYS_ON_FLAGS = (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
                   | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED)
#: Modes that need a position from the EKF: refused armed without one, and their arming checks ask for it.
NEEDS_POSITION_MODES = frozenset({GUIDED, LOITER, RTL, POSHOLD, BRAKE})
#: ArduCopter's takeoff climb seen in SITL (peak 1.23 m/s to 2 m); PILOT_SPEED_UP caps it.
TAKEOFF_CLIMB_M_S = 1.25


class ArduCopter(Autopilot):
    name = "ardupilot"
    battery_capacity_param = "BATT_CAPACITY"
    mav_autopilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    frame_rules = FrameRules(
        frames=frozenset({mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_OFFSET_NED,
                          mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_OFFSET_NED}),
        body_yaw_relative=True, any_bit_ignores_group=True, body_position_ignored=False)
    touchdown_is_a_hit = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.mode = STABILIZE
        self._resets_done = 0
        self._next_prearm_s = math.inf
        super().__init__(*args, **kwargs)

    def start_cold(self, scale: float = 1.0) -> None:
        super().start_cold(scale)
        if self.cold.prearm_report_s > 0:
            self._next_prearm_s = self.cold.prearm_report_s

    def _arm_refusals(self, mode: int) -> tuple[str, ...]:
        """The cold start's "Arm: ..." checks that fail now for ``mode`` (none without --cold-start)."""
        if self.cold is None:
            return ()
        return self.cold.arm_refusals(self.now_s, mode in NEEDS_POSITION_MODES)

    # ----------------------------------------------------------------- state
    def apply_params(self) -> None:
        p = self.params.get
        limits = self.vehicle.limits
        limits.max_speed_xy_m_s = p("WPNAV_SPEED") / 100.0
        limits.max_climb_m_s = p("WPNAV_SPEED_UP") / 100.0
        limits.max_descent_m_s = p("WPNAV_SPEED_DN") / 100.0
        limits.takeoff_climb_m_s = min(TAKEOFF_CLIMB_M_S, limits.max_climb_m_s)
        limits.takeoff_delay_s = p("MOT_SPOOL_TIME") + p("TKOFF_SLEW_TIME")
        limits.land_speed_m_s = p("LAND_SPEED") / 100.0
        limits.disarm_after_land_s = 2.0
        limits.disarm_idle_s = p("DISARM_DELAY")
        limits.setpoint_timeout_s = p("GUID_TIMEOUT")
        limits.yaw_slew_rad_s = math.radians(p("ATC_SLEW_YAW") / 100.0)
        limits.auto_yaw_min_speed_m_s = 0.05 * limits.max_speed_xy_m_s
        limits.return_alt_m = p("RTL_ALT") / 100.0
        limits.return_speed_m_s = (p("RTL_SPEED") or p("WPNAV_SPEED")) / 100.0
        fence = self.vehicle.fence
        fence.enabled = bool(p("FENCE_ENABLE"))
        fence.margin_m = p("FENCE_MARGIN")
        fence_type = int(p("FENCE_TYPE"))
        fence.alt_max_m = p("FENCE_ALT_MAX") if fence_type & 1 else None
        fence.radius_m = p("FENCE_RADIUS") if fence_type & 2 else None
        fence.box_ned_m = self.vehicle.room_box_ned_m if fence_type & 4 else None

    def mode_name(self) -> str:
        return mavutil.mode_mapping_acm.get(self.mode, str(self.mode))

    def heartbeat_fields(self) -> tuple[int, int, int]:
        base = ALWAYS_ON_FLAGS
        if self.mode in POSITION_CONTROLLED_MODES or not self.booted:   # 89 in STABILIZE during boot, as seen
            base |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.vehicle.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        if not self.booted:
            status = mavlink.MAV_STATE_BOOT
        elif not self.vehicle.armed or (self.vehicle.landed and self.vehicle.behaviour not in (Behaviour.LAND, Behaviour.RTL)):
            status = mavlink.MAV_STATE_STANDBY   # land_complete: on the ground, armed or not (LAND disarms first)
        else:
            status = mavlink.MAV_STATE_ACTIVE
        return base, self.mode, status

    def armable(self) -> bool:
        return (self.booted and not self.vehicle.armed and self.mode in ARMABLE_MODES
                and not self._arm_refusals(self.mode))

    def position_target(self) -> tuple | None:
        if self.mode != GUIDED or self.vehicle.behaviour is not Behaviour.VELOCITY:
            return None
        return self.velocity_position_target()

    def mission_items(self) -> list[Any]:
        if not self.booted:
            return []     # MISSION_COUNT 0 before home is set; then item 0 is home
        lat, lon, alt = self.home
        return [(mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT, int(round(lat * 1e7)),
                 int(round(lon * 1e7)), alt)]

    # ----------------------------------------------------------------- modes
    def set_mode(self, number: int) -> int:
        if number not in mavutil.mode_mapping_acm:
            self.out.text(mavlink.MAV_SEVERITY_WARNING, f"No such mode {number}")
            return mavlink.MAV_RESULT_FAILED
        if number not in SIMULATED_MODES:
            self.out.text(mavlink.MAV_SEVERITY_WARNING, f"Mode change failed: {mavutil.mode_mapping_acm[number]} not simulated")
            return mavlink.MAV_RESULT_FAILED
        if number == self.mode:
            return mavlink.MAV_RESULT_ACCEPTED
        if self.vehicle.armed and number in NEEDS_POSITION_MODES and not self.has_position():
            # disarmed, the mode checks are skipped (the arming checks catch it); armed, they are not
            self.out.text(mavlink.MAV_SEVERITY_WARNING,
                          f"Mode change to {mavutil.mode_mapping_acm[number]} failed: requires position")
            return mavlink.MAV_RESULT_FAILED
        self.mode = number
        self._enter_mode()
        self.out.send_heartbeat_now()
        return mavlink.MAV_RESULT_ACCEPTED

    def _enter_mode(self) -> None:
        vehicle = self.vehicle
        if not vehicle.armed:
            return
        if self.mode == LAND:
            vehicle.land()
        elif self.mode == RTL:
            vehicle.return_to_launch() if not vehicle.landed else vehicle.land()
        else:
            vehicle.hold()

    # ----------------------------------------------------------------- commands
    def on_command(self, ctx: CommandContext) -> list[int]:
        p = ctx.params
        cmd = ctx.command
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            return [self._arm_disarm(p[0] >= 0.5, int(round(p[1])) == FORCE_MAGIC if math.isfinite(p[1]) else False)]
        if cmd == mavlink.MAV_CMD_DO_SET_MODE:
            if not math.isfinite(p[0]) or not math.isfinite(p[1]) or not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                return [mavlink.MAV_RESULT_FAILED]
            return [self.set_mode(int(p[1]))]
        if cmd == mavlink.MAV_CMD_NAV_TAKEOFF:
            return [self._takeoff(p[6])]
        if cmd == mavlink.MAV_CMD_NAV_LAND:
            return [self.set_mode(LAND)]
        if cmd == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return [self.set_mode(RTL)]
        if cmd == mavlink.MAV_CMD_CONDITION_YAW:
            return [self._condition_yaw(p)]
        if cmd == mavlink.MAV_CMD_DO_FENCE_ENABLE:
            return [mavlink.MAV_RESULT_ACCEPTED if self.params.set("FENCE_ENABLE", 1 if p[0] >= 0.5 else 0)
                    else mavlink.MAV_RESULT_FAILED]
        return [mavlink.MAV_RESULT_UNSUPPORTED]

    def stream_rates(self) -> dict[str, float]:
        """``[streams]`` maps each MAVn_* rate parameter to its stream id and messages."""
        return {name: self.params.get(param) for param, group in self.streams.items() for name in group["messages"]}

    def messages_paced_by(self, param_name: str) -> list[str]:
        group = self.streams.get(param_name)
        return list(group["messages"]) if isinstance(group, dict) else []

    def on_request_data_stream(self, msg: Any) -> None:
        """Sets the MAVn_* rate parameters of the stream (0 = all); they range 0-50 Hz."""
        rate = min(float(msg.req_message_rate), 50.0) if msg.start_stop else 0.0
        for param_name, group in self.streams.items():
            if msg.req_stream_id in (0, group["stream"]):
                self.params.set(param_name, rate)

    def geofence_status(self) -> tuple[bool, bool, bool]:
        """AC_Fence: present and healthy (the capture: present=1, enabled=FENCE_ENABLE, health=1); the sim's
        fence stops the vehicle before the boundary, so it is never breached."""
        return True, self.vehicle.fence.enabled, True

    def message_interval(self, msg_id: int, interval_us: float) -> tuple[int, float | None]:
        """GCS_MAVLINK::set_message_interval: param2 read as int32; 0 = default, -1 = off, 1 ms to 60 s.

        One deliberate difference: ArduPilot would let a client silence HEARTBEAT on that link (-1) or slow
        it to once a minute; a UDP port is one link shared by every sender, so one stray client would hide the
        vehicle from the others. The sim keeps HEARTBEAT at 1 Hz (DENIED), as PX4 does. Other rates apply as
        ArduPilot's.
        """
        if msg_id == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
            return mavlink.MAV_RESULT_DENIED, None
        us = int(max(INT32_MIN, min(INT32_MAX, interval_us)))
        if us == 0:
            return mavlink.MAV_RESULT_ACCEPTED, None
        if us == -1:
            return mavlink.MAV_RESULT_ACCEPTED, 0.0
        interval_ms = 1 if us < 1000 else 60000 if us > 60_000_000 else us // 1000
        return mavlink.MAV_RESULT_ACCEPTED, 1000.0 / interval_ms

    def on_set_mode(self, msg: Any) -> list[int]:
        if msg.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            self.set_mode(int(msg.custom_mode))
        return []   # this firmware's SET_MODE handler sends no COMMAND_ACK

    def _arm_disarm(self, arm: bool, forced: bool) -> int:
        vehicle = self.vehicle
        if not arm:
            if not vehicle.armed:
                return mavlink.MAV_RESULT_ACCEPTED
            if not vehicle.landed and not forced:
                self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "Disarm: vehicle is flying")
                return mavlink.MAV_RESULT_FAILED
            vehicle.disarm()
            self.out.text(mavlink.MAV_SEVERITY_INFO, "Disarming motors")
            return mavlink.MAV_RESULT_ACCEPTED
        if vehicle.armed:
            return mavlink.MAV_RESULT_ACCEPTED
        if not self.booted:
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "Arm: System not initialised")
            return mavlink.MAV_RESULT_FAILED
        if self.mode not in ARMABLE_MODES and not forced:
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "Arm: Mode not armable")
            return mavlink.MAV_RESULT_FAILED
        refusals = () if forced else self._arm_refusals(self.mode)
        for text in refusals:
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL, text)
        if refusals:
            return mavlink.MAV_RESULT_FAILED
        vehicle.arm()
        self.out.text(mavlink.MAV_SEVERITY_INFO, "Arming motors")
        self.out.send_now(mavlink.MAVLINK_MSG_ID_HOME_POSITION)   # home is (re)set at arming
        return mavlink.MAV_RESULT_ACCEPTED

    def _takeoff(self, alt_param: float) -> int:
        vehicle = self.vehicle
        alt_m = alt_param if math.isfinite(alt_param) else 0.0
        if alt_m <= 0:
            alt_m = self.params.get("PILOT_TKOFF_ALT") / 100.0
        if self.mode != GUIDED or not vehicle.armed or not vehicle.landed or alt_m <= 0:
            return mavlink.MAV_RESULT_FAILED   # no text: the firmware says nothing either
        if vehicle.behaviour is Behaviour.TAKEOFF:
            return mavlink.MAV_RESULT_FAILED
        vehicle.takeoff(alt_m)
        return mavlink.MAV_RESULT_ACCEPTED

    def _condition_yaw(self, p: tuple[float, ...]) -> int:
        if self.mode != GUIDED or not self.vehicle.armed or self.vehicle.landed or not math.isfinite(p[0]):
            return mavlink.MAV_RESULT_FAILED
        angle = math.radians(p[0])
        if math.isfinite(p[3]) and p[3] >= 0.5:
            direction = -1.0 if math.isfinite(p[2]) and p[2] < 0 else 1.0
            target = float(self.vehicle.state.yaw_rad) + direction * angle
        else:
            target = angle
        self.vehicle.set_yaw_target(target)
        return mavlink.MAV_RESULT_ACCEPTED

    # ----------------------------------------------------------------- setpoints and time
    def on_setpoint(self, msg: Any) -> None:
        if self.mode != GUIDED:
            return   # ArduCopter drops setpoints outside GUIDED without a word
        sp = self.decode(msg, auto_yaw=self.params.get("WP_YAW_BEHAVIOR") != 0)
        if sp is not None and self.vehicle.armed:
            self.vehicle.follow(sp)

    def update(self, events: list[VehicleEvent]) -> None:
        super().update(events)
        if self.cold is not None:
            self._cold_boot_rules()
        for event in events:
            if event in (VehicleEvent.DISARMED_LANDED, VehicleEvent.DISARMED_IDLE):
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Disarming motors")
            elif event is VehicleEvent.RTL_LANDING:
                pass   # ArduCopter stays in RTL through its final descent

    def _cold_boot_rules(self) -> None:
        """End of initialisation and the RC mode switch reset the mode; the pre-arm report while not ready."""
        cold = self.cold
        resets = cold.mode_resets_s
        while self._resets_done < len(resets) and self.now_s >= resets[self._resets_done]:
            self._resets_done += 1
            if self.mode != STABILIZE and not self.vehicle.armed:
                self.mode = STABILIZE
                self._enter_mode()
                self.out.send_heartbeat_now()
        if self.now_s >= self._next_prearm_s:
            self._next_prearm_s += cold.prearm_report_s
            if self.booted and not self.vehicle.armed and self._arm_refusals(GUIDED) and cold.prearm_text:
                self.out.text(mavlink.MAV_SEVERITY_CRITICAL, cold.prearm_text)
