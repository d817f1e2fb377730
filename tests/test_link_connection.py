"""Connection strings in pymavlink syntax; everything else refused in one line."""

from __future__ import annotations

import pytest

from gcs_voice.errors import LinkError
from gcs_voice.link.connection import parse_connection, udp_listen
from gcs_voice.link.autopilots import ARDUPILOT, PX4, profile_for
from pymavlink import mavutil


@pytest.mark.parametrize(("text", "kind", "device"), [
    ("udpin:0.0.0.0:14550", "udpin", "udpin:0.0.0.0:14550"),
    ("udpout:192.168.1.5:14550", "udpout", "udpout:192.168.1.5:14550"),
    ("tcp:127.0.0.1:5760", "tcp", "tcp:127.0.0.1:5760"),
    ("tcpin:0.0.0.0:5760", "tcpin", "tcpin:0.0.0.0:5760"),
    ("/dev/ttyACM0", "serial", "/dev/ttyACM0"),
    ("/dev/ttyUSB0,921600", "serial", "/dev/ttyUSB0"),
    ("COM3,115200", "serial", "COM3"),
])
def test_accepted(text: str, kind: str, device: str) -> None:
    spec = parse_connection(text)
    assert (spec.kind, spec.device) == (kind, device)


def test_serial_baud_and_udp_flag() -> None:
    assert parse_connection("/dev/ttyUSB0,921600").baud == 921600
    assert parse_connection("/dev/ttyACM0").baud == 57600
    assert udp_listen(14550) == "udpin:0.0.0.0:14550"
    with pytest.raises(LinkError):
        udp_listen("port")


@pytest.mark.parametrize(("text", "hint"), [
    ("udpin://0.0.0.0:14540", "udpin:0.0.0.0:14540"),
    ("udp://:14540", "MAVSDK"),
    ("serial:///dev/ttyUSB0:57600", "MAVSDK"),
    ("udpin:0.0.0.0:99999", "bad port"),
    ("udpin:14550", "HOST:PORT"),
    ("udpout:127.0.0.1:0", "port 0"),
    ("banana", "unknown connection"),
    ("", "unknown connection"),
])
def test_refused_with_one_line(text: str, hint: str) -> None:
    with pytest.raises(LinkError) as info:
        parse_connection(text)
    assert hint in str(info.value) and "\n" not in str(info.value)


def test_profiles_use_pymavlink_mode_tables() -> None:
    assert profile_for(mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA) is ARDUPILOT
    assert profile_for(mavutil.mavlink.MAV_AUTOPILOT_PX4) is PX4
    assert profile_for(mavutil.mavlink.MAV_AUTOPILOT_INVALID) is None
    assert ARDUPILOT.custom_mode("GUIDED") == 4 and ARDUPILOT.custom_mode("LAND") == 9
    assert ARDUPILOT.custom_mode("BRAKE") == 17
    # PX4 custom_mode = sub << 24 | main << 16, values from the PX4 capture
    assert PX4.custom_mode("OFFBOARD") == 393216 and PX4.mode_params("OFFBOARD") == (1.0, 6.0, 0.0)
    assert PX4.custom_mode("LOITER") == 50593792 and PX4.custom_mode("RTL") == 84148224
    assert PX4.mode_name(0, 67371008) == "MISSION" and ARDUPILOT.mode_name(0, 4) == "GUIDED"
    with pytest.raises(KeyError):
        PX4.mode_params("GUIDED")


def test_flags_give_connection_and_settings(tmp_path) -> None:
    import argparse

    from gcs_voice.link.options import add_link_arguments, connection_from_args, settings_from_args

    parser = argparse.ArgumentParser()
    add_link_arguments(parser)
    assert connection_from_args(parser.parse_args([])) == "udpin:0.0.0.0:14550"
    assert connection_from_args(parser.parse_args(["--udp", "14551"])) == "udpin:0.0.0.0:14551"
    assert connection_from_args(parser.parse_args(["--connect", "tcp:127.0.0.1:5760"])) == "tcp:127.0.0.1:5760"
    with pytest.raises(LinkError, match="MAVSDK"):
        connection_from_args(parser.parse_args(["--connect", "udpin://0.0.0.0:14540"]))
    config = tmp_path / "fly.toml"
    config.write_text("[safety]\nceiling_m = 3.0\nfloor_m = 0.8\n")
    settings = settings_from_args(parser.parse_args(["--config", str(config), "--floor", "1.0", "--speed", "0.7"]))
    assert (settings.ceiling_m, settings.floor_m, settings.horizontal_speed_m_s) == (3.0, 1.0, 0.7)


def test_unwritable_tlog_is_one_line() -> None:
    from gcs_voice.link import VehicleLink

    with pytest.raises(LinkError, match="cannot write the flight log"):
        VehicleLink("udpin:127.0.0.1:0", tlog_path="/proc/no/such/dir/flight.tlog")
