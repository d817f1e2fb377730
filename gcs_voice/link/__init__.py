"""The ground-station side of MAVLink: connection strings, vehicle state, setpoints, and the link itself."""

from gcs_voice.link.acks import ACCEPTED, REFUSED, TIMED_OUT, OperationResult
from gcs_voice.link.connection import parse_connection, udp_listen
from gcs_voice.link.setpoints import Setpoint
from gcs_voice.link.state import VehicleState, VehicleStateTracker
from gcs_voice.link.vehicle_link import VehicleLink

__all__ = ["ACCEPTED", "REFUSED", "TIMED_OUT", "OperationResult", "Setpoint", "VehicleLink", "VehicleState",
           "VehicleStateTracker", "parse_connection", "udp_listen"]
