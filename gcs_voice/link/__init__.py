"""The ground-station side of MAVLink: connection strings, vehicle state, setpoints, and the link itself.

Typical use (what the bridge does)::

    settings = load_settings(config_path, **flag_overrides)        # gcs_voice.settings
    mapper = ActionMapper(settings)                                 # gcs_voice.actions.mapper
    with VehicleLink("udpin:0.0.0.0:14550", settings, tlog_path="flight.tlog", on_event=print) as link:
        link.connect()                       # wait for a HEARTBEAT, ask for telemetry
        link.takeoff(settings.takeoff_altitude_m, source=mapper.setpoint)   # OperationResult
        mapper.reset_heading(link.state)
        link.start_stream(mapper.setpoint)   # 10 Hz from the link's thread, nothing while the link is lost
        mapper.apply("go_forward", link.state)      # the stream picks it up at the next tick
        link.land()

``arm`` and ``takeoff`` first wait for the vehicle's own readiness signals (``link.readiness``: boot,
pre-arm bit, EKF position) and keep the arming mode; ``link.readiness()`` says what it still waits for.
Operations (``set_mode``, ``set_velocity_mode``, ``arm``, ``disarm``, ``takeoff``, ``land``,
``request_telemetry``) block and return an :class:`OperationResult` (``ok``, ``status`` accepted /
refused / timed out, ``reason`` with the vehicle's words); they never raise for a refusal.
``link.state`` is a :class:`VehicleState` snapshot (``autopilot``, ``mode``, ``armed``, ``landed_state``,
``height_m``, ``heading_deg``, ``link_ok``, ...).
"""

from gcs_voice.link.acks import ACCEPTED, REFUSED, TIMED_OUT, OperationResult
from gcs_voice.link.connection import parse_connection, udp_listen
from gcs_voice.link.setpoints import Setpoint
from gcs_voice.link.state import VehicleState, VehicleStateTracker
from gcs_voice.link.vehicle_link import SetpointSource, VehicleLink

__all__ = ["ACCEPTED", "REFUSED", "TIMED_OUT", "OperationResult", "Setpoint", "SetpointSource", "VehicleLink",
           "VehicleState", "VehicleStateTracker", "parse_connection", "udp_listen"]
