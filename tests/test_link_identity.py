"""Our identity beside QGroundControl (255/190): the setting, its flags, and whose COMMAND_ACK is ours."""

from __future__ import annotations

import argparse

import pytest
from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.options import add_link_arguments, settings_from_args
from gcs_voice.link.state import VehicleStateTracker
from gcs_voice.settings import SettingsError, load_settings

VEHICLE = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def _tracker() -> VehicleStateTracker:
    tracker = VehicleStateTracker(gcs_system_id=255, gcs_component_id=231)
    beat = VEHICLE.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                    mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, mavlink.MAV_STATE_ACTIVE)
    tracker.update(_wire(beat), 0.0)
    return tracker


def _wire(msg: mavlink.MAVLink_message) -> mavlink.MAVLink_message:
    """The message as a receiver decodes it (source ids and all)."""
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(VEHICLE)))


def _ack(command: int, system: int, component: int) -> mavlink.MAVLink_message:
    return _wire(VEHICLE.command_ack_encode(command, mavlink.MAV_RESULT_ACCEPTED, 0, 0, system, component))


def test_default_identity_is_a_gcs_system_beside_qgroundcontrol() -> None:
    settings = load_settings()
    assert settings.gcs_system_id == 255   # ArduPilot's MAV_GCS_SYSID default: its GCS failsafe counts us
    assert settings.gcs_component_id not in (190, 230)   # QGroundControl / Mission Planner, MAVProxy


def test_flags_set_the_identity_and_refuse_nonsense() -> None:
    parser = argparse.ArgumentParser()
    add_link_arguments(parser)
    settings = settings_from_args(parser.parse_args(["--gcs-system-id", "254", "--gcs-component-id", "191"]))
    assert (settings.gcs_system_id, settings.gcs_component_id) == (254, 191)
    with pytest.raises(SystemExit):
        parser.parse_args(["--gcs-component-id", "300"])
    with pytest.raises(SettingsError, match="--gcs-system-id must be a whole number"):
        settings_from_args(parser.parse_args(["--gcs-system-id", "254.5"]))


def test_only_acks_addressed_to_us_are_ours() -> None:
    tracker = _tracker()
    command = mavlink.MAV_CMD_DO_SET_MODE
    assert tracker.update(_ack(command, 255, 190), 1.0) == []          # QGroundControl's
    assert tracker.state.other_station == (255, 190) and tracker.state.other_station_mode_s == 1.0
    assert tracker.update(_ack(command, 245, 190), 1.1) == []          # MAVSDK's
    assert [a.command for a in tracker.update(_ack(command, 255, 231), 1.2)] == [command]
    assert [a.command for a in tracker.update(_ack(command, 255, 0), 1.3)] == [command]    # to our whole system
    assert [a.command for a in tracker.update(_ack(command, 0, 0), 1.4)] == [command]      # MAVLink 1 style
    assert len(tracker.acks) == 3


def test_a_tracker_without_a_component_keeps_reading_old_captures() -> None:
    """The captures in ../shared/tlogs were flown as 255/190: replay tools read them with no component set."""
    tracker = VehicleStateTracker(gcs_system_id=255)
    tracker.update(_wire(VEHICLE.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                                  0, 4, mavlink.MAV_STATE_ACTIVE)), 0.0)
    assert len(tracker.update(_ack(mavlink.MAV_CMD_NAV_TAKEOFF, 255, 190), 1.0)) == 1
