"""High-level flight operations over a LinkChannel, with each autopilot's rules (see ../shared/tlogs).

Each returns an OperationResult: accepted, refused (with the COMMAND_ACK result and the vehicle's
STATUSTEXTs) or timed out. A mode counts only when the HEARTBEAT shows it, because PX4 ACKs DO_SET_MODE
twice and its first ACK is always ACCEPTED. They run in the caller's thread and use the channel only
through its public side (``state``, ``wait_for``, ``send``, ``collect_acks``, the stream).
"""

from __future__ import annotations

import time

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.acks import ACCEPTED, REFUSED, TIMED_OUT, AckCollector, OperationResult, command_name
from gcs_voice.link.channel import LinkChannel, SetpointSource
from gcs_voice.link.readiness import HOME, READY, SET_MODE, WAIT, Readiness, ReadinessRules, assess, load_rules, next_step
from gcs_voice.link.state import CommandAck, VehicleState

__all__ = ["FlightOperations"]

_NAN = float("nan")
#: HEARTBEAT.type values this bridge flies (its modes and setpoints are the copter ones)
MULTICOPTER_TYPES = frozenset({
    mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_TYPE_HEXAROTOR, mavlink.MAV_TYPE_OCTOROTOR, mavlink.MAV_TYPE_TRICOPTER,
    mavlink.MAV_TYPE_COAXIAL, mavlink.MAV_TYPE_HELICOPTER, mavlink.MAV_TYPE_DODECAROTOR, mavlink.MAV_TYPE_DECAROTOR,
})
#: EKF_STATUS_REPORT is in ArduPilot's dialect, not in common
MSG_ID_EKF_STATUS_REPORT = 193
#: after a refusal, texts that explain it may still be on their way
_REASON_GRACE_S = 0.25


class FlightOperations:
    """Mode, arm, take-off, land, disarm and telemetry requests for the vehicle on one ``LinkChannel``."""

    def __init__(self, link: LinkChannel) -> None:
        self.link = link
        self.settings = link.settings
        self.readiness_rules: ReadinessRules = load_rules()
        #: set once telemetry was asked for: a vehicle heard again after a loss is asked again
        self.telemetry_requested = False

    # ---- commands -------------------------------------------------------------------------------
    def _command(self, command: int, params: tuple[float, ...], settle_s: float = 0.0,
                 retries: int | None = None) -> tuple[CommandAck | None, AckCollector]:
        """Send COMMAND_LONG (with retries) and wait for its ACK; with ``settle_s`` take the last ACK in that window."""
        state = self.link.state
        with self.link.collect_acks() as collector:
            ack: CommandAck | None = None
            for confirmation in range((self.settings.command_retries if retries is None else retries) + 1):
                padded = (list(params) + [0.0] * 7)[:7]
                self.link.send(self.link.mav.command_long_encode(
                    state.system_id or 1, state.component_id or 1, command, confirmation, *padded))
                got = self.link.wait_for(lambda _s: bool(collector.acks_for(command)),
                                         self.settings.command_timeout_s)
                if got is not None:
                    if settle_s > 0:
                        time.sleep(settle_s)
                    ack = collector.acks_for(command)[-1]
                    break
            if ack is not None and not ack.accepted:
                time.sleep(_REASON_GRACE_S)
        return ack, collector

    def _verdict(self, operation: str, command: int, ack: CommandAck | None,
                 collector: AckCollector) -> OperationResult | None:
        """None when accepted; else the refused / timed-out result."""
        texts = tuple(t.text for t in collector.texts)
        if ack is None:
            return OperationResult(operation, TIMED_OUT, f"no COMMAND_ACK for {command_name(command)}", texts)
        if not ack.accepted:
            return OperationResult(operation, REFUSED, collector.reason(ack), texts)
        return None

    def _vehicle(self, operation: str) -> tuple[VehicleState, OperationResult | None]:
        state = self.link.state
        if state.system_id is None or not state.link_ok:
            return state, OperationResult(operation, TIMED_OUT, "no vehicle on the link")
        if state.profile is None:
            return state, OperationResult(operation, REFUSED, "not an ArduPilot or PX4 flight controller")
        if state.mav_type not in MULTICOPTER_TYPES:
            return state, OperationResult(operation, REFUSED, f"vehicle type {state.mav_type} is not a multicopter")
        return state, None

    # ---- modes ----------------------------------------------------------------------------------
    def set_mode(self, mode: str) -> OperationResult:
        operation = f"set mode {mode}"
        state, problem = self._vehicle(operation)
        if problem:
            return problem
        profile = state.profile
        try:
            params, wanted = profile.mode_params(mode), profile.custom_mode(mode)
        except KeyError:
            return OperationResult(operation, REFUSED, f"{profile.name} has no mode {mode}")
        if state.custom_mode == wanted:
            return OperationResult(operation, ACCEPTED, "already in it")
        settle = self.settings.ack_settle_s if profile.double_mode_ack else 0.0
        ack, collector = self._command(mavlink.MAV_CMD_DO_SET_MODE, params, settle)
        refused = self._verdict(operation, mavlink.MAV_CMD_DO_SET_MODE, ack, collector)
        if refused and refused.status == REFUSED:
            return refused
        seen = self.link.wait_for(lambda s: s.custom_mode == wanted, self.settings.mode_confirm_s)
        if seen is None:
            now = self.link.state.mode
            said = "; ".join(collector.warnings())
            return OperationResult(operation, REFUSED if ack else TIMED_OUT,
                                   f"HEARTBEAT still shows {now}" + (f": {said}" if said else ""))
        return OperationResult(operation, ACCEPTED)

    def set_velocity_mode(self, source: SetpointSource | None = None) -> OperationResult:
        """GUIDED (ArduPilot) or OFFBOARD (PX4, after streaming setpoints for ``offboard_prestream_s``)."""
        state, problem = self._vehicle("velocity control")
        if problem:
            return problem
        if state.profile.needs_prestream:
            if source is not None or not self.link.streaming:
                self.link.start_stream(source)
            time.sleep(self.settings.offboard_prestream_s)
        return self.set_mode(state.profile.velocity_mode)

    # ---- arming ---------------------------------------------------------------------------------
    @property
    def ready_timeout_s(self) -> float:
        """How long ``arm`` waits, by default, for the vehicle to become ready and armed."""
        return self.settings.arm_timeout_s

    def readiness(self) -> Readiness:
        """What the vehicle still lacks before it can be armed (its own signals; see ``link.readiness``)."""
        return assess(self.link.state)

    def arm(self, timeout_s: float | None = None) -> OperationResult:
        """Arm in the arming mode (GUIDED / Hold) as a ground station would, within ``timeout_s``.

        Loops on ``readiness.next_step``: waits while the vehicle boots or says it is not ready (saying
        what it waits for, once per change), asks for the arming mode again whenever the HEARTBEAT shows
        another one, and sends ARM only when the vehicle is ready and the mode has settled. A refused ARM
        is retried every ``arm_retry_s``; armed in another mode (a race with the vehicle's own mode
        change) sets the mode again, or disarms when that is refused.
        """
        state, problem = self._vehicle("arm")
        if problem:
            return problem
        if state.armed:   # e.g. "arm" heard in flight: leave the mode alone (PX4 flies OFFBOARD, not Hold)
            return OperationResult("arm", ACCEPTED, "already armed")
        rules = self.readiness_rules
        deadline = time.monotonic() + (self.ready_timeout_s if timeout_s is None else timeout_s)
        said, last, next_home_request = "", None, time.monotonic()
        while True:
            state = self.link.state
            if not state.link_ok:
                return OperationResult("arm", TIMED_OUT, "link lost while arming")
            if not self.link.running:   # the link is closing (end of session): arm nothing
                return OperationResult("arm", TIMED_OUT, "link closed while waiting to arm")
            now = time.monotonic()
            step = next_step(state, now, rules)
            if step.action == READY:
                return OperationResult("arm", ACCEPTED, "" if last is None else "after waiting",
                                       last.texts if last else ())
            if step.why != said:
                said = step.why
                self.link.on_event(step.why if step.action == WAIT else f"{step.action}: {step.why}")
            if step.action == WAIT:
                if HOME in assess(state).waiting_for and now >= next_home_request:
                    next_home_request = now + rules.home_request_s
                    self.link.send(self.link.mav.command_long_encode(
                        state.system_id, state.component_id or 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                        float(mavlink.MAVLINK_MSG_ID_HOME_POSITION), 0, 0, 0, 0, 0, 0))
                left = deadline - now
                if left <= 0:
                    return OperationResult("arm", TIMED_OUT, f"the vehicle did not become ready: {step.why}")
                self.link.wait_for(lambda s, step=step: next_step(s, time.monotonic(), rules) != step, min(left, 0.5))
                continue
            if step.action == SET_MODE:
                result = self.set_mode(step.mode)
                if not result.ok:
                    if state.armed:  # armed outside the arming mode and cannot get out of it: disarm
                        self.disarm()
                        return OperationResult("arm", REFUSED, f"armed in {state.mode} and {result}; disarmed",
                                               result.texts)
                    last = result
                    self.link.on_event(str(result))
                else:
                    continue
            else:  # ARM
                last = self._arm_once()
                if last.ok:
                    continue
                self.link.on_event(str(last))
            wait_s = min(self.settings.arm_retry_s, deadline - time.monotonic())
            if wait_s <= 0:
                return last if last is not None else OperationResult("arm", TIMED_OUT, step.why)
            time.sleep(wait_s)

    def _arm_once(self) -> OperationResult:
        """One COMPONENT_ARM_DISARM(1); accepted only when the HEARTBEAT shows armed."""
        ack, collector = self._command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,))
        refused = self._verdict("arm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, ack, collector)
        if refused is not None:
            return refused
        if self.link.wait_for(lambda s: bool(s.armed), self.settings.mode_confirm_s):
            return OperationResult("arm", ACCEPTED, "", tuple(t.text for t in collector.texts))
        return OperationResult("arm", TIMED_OUT, "ACK accepted but HEARTBEAT never showed armed")

    def disarm(self) -> OperationResult:
        state, problem = self._vehicle("disarm")
        if problem:
            return problem
        if state.armed is False:
            self.link.stop_stream()
            return OperationResult("disarm", ACCEPTED, "already disarmed")
        ack, collector = self._command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.0,))
        refused = self._verdict("disarm", mavlink.MAV_CMD_COMPONENT_ARM_DISARM, ack, collector)
        if refused:  # e.g. in flight: keep streaming, or the vehicle would brake / fail safe
            return refused
        self.link.stop_stream()
        if self.link.wait_for(lambda s: s.armed is False, self.settings.mode_confirm_s) is None:
            return OperationResult("disarm", TIMED_OUT, "HEARTBEAT still shows armed")
        return OperationResult("disarm", ACCEPTED)

    # ---- take-off and landing -------------------------------------------------------------------
    def takeoff(self, altitude_m: float, source: SetpointSource | None = None) -> OperationResult:
        """Arm and climb to ``altitude_m`` above home, then stream setpoints in the velocity mode.

        ArduCopter: GUIDED, arm, NAV_TAKEOFF(param7 = metres above home); nothing is streamed during
        the climb (a velocity setpoint would end the take-off). PX4: Hold, arm, NAV_TAKEOFF(param7 =
        home AMSL + metres), then stream and switch to OFFBOARD.
        """
        operation = f"take off to {altitude_m:g} m"
        state, problem = self._vehicle(operation)
        if problem:
            return problem
        if not (0.0 < altitude_m <= self.settings.ceiling_m):
            return OperationResult(operation, REFUSED, f"altitude must be in (0, {self.settings.ceiling_m:g}] m")
        airborne = state.landed_state == "IN_AIR" or (state.landed_state is None and (state.height_m or 0.0) > 1.0)
        if state.armed and airborne:
            return OperationResult(operation, REFUSED, "already flying")
        profile = state.profile
        self.link.stop_stream()
        step = self.arm()   # waits for readiness, sets and keeps the arming mode
        if not step.ok:
            return OperationResult(operation, step.status, str(step), step.texts)
        # ArduCopter resets the mode when its initialisation ends (3 s after boot) or from the RC switch:
        # check again, armed, before the take-off (GUIDED may be entered armed on the ground).
        step = self.set_mode(profile.arm_mode)
        if not step.ok:
            return OperationResult(operation, step.status, str(step), step.texts)
        param7 = altitude_m
        if profile.takeoff_alt_is_amsl:
            home = self.link.state.home_amsl_m
            if home is None:
                self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(mavlink.MAVLINK_MSG_ID_HOME_POSITION),))
                got = self.link.wait_for(lambda s: s.home_amsl_m is not None, 2.0)
                home = got.home_amsl_m if got else None
            if home is None:
                return OperationResult(operation, REFUSED, "home altitude unknown (no HOME_POSITION)")
            param7 = home + altitude_m
        ack, collector = self._command(mavlink.MAV_CMD_NAV_TAKEOFF, (0.0, 0.0, 0.0, _NAN, _NAN, _NAN, param7))
        refused = self._verdict(operation, mavlink.MAV_CMD_NAV_TAKEOFF, ack, collector)
        if refused:
            return refused
        target_m = altitude_m * self.settings.takeoff_reached_fraction
        reached = self.link.wait_for(lambda s: (s.height_m or 0.0) >= target_m or not s.link_ok,
                                self.settings.takeoff_timeout_s)
        if reached is None or not reached.link_ok:
            return OperationResult(operation, TIMED_OUT, f"height {self.link.state.height_m} m after "
                                   f"{self.settings.takeoff_timeout_s:g} s")
        if profile.needs_prestream:
            step = self.set_velocity_mode(source)
            if not step.ok:
                return OperationResult(operation, step.status, str(step), step.texts)
        else:
            self.link.start_stream(source)
        return OperationResult(operation, ACCEPTED, f"{reached.height_m:.2f} m")

    def land(self) -> OperationResult:
        """NAV_LAND at the current position; the stream stops once it is accepted (both land on their own)."""
        state, problem = self._vehicle("land")
        if problem:
            return problem
        ack, collector = self._command(mavlink.MAV_CMD_NAV_LAND, (0.0, 0.0, 0.0, _NAN, _NAN, _NAN, _NAN))
        refused = self._verdict("land", mavlink.MAV_CMD_NAV_LAND, ack, collector)
        if refused:  # keep streaming: without setpoints PX4 fails safe (RTL) and ArduCopter brakes
            return refused
        self.link.stop_stream()  # LAND ignores setpoints on both autopilots
        wanted = state.profile.custom_mode(state.profile.land_mode)
        if self.link.wait_for(lambda s: s.custom_mode == wanted, self.settings.mode_confirm_s) is None:
            return OperationResult("land", TIMED_OUT, f"HEARTBEAT still shows {self.link.state.mode}")
        return OperationResult("land", ACCEPTED)

    def return_to_launch(self) -> OperationResult:
        """NAV_RETURN_TO_LAUNCH: the autopilot's own return (climb to its return altitude, fly home, land); the
        stream stops once the HEARTBEAT shows RTL (both ignore setpoints in it)."""
        state, problem = self._vehicle("return to launch")
        if problem:
            return problem
        ack, collector = self._command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, ())
        refused = self._verdict("return to launch", mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, ack, collector)
        if refused:  # keep streaming: the vehicle is still ours and holding
            return refused
        wanted = state.profile.custom_mode("RTL")
        if self.link.wait_for(lambda s: s.custom_mode == wanted, self.settings.mode_confirm_s) is None:
            return OperationResult("return to launch", TIMED_OUT, f"HEARTBEAT still shows {self.link.state.mode}")
        self.link.stop_stream()
        return OperationResult("return to launch", ACCEPTED)

    # ---- telemetry ------------------------------------------------------------------------------
    def request_telemetry(self) -> OperationResult:
        """SET_MESSAGE_INTERVAL for what the bridge reads; REQUEST_DATA_STREAM when any is not accepted."""
        state, problem = self._vehicle("request telemetry")
        if problem:
            return problem
        wanted = {
            mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self.settings.local_position_ned_hz,
            mavlink.MAVLINK_MSG_ID_ATTITUDE: self.settings.attitude_hz,
            mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self.settings.extended_sys_state_hz,
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self.settings.global_position_int_hz,
        }
        refused: list[str] = []
        for message_id, rate_hz in wanted.items():
            ack, _ = self._command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (float(message_id), 1e6 / rate_hz),
                                   retries=0)
            if ack is None or not ack.accepted:
                refused.append(str(message_id))
        # optional: a downward rangefinder, fast enough for the floor rule (refused or absent is fine)
        self._command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (float(mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR),
                                                             1e6 / self.settings.local_position_ned_hz), retries=0)
        # the readiness signals (link.readiness): SYS_STATUS's PREARM_CHECK bit, and ArduPilot's EKF flags;
        # ArduCopter streams neither unasked, PX4 sends SYS_STATUS anyway and has no EKF_STATUS_REPORT
        readiness = [mavlink.MAVLINK_MSG_ID_SYS_STATUS]
        if state.profile is not None and not state.profile.needs_prestream:
            readiness.append(MSG_ID_EKF_STATUS_REPORT)
        for message_id in readiness:
            self._command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                          (float(message_id), 1e6 / self.settings.extended_sys_state_hz), retries=0)
        self._command(mavlink.MAV_CMD_REQUEST_MESSAGE, (float(mavlink.MAVLINK_MSG_ID_HOME_POSITION),), retries=0)
        self.telemetry_requested = True
        if refused:
            self.link.send(self.link.mav.request_data_stream_encode(
                state.system_id, state.component_id, mavlink.MAV_DATA_STREAM_ALL, self.settings.data_stream_hz, 1))
            return OperationResult("request telemetry", REFUSED,
                                   f"SET_MESSAGE_INTERVAL not accepted for {', '.join(refused)}; "
                                   "asked REQUEST_DATA_STREAM instead")
        return OperationResult("request telemetry", ACCEPTED)
