"""Parameter and mission protocols as QGroundControl's start-up uses them (full download, empty mission)."""

from __future__ import annotations

import math
import struct

import pytest
from tools.flight.lockstep_gcs import LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

from sim_bridge.params import ParamsError, load_params


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_full_parameter_download_is_consistent(autopilot: str) -> None:
    g = LockstepGcs(autopilot, room="open_field")
    try:
        g.run(0.2)
        g.send(g.mav.param_request_list_encode(1, 1))
        g.run(2.0)
        values = [m for _t, m in g.of_type("PARAM_VALUE")]
        counts = {m.param_count for m in values}
        assert len(counts) == 1
        count = counts.pop()
        assert count == len(load_params(autopilot)) and sorted(m.param_index for m in values) == list(range(count))
        names = {m.param_id for m in values}
        assert len(names) == count
        # read one back by name and by index
        g.send(g.mav.param_request_read_encode(1, 1, values[3].param_id.encode(), -1))
        by_name = g.wait("PARAM_VALUE", 0.5)
        assert by_name.param_index == 3 and by_name.param_value == values[3].param_value
        g.send(g.mav.param_request_read_encode(1, 1, b"", 5))
        assert g.wait("PARAM_VALUE", 0.5).param_id == values[5].param_id
        # unknown names get no answer (both firmwares)
        g.send(g.mav.param_request_read_encode(1, 1, b"NO_SUCH_PARAM", -1))
        assert g.wait("PARAM_VALUE", 0.5) is None
    finally:
        g.close()


def test_ardupilot_param_set_changes_behaviour_and_request_data_stream() -> None:
    g = LockstepGcs("ardupilot", room="open_field")
    try:
        g.send(g.mav.param_set_encode(1, 1, b"GUID_TIMEOUT", 1.5, M.MAV_PARAM_TYPE_REAL32))
        echo = g.wait("PARAM_VALUE", 0.5)
        assert echo.param_id == "GUID_TIMEOUT" and echo.param_value == 1.5
        assert g.server.vehicle.limits.setpoint_timeout_s == 1.5
        g.send(g.mav.param_set_encode(1, 1, b"DISARM_DELAY", 300.0, M.MAV_PARAM_TYPE_INT8))   # out of INT8 range
        assert g.wait("PARAM_VALUE", 0.5).param_value == 10.0, "refused: the value held is sent back"
        # REQUEST_DATA_STREAM ALL at 5 Hz: no ACK, streams at 5 Hz, MAV1_* follow
        g.send(g.mav.request_data_stream_encode(1, 1, 0, 5, 1))
        g.run(0.1)
        start = g.t_s
        g.run(4.0)
        att = [t for t, m in g.of_type("ATTITUDE") if t > start]
        assert len(att) == pytest.approx(20, abs=2)
        assert not g.of_type("COMMAND_ACK")
        assert g.server.params.get("MAV1_POSITION") == 5
        g.send(g.mav.request_data_stream_encode(1, 1, 0, 65535, 1))   # the MAVn_* parameters range 0-50 Hz
        g.run(0.1)
        assert g.server.params.get("MAV1_POSITION") == 50
    finally:
        g.close()


def test_px4_integers_go_bytewise() -> None:
    g = LockstepGcs("px4", room="open_field")
    try:
        g.send(g.mav.param_request_read_encode(1, 1, b"COM_OBL_RC_ACT", -1))
        m = g.wait("PARAM_VALUE", 0.5)
        assert m.param_type == M.MAV_PARAM_TYPE_INT32 and struct.pack("<f", m.param_value) == struct.pack("<i", 0)
        g.send(g.mav.param_request_read_encode(1, 1, b"COM_OF_LOSS_T", -1))
        assert g.wait("PARAM_VALUE", 0.5).param_value == 1.0
        # the bytes are read as the parameter's own type (REAL32), whatever the message declares: a NaN
        # declared INT8 is refused, not read as its first byte (0), which would end OFFBOARD at once
        g.send(g.mav.param_set_encode(1, 1, b"COM_OF_LOSS_T", math.nan, M.MAV_PARAM_TYPE_INT8))
        assert g.wait("PARAM_VALUE", 0.5).param_value == 1.0
        assert g.server.params.get("COM_OF_LOSS_T") == 1.0
    finally:
        g.close()


@pytest.mark.parametrize("autopilot, expected_after_boot", [("ardupilot", 1), ("px4", 0)])
def test_mission_list(autopilot: str, expected_after_boot: int) -> None:
    g = LockstepGcs(autopilot, room="open_field")
    try:
        g.send(g.mav.mission_request_list_encode(1, 1, 0))
        assert g.wait("MISSION_COUNT", 0.3).count == 0
        g.boot()
        g.send(g.mav.mission_request_list_encode(1, 1, 0))
        assert g.wait("MISSION_COUNT", 0.3).count == expected_after_boot
        if expected_after_boot:
            g.send(g.mav.mission_request_int_encode(1, 1, 0, 0))
            item = g.wait("MISSION_ITEM_INT", 0.3)
            assert item.command == M.MAV_CMD_NAV_WAYPOINT and item.x == round(47.397742e7), "item 0 is home"
        g.send(g.mav.mission_request_list_encode(1, 1, M.MAV_MISSION_TYPE_FENCE))
        assert g.wait("MISSION_COUNT", 0.3).count == 0
    finally:
        g.close()


def test_bad_parameter_file_is_one_clear_error(tmp_path) -> None:
    bad = tmp_path / "p.toml"
    bad.write_text('[params]\nTHIS_NAME_IS_FAR_TOO_LONG = { value = 1, type = "INT8" }\n')
    with pytest.raises(ParamsError, match="at most 16 characters"):
        load_params("ardupilot", bad)
    bad.write_text('[params]\nX = { value = 1, type = "FLOAT64" }\n')
    with pytest.raises(ParamsError, match="X: needs value and type"):
        load_params("ardupilot", bad)
