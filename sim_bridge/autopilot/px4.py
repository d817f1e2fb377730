"""PX4's rules on the wire (../shared/tlogs/PX4.md is the reference for every choice here).

custom_mode = sub << 24 | main << 16. DO_SET_MODE is acknowledged twice (the mavlink module's
ACCEPTED, then commander's verdict); main mode 4 with sub 0 is Mission. OFFBOARD needs setpoints
already streaming (MAV_FRAME_LOCAL_NED or BODY_NED only); when they stop for COM_OF_LOSS_T while armed
in OFFBOARD the failsafe engages (RTL without RC, Hold with COM_OBL_RC_ACT = 5, Land with 6). Yaw is
an absolute heading in every frame and the nose is never turned toward the travel.
"""

from __future__ import annotations

import math
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.autopilot.base import FORCE_MAGIC, Autopilot, CommandContext
from sim_bridge.setpoints import FrameRules, SetpointRejected
from sim_bridge.vehicle import Behaviour, VehicleEvent

__all__ = ["PX4"]

M = mavutil
MANUAL, ALTCTL, POSCTL, AUTO, ACRO, OFFBOARD, STABILIZED = (
    M.PX4_CUSTOM_MAIN_MODE_MANUAL, M.PX4_CUSTOM_MAIN_MODE_ALTCTL, M.PX4_CUSTOM_MAIN_MODE_POSCTL,
    M.PX4_CUSTOM_MAIN_MODE_AUTO, M.PX4_CUSTOM_MAIN_MODE_ACRO, M.PX4_CUSTOM_MAIN_MODE_OFFBOARD,
    M.PX4_CUSTOM_MAIN_MODE_STABILIZED)
HOLD = (AUTO, M.PX4_CUSTOM_SUB_MODE_AUTO_LOITER)
TAKEOFF = (AUTO, M.PX4_CUSTOM_SUB_MODE_AUTO_TAKEOFF)
MISSION = (AUTO, M.PX4_CUSTOM_SUB_MODE_AUTO_MISSION)
RTL = (AUTO, M.PX4_CUSTOM_SUB_MODE_AUTO_RTL)
LAND = (AUTO, M.PX4_CUSTOM_SUB_MODE_AUTO_LAND)
OFFBOARD_MODE = (OFFBOARD, 0)
MANUAL_MAINS = frozenset({MANUAL, ALTCTL, POSCTL, ACRO, STABILIZED})
#: The names PX4 uses in "Switching to <name> is currently not available".
DISPLAY_NAMES = {HOLD: "Hold", TAKEOFF: "Takeoff", MISSION: "Mission", RTL: "Return", LAND: "Land",
                 OFFBOARD_MODE: "Offboard", (MANUAL, 0): "Manual", (ALTCTL, 0): "Altitude", (POSCTL, 0): "Position",
                 (ACRO, 0): "Acro", (STABILIZED, 0): "Stabilized"}
KNOWN_AUTO_SUBS = frozenset({2, 3, 4, 5, 6})
ARM_DENIED = "Arming denied: Resolve system health failures first\t"
#: PX4's takeoff: "Takeoff detected" came 1.56 s after the command in the SIH run.
TAKEOFF_DELAY_S = 1.0
#: Offboard-loss actions (COM_OBL_RC_ACT) that PX4 can honour without manual control.
OBL_HOLD, OBL_LAND = 5, 6


class PX4(Autopilot):
    name = "px4"
    battery_capacity_param = "BAT1_CAPACITY"
    mav_autopilot = mavlink.MAV_AUTOPILOT_PX4
    frame_rules = FrameRules(frames=frozenset({mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_NED}),
                             body_yaw_relative=False, any_bit_ignores_group=False, body_position_ignored=True)
    prearm_bit_present = False   # PX4.md: only onboard_control_sensors_health gets PREARM_CHECK when armable
    chunks_long_texts = True
    acks_on_links_that_saw_the_sender = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.mode: tuple[int, int] = HOLD
        self.failsafe_intended: tuple[int, int] | None = None
        self.last_signal_s = -math.inf
        self.signal_seen = False
        self._text_budget_s = 0.0
        super().__init__(*args, **kwargs)

    # ----------------------------------------------------------------- state
    def apply_params(self) -> None:
        p = self.params.get
        limits = self.vehicle.limits
        limits.max_speed_xy_m_s = p("MPC_XY_VEL_MAX")
        limits.max_climb_m_s = p("MPC_Z_VEL_MAX_UP")
        limits.max_descent_m_s = p("MPC_Z_VEL_MAX_DN")
        limits.takeoff_climb_m_s = p("MPC_TKO_SPEED")
        limits.takeoff_delay_s = TAKEOFF_DELAY_S
        limits.land_speed_m_s = p("MPC_LAND_SPEED")
        limits.disarm_after_land_s = p("COM_DISARM_LAND")
        limits.disarm_idle_s = p("COM_DISARM_PRFLT")
        limits.setpoint_timeout_s = None
        limits.yaw_slew_rad_s = None
        limits.auto_yaw_min_speed_m_s = math.inf
        limits.return_alt_m = p("RTL_RETURN_ALT")
        limits.return_cone_deg = p("RTL_CONE_ANG") or None
        limits.return_speed_m_s = p("MPC_XY_CRUISE")
        fence = self.vehicle.fence
        fence.radius_m = p("GF_MAX_HOR_DIST") or None
        fence.alt_max_m = p("GF_MAX_VER_DIST") or None
        fence.enabled = fence.radius_m is not None or fence.alt_max_m is not None

    @property
    def custom_mode(self) -> int:
        main, sub = self.mode
        return sub << 24 | main << 16

    def mode_name(self) -> str:
        return mavutil.interpret_px4_mode(0, self.custom_mode)

    def offboard_signal(self) -> bool:
        return self.now_s - self.last_signal_s <= self.params.get("COM_OF_LOSS_T")

    def _mode_armable(self, mode: tuple[int, int]) -> bool:
        if mode == OFFBOARD_MODE:
            return self.offboard_signal()
        return mode in (HOLD, TAKEOFF)

    def armable(self) -> bool:
        return self.booted and not self.vehicle.armed and self._mode_armable(self.mode)

    def heartbeat_fields(self) -> tuple[int, int, int]:
        main, _sub = self.mode
        if main == AUTO:
            base = 29
        elif main == OFFBOARD:
            base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
                mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED if self.signal_seen or self.vehicle.armed else 0)
        else:
            base = next((b for b, m, _s in mavutil.px4_map.values() if m == main), 81)
        if self.vehicle.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        if self.failsafe_intended is not None and self.vehicle.armed:
            status = mavlink.MAV_STATE_CRITICAL
        elif self.vehicle.armed:
            status = mavlink.MAV_STATE_ACTIVE
        elif self.booted and self._mode_armable(self.mode):
            status = mavlink.MAV_STATE_STANDBY
        else:
            status = mavlink.MAV_STATE_UNINIT
        return base, self.custom_mode, status

    def position_target(self) -> tuple | None:
        if self.mode != OFFBOARD_MODE or self.vehicle.behaviour is not Behaviour.VELOCITY:
            return None
        return self.velocity_position_target()

    # ----------------------------------------------------------------- modes
    def _switch(self, mode: tuple[int, int], failsafe: bool = False) -> None:
        if mode == self.mode:
            return
        self.mode = mode
        if not failsafe:
            self.failsafe_intended = None
        vehicle = self.vehicle
        if not vehicle.armed:
            return
        if mode == LAND:
            vehicle.land()
        elif mode == RTL:
            vehicle.return_to_launch() if not vehicle.landed else vehicle.land()
        elif mode == OFFBOARD_MODE and vehicle.setpoint is not None and self.offboard_signal():
            vehicle.follow(vehicle.setpoint, from_ground=True)
        elif mode != TAKEOFF:
            vehicle.hold()
        # no extra HEARTBEAT: PX4 reports the new mode in its next 1 Hz beat

    def request_mode(self, main: int, sub: int) -> int:
        """Commander's verdict on a mode request (the second ACK)."""
        if main == AUTO:
            mode = (AUTO, sub if sub in KNOWN_AUTO_SUBS else M.PX4_CUSTOM_SUB_MODE_AUTO_MISSION)
        elif main == OFFBOARD or main in MANUAL_MAINS:
            mode = (main, 0)
        else:
            return mavlink.MAV_RESULT_UNSUPPORTED
        if self.vehicle.armed:
            available = (self.offboard_signal() if mode == OFFBOARD_MODE
                         else mode not in (MISSION,) and main not in MANUAL_MAINS)
            if not available:
                self.out.text(mavlink.MAV_SEVERITY_CRITICAL,
                              f"Switching to {DISPLAY_NAMES.get(mode, 'mode')} is currently not available\t")
                return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        self._switch(mode)
        return mavlink.MAV_RESULT_ACCEPTED

    # ----------------------------------------------------------------- commands
    def on_command(self, ctx: CommandContext) -> list[int]:
        p = ctx.params
        cmd = ctx.command
        if cmd == mavlink.MAV_CMD_DO_SET_MODE:
            if not all(math.isfinite(v) for v in p[:3]):
                return [mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED]
            return [mavlink.MAV_RESULT_ACCEPTED, self.request_mode(int(p[1]), int(p[2]))]
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            forced = math.isfinite(p[1]) and int(round(p[1])) == FORCE_MAGIC
            return [self._arm_disarm(p[0] >= 0.5, forced)]
        if cmd == mavlink.MAV_CMD_NAV_TAKEOFF:
            return [self._takeoff(p[6])]
        if cmd == mavlink.MAV_CMD_NAV_LAND:
            if self.vehicle.armed and not self.vehicle.landed:
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Landing at current position\t")
            self._switch(LAND)
            return [mavlink.MAV_RESULT_ACCEPTED]
        if cmd == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self._start_rtl()
            return [mavlink.MAV_RESULT_ACCEPTED]
        return [mavlink.MAV_RESULT_UNSUPPORTED]

    def message_interval(self, msg_id: int, interval_us: float) -> tuple[int, float | None]:
        """MavlinkReceiver::set_message_interval: HEARTBEAT is never changed; < 0 = off, 0 = default."""
        if msg_id == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
            return mavlink.MAV_RESULT_FAILED, None
        if interval_us < -1e-5:
            return mavlink.MAV_RESULT_ACCEPTED, 0.0
        if interval_us > 1e-5:
            return mavlink.MAV_RESULT_ACCEPTED, 1e6 / interval_us
        return mavlink.MAV_RESULT_ACCEPTED, None

    def on_set_mode(self, msg: Any) -> list[int]:
        main = (msg.custom_mode >> 16) & 0xFF
        sub = (msg.custom_mode >> 24) & 0xFF
        return [self.request_mode(main, sub)]   # one ACK, commander's

    def _arm_disarm(self, arm: bool, forced: bool) -> int:
        vehicle = self.vehicle
        if not arm:
            if not vehicle.armed:
                return mavlink.MAV_RESULT_ACCEPTED
            if not vehicle.landed and not forced:
                self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed\t")
                return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            self._disarmed("Disarmed by external command\t")
            return mavlink.MAV_RESULT_ACCEPTED
        if vehicle.armed:
            return mavlink.MAV_RESULT_ACCEPTED
        if not (self.booted and self._mode_armable(self.mode)) and not forced:
            for text in (self.cold.arm_refusals(self.now_s, True) if self.cold is not None else ()):
                self.out.text(mavlink.MAV_SEVERITY_CRITICAL, text)   # "Preflight Fail: heading estimate not stable"
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL, ARM_DENIED)
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        vehicle.arm()
        self.out.text(mavlink.MAV_SEVERITY_INFO, "Armed by external command\t")
        if self.mode == TAKEOFF:
            vehicle.takeoff(self.params.get("MIS_TAKEOFF_ALT"))
        elif self.mode == OFFBOARD_MODE and vehicle.setpoint is not None:
            vehicle.follow(vehicle.setpoint, from_ground=True)
        return mavlink.MAV_RESULT_ACCEPTED

    def _disarmed(self, text: str) -> None:
        self.vehicle.disarm()
        self.out.text(mavlink.MAV_SEVERITY_INFO, text)
        if self.failsafe_intended is not None:
            self.mode = self.failsafe_intended     # PX4 goes back to the mode the user had chosen
            self.failsafe_intended = None

    def _takeoff(self, alt_amsl_param: float) -> int:
        vehicle = self.vehicle
        alt_m = alt_amsl_param - self.home[2] if math.isfinite(alt_amsl_param) else math.nan
        if not math.isfinite(alt_m) or alt_m <= 0.5:
            alt_m = self.params.get("MIS_TAKEOFF_ALT")
        self._switch(TAKEOFF)
        if vehicle.armed and vehicle.landed and vehicle.behaviour is not Behaviour.TAKEOFF:
            vehicle.takeoff(alt_m)
        elif vehicle.armed and not vehicle.landed:
            self._switch(HOLD)
        return mavlink.MAV_RESULT_ACCEPTED

    def _start_rtl(self, failsafe: bool = False) -> None:
        vehicle = self.vehicle
        flying = vehicle.armed and not vehicle.landed
        self._switch(RTL, failsafe=failsafe)
        if flying:
            above = vehicle.rtl_alt_m
            self.out.text(mavlink.MAV_SEVERITY_INFO,
                          f"RTL: start return at {self.home[2] + above:.0f} m ({above:.0f} m above destination)\t")

    # ----------------------------------------------------------------- setpoints and time
    def on_rejected_setpoint(self, rejected: SetpointRejected) -> None:
        if self.now_s < self._text_budget_s:
            return   # PX4 answers each one; gcs-sim caps these texts at 10/s so a flood cannot echo back
        self._text_budget_s = self.now_s + 0.1
        if rejected.reason == "frame":
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL,
                          f"SET_POSITION_TARGET_LOCAL_NED coordinate frame {rejected.frame} unsupported\t")
        else:
            self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "SET_POSITION_TARGET_LOCAL_NED invalid\t")

    def on_setpoint(self, msg: Any) -> None:
        if not self.params.get("MAV_FWDEXTSP"):
            return
        sp = self.decode(msg, auto_yaw=False)
        if sp is None:
            return   # a dropped setpoint is no offboard signal
        self.last_signal_s = self.now_s
        self.signal_seen = True
        if self.cold is not None and self.cold.velocity_only_sink_m_s and sp.pos_ned_m[2] is None:
            # SIH's estimator on velocity-only setpoints: the height is not held (PX4.md)
            vel = sp.vel_ned_m_s
            sp.vel_ned_m_s = (vel[0], vel[1], vel[2] + self.cold.velocity_only_sink_m_s)
        self.vehicle.setpoint = sp
        if self.mode == OFFBOARD_MODE and self.vehicle.armed:
            self.vehicle.follow(sp, from_ground=True)

    def update(self, events: list[VehicleEvent]) -> None:
        super().update(events)
        vehicle = self.vehicle
        for event in events:
            if event is VehicleEvent.LIFTOFF and self.mode == TAKEOFF:
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Takeoff detected\t")
            elif event is VehicleEvent.TAKEOFF_DONE and self.mode == TAKEOFF:
                self._switch(HOLD)
            elif event is VehicleEvent.RTL_LANDING:
                self.out.text(mavlink.MAV_SEVERITY_INFO, "RTL: land at destination\t")
            elif event is VehicleEvent.TOUCHDOWN and vehicle.behaviour in (Behaviour.LAND, Behaviour.RTL):
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Landing detected\t")
            elif event is VehicleEvent.DISARMED_LANDED:
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Disarmed by landing\t")
                if self.failsafe_intended is not None:
                    self.mode, self.failsafe_intended = self.failsafe_intended, None
            elif event is VehicleEvent.DISARMED_IDLE:
                self.out.text(mavlink.MAV_SEVERITY_INFO, "Disarmed by auto preflight disarming\t")
        if self.mode == OFFBOARD_MODE and vehicle.armed and not self.offboard_signal():
            self._offboard_lost()

    def _offboard_lost(self) -> None:
        self.out.text(mavlink.MAV_SEVERITY_CRITICAL, "Failsafe activated\t")
        self.failsafe_intended = self.mode
        action = int(self.params.get("COM_OBL_RC_ACT"))
        if action == OBL_HOLD:
            self._switch(HOLD, failsafe=True)
        elif action == OBL_LAND:
            self._switch(LAND, failsafe=True)
        else:
            self._start_rtl(failsafe=True)   # Position/Altitude/Manual need RC; without it PX4 falls to RTL
