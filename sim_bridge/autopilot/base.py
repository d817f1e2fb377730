"""What every personality shares: clock, home, identity data, the outbox, and the hooks the server calls.

A personality is the autopilot's *rules* (mode numbers, which commands are refused and how, what
happens when setpoints stop); ``sim_bridge.vehicle`` is the flying. The server calls ``on_command``,
``on_set_mode``, ``on_setpoint`` and ``update``; the personality answers through the ``Outbox``.
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge.autopilot.boot import ColdBoot
from sim_bridge.battery import Battery
from sim_bridge.params import ParamStore
from sim_bridge.setpoints import FrameRules, SetpointRejected, decode_setpoint
from sim_bridge.vehicle import Vehicle, VehicleEvent

__all__ = ["Autopilot", "Outbox", "CommandContext", "load_personality_data", "FORCE_MAGIC"]

#: param2 of MAV_CMD_COMPONENT_ARM_DISARM that forces arming/disarming past the checks (both autopilots).
FORCE_MAGIC = 21196
#: MESSAGE_INTERVAL.interval_us is an int32 on the wire; a float param beyond it is read as its nearest end.
INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1


class Outbox(Protocol):
    """The server side a personality talks to."""

    def send(self, msg: Any, link: Any = None) -> None: ...
    def text(self, severity: int, text: str) -> None: ...
    def send_heartbeat_now(self) -> None: ...
    def send_now(self, msg_id: int) -> None: ...


class CommandContext:
    """One COMMAND_LONG / COMMAND_INT as the personality sees it (params 1-7, who sent it, where)."""

    def __init__(self, command: int, params: tuple[float, ...], link: Any, src_system: int, src_component: int) -> None:
        self.command = command
        self.params = params
        self.link = link
        self.src_system = src_system
        self.src_component = src_component
        self.replies: list[Any] = []     # messages to send after the ACK (REQUEST_MESSAGE and the like)


def load_personality_data(name: str) -> dict:
    text = resources.files("sim_bridge").joinpath("data", f"autopilot_{name}.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


class Autopilot:
    """Base personality. Subclasses set ``mav_autopilot``, ``frame_rules`` and the mode logic."""

    name = "base"
    mav_autopilot = mavlink.MAV_AUTOPILOT_GENERIC
    frame_rules: FrameRules
    #: SYS_STATUS lists MAV_SYS_STATUS_PREARM_CHECK as present/enabled (ArduPilot); PX4 sets it only in health
    prearm_bit_present = True
    #: STATUSTEXT longer than 50 bytes: sent in chunks sharing an id (PX4), else cut at 50 (ArduPilot)
    chunks_long_texts = False
    #: a touchdown is reported as "SIM Hit ground at ..." (ArduPilot SITL does; PX4 SIH does not)
    touchdown_is_a_hit = False
    #: where the COMMAND_ACKs of the personality's own commands go. ArduPilot answers on the channel the
    #: command came in on (GCS_MAVLINK::handle_command_long). PX4's commander publishes its verdict, and
    #: every MAVLink instance sends it on its own link if the addressee (system, component) was seen
    #: there (mavlink_main.cpp, ``component_was_seen``): with QGroundControl on 14550 and an API on
    #: 14540, each hears only its own ACKs, unless both share one identity. The mavlink module's own
    #: first ACK of DO_SET_MODE stays on the receiving link.
    acks_on_links_that_saw_the_sender = False
    #: the parameter that holds the battery's capacity in mAh (sim_bridge/battery.py)
    battery_capacity_param = ""

    def __init__(self, vehicle: Vehicle, params: ParamStore, out: Outbox,
                 home: tuple[float, float, float], epoch_unix_s: float) -> None:
        self.vehicle = vehicle
        self.params = params
        self.out = out
        self.home = home
        self.epoch_unix_s = epoch_unix_s
        data = load_personality_data(self.name)
        self.identity: dict = data["identity"]
        self.boot_s = float(data["timing"]["boot_s"])
        self.texts: dict = data["texts"]
        self.streams: dict = data["streams"]
        self.rejected_setpoints = 0
        self.booted = False
        self.battery = Battery()
        self._battery_low_said = False
        self._data = data
        #: the real autopilot's boot timeline (``start_cold``), or None: ready after ``boot_s``
        self.cold: ColdBoot | None = None
        params.on_change(lambda _name, _value: self.apply_params())
        self.apply_params()

    # ----------------------------------------------------------------- time
    @property
    def now_s(self) -> float:
        return self.vehicle.time_s

    def time_boot_ms(self) -> int:
        return int(self.now_s * 1000) & 0xFFFFFFFF

    def time_unix_usec(self) -> int:
        return int((self.epoch_unix_s + self.now_s) * 1e6)

    def start_cold(self, scale: float = 1.0) -> None:
        """Boot like the real autopilot (``[cold_start]`` of the personality's TOML), times multiplied by ``scale``."""
        self.cold = ColdBoot.from_data(self._data["cold_start"], scale)
        self.boot_s = self.cold.init_end_s

    def has_position(self) -> bool:
        """The estimator has a position (always, unless a cold start is still converging)."""
        return self.cold is None or self.cold.has_position(self.now_s)

    def ekf_flags(self) -> int:
        """EKF_STATUS_REPORT.flags: ArduCopter's values before and after "EKF3 is using GPS"."""
        if self.cold is not None:
            flags = self.cold.ekf_flags(self.now_s)
            if flags is not None:
                return flags
        return 831 if self.booted and self.has_position() else 167

    # ----------------------------------------------------------------- hooks
    def apply_params(self) -> None:
        """Push parameter values into the vehicle's limits and fence."""

    def heartbeat_fields(self) -> tuple[int, int, int]:
        raise NotImplementedError

    def mode_name(self) -> str:
        raise NotImplementedError

    def armable(self) -> bool:
        return self.booted and not self.vehicle.armed

    def on_command(self, ctx: CommandContext) -> list[int]:
        """Handle a command; return the MAV_RESULT of each COMMAND_ACK to send (in order, may be empty)."""
        return [mavlink.MAV_RESULT_UNSUPPORTED]

    def on_set_mode(self, msg: Any) -> list[int]:
        """The SET_MODE message; returns the COMMAND_ACK results (for command 176) to send."""
        return []

    def on_setpoint(self, msg: Any) -> None:
        raise NotImplementedError

    def stream_rates(self) -> dict[str, float]:
        """Default rate (Hz) of each streamed message, by name: ``[streams]`` of the personality data."""
        return {name: float(rate_hz) for name, rate_hz in self.streams.items()}

    def messages_paced_by(self, param_name: str) -> list[str]:
        """Messages whose rate a parameter sets (ArduPilot's MAVn_* groups); none by default."""
        return []

    def on_request_data_stream(self, msg: Any) -> None:
        """REQUEST_DATA_STREAM; ignored by default (PX4: deprecated, does nothing)."""

    def geofence_status(self) -> tuple[bool, bool, bool]:
        """SYS_STATUS geofence bit as (present, enabled, healthy); PX4's SIH capture reports none."""
        return False, False, False

    def message_interval(self, msg_id: int, interval_us: float) -> tuple[int, float | None]:
        """SET_MESSAGE_INTERVAL as this firmware reads it, for the asking link only.

        Returns (MAV_RESULT, rate in Hz): None = back to the default, 0 = off. ``interval_us`` is finite.
        """
        raise NotImplementedError

    def position_target(self) -> tuple | None:
        """(type_mask, pos, vel, yaw, yaw_rate) for POSITION_TARGET_LOCAL_NED, or None."""
        return None

    def mission_items(self) -> list[Any]:
        return []

    def battery_capacity_mah(self) -> float:
        return self.params.get(self.battery_capacity_param) if self.battery_capacity_param else 0.0

    def battery_remaining_pct(self) -> int:
        return self.battery.remaining_pct(self.battery_capacity_mah())

    def update(self, events: list[VehicleEvent]) -> None:
        self.battery.step(self.now_s, self.vehicle.armed)
        if not self._battery_low_said and self.battery_remaining_pct() < self.battery.spec.low_pct:
            self._battery_low_said = True  # once, as the autopilots warn (their failsafe action is not simulated)
            capacity = self.battery_capacity_mah()
            self.out.text(mavlink.MAV_SEVERITY_WARNING, self.texts["battery_low"].format(
                volts=self.battery.voltage_mv(capacity) / 1000.0, used_mah=self.battery.consumed_mah,
                pct=self.battery_remaining_pct()))
        if self.cold is not None:
            for line in self.cold.texts_due(self.now_s):
                self.out.text(mavlink.MAV_SEVERITY_INFO, line)
        if not self.booted and self.now_s >= self.boot_s:
            self.booted = True
            for line in self.texts.get("boot", []):
                self.out.text(mavlink.MAV_SEVERITY_INFO, line)

    # ----------------------------------------------------------------- shared helpers
    def decode(self, msg: Any, auto_yaw: bool):
        """Setpoint from ``msg`` by this personality's frame rules, or None (counted) if rejected."""
        state = self.vehicle.state
        pos = (float(state.pos_ned_m[0]), float(state.pos_ned_m[1]), float(state.pos_ned_m[2]))
        try:
            return decode_setpoint(msg, self.frame_rules, float(state.yaw_rad), pos, self.now_s, auto_yaw)
        except SetpointRejected as rejected:
            self.rejected_setpoints += 1
            self.on_rejected_setpoint(rejected)
            return None

    def on_rejected_setpoint(self, rejected: SetpointRejected) -> None:
        """ArduCopter drops bad setpoints silently; PX4 says why."""

    def velocity_position_target(self) -> tuple | None:
        """POSITION_TARGET_LOCAL_NED content from the setpoint in use (velocity targets, yaw)."""
        sp = self.vehicle.setpoint
        if sp is None:
            return None
        mask = mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE \
            | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE
        yaw = sp.yaw_rad if sp.yaw_rad is not None else float(self.vehicle.state.yaw_rad)
        yaw_rate = sp.yaw_rate_rad_s if sp.yaw_rate_rad_s is not None else 0.0
        pos = tuple(v if v is not None else math.nan for v in sp.pos_ned_m)
        return mask, pos, sp.vel_ned_m_s, yaw, yaw_rate
