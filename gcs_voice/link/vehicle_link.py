"""The ground-station side of MAVLink for one vehicle: the channel, and the flight operations on it.

A :class:`VehicleLink` is the one owner of the connection (it is the :class:`LinkChannel`: reader/timer
thread, state, setpoint stream) and carries one :class:`FlightOperations` (mode, arm, take-off, land,
disarm, telemetry), which runs in the caller's thread, waits on what the reader saw, and returns an
:class:`OperationResult`; it never raises for a refusal. The operations reach the channel only through
its public methods.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from gcs_voice.link.acks import OperationResult
from gcs_voice.link.channel import LinkChannel, SetpointSource
from gcs_voice.link.operations import FlightOperations
from gcs_voice.link.readiness import Readiness, ReadinessRules
from gcs_voice.link.security import LinkSecurity
from gcs_voice.link.state import VehicleState
from gcs_voice.settings import Settings

__all__ = ["VehicleLink", "SetpointSource"]


class VehicleLink(LinkChannel):
    """``with VehicleLink("udpin:0.0.0.0:14550") as link: link.wait_vehicle(); link.takeoff(1.5)``."""

    def __init__(self, connection: str, settings: Settings | None = None, tlog_path: str | Path | None = None,
                 on_event: Callable[[str], None] | None = None, security: LinkSecurity | None = None) -> None:
        super().__init__(connection, settings, tlog_path, on_event, security)
        self.operations = FlightOperations(self)
        self.on_link_back = self._ask_telemetry_again

    def _ask_telemetry_again(self) -> None:
        """A vehicle heard again after a loss may have rebooted and forgotten our message intervals."""
        if self.operations.telemetry_requested:
            self.operations.request_telemetry()

    def connect(self, timeout_s: float = 30.0) -> VehicleState:
        """Open, wait for the vehicle and ask for the telemetry the bridge reads (one call for a CLI)."""
        if not self.running:
            self.open()
        self.wait_vehicle(timeout_s)
        result = self.request_telemetry()
        if not result.ok:
            self.on_event(str(result))
        return self.state

    # ---- the operations (gcs_voice.link.operations says how each one works) -------------------------
    @property
    def readiness_rules(self) -> ReadinessRules:
        """When the vehicle counts as ready to arm, and how long a landing may take (``readiness.toml``)."""
        return self.operations.readiness_rules

    @readiness_rules.setter
    def readiness_rules(self, rules: ReadinessRules) -> None:
        self.operations.readiness_rules = rules

    @property
    def ready_timeout_s(self) -> float:
        """How long ``arm`` waits, by default, for the vehicle to become ready and armed."""
        return self.operations.ready_timeout_s

    def readiness(self) -> Readiness:
        """What the vehicle still lacks before it can be armed."""
        return self.operations.readiness()

    def set_mode(self, mode: str) -> OperationResult:
        """DO_SET_MODE, accepted once the HEARTBEAT shows ``mode``."""
        return self.operations.set_mode(mode)

    def set_velocity_mode(self, source: SetpointSource | None = None) -> OperationResult:
        """GUIDED (ArduPilot) or OFFBOARD (PX4, after streaming setpoints first)."""
        return self.operations.set_velocity_mode(source)

    def arm(self, timeout_s: float | None = None) -> OperationResult:
        """Arm in the arming mode once the vehicle is ready, within ``timeout_s``."""
        return self.operations.arm(timeout_s)

    def disarm(self) -> OperationResult:
        """Disarm (refused by the vehicle in flight: the stream then keeps going)."""
        return self.operations.disarm()

    def takeoff(self, altitude_m: float, source: SetpointSource | None = None) -> OperationResult:
        """Arm, climb to ``altitude_m`` above home, then stream ``source`` in the velocity mode."""
        return self.operations.takeoff(altitude_m, source)

    def land(self) -> OperationResult:
        """NAV_LAND where the vehicle is; the stream stops once it is accepted."""
        return self.operations.land()

    def return_to_launch(self) -> OperationResult:
        """The autopilot's own RTL (it flies home and lands); the stream stops once the vehicle is in it."""
        return self.operations.return_to_launch()

    def request_telemetry(self) -> OperationResult:
        """Ask for the messages the bridge reads, at the rates in the settings."""
        return self.operations.request_telemetry()
