"""The link on the wire: a real pymavlink peer on 127.0.0.1 (tests/link_peer.py) records what we send."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from gcs_voice.errors import LinkError
from gcs_voice.link import ACCEPTED, REFUSED, Setpoint, VehicleLink
from gcs_voice.link.setpoints import TYPE_MASK_POSITION_VELOCITY_YAW
from gcs_voice.settings import load_settings
from link_peer import PX4_OFFBOARD, ScriptedVehicle

FAST = load_settings(arm_retry_s=0.3, command_timeout_s=0.5, mode_confirm_s=1.5, offboard_prestream_s=0.6,
                     takeoff_timeout_s=5.0)


def _link(vehicle: ScriptedVehicle, tmp_path: Path, events: list | None = None, **overrides) -> VehicleLink:
    link = VehicleLink(vehicle.connection, FAST.with_overrides(**overrides), tlog_path=tmp_path / "flight.tlog",
                       on_event=(events.append if events is not None else None))
    link.open()
    link.wait_vehicle(timeout_s=5)
    return link


def test_heartbeat_identity_and_telemetry_request(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot") as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            assert link.state.autopilot == "ArduPilot"
            assert link.request_telemetry().ok
            time.sleep(1.1)
        finally:
            link.close()
        beats = vehicle.messages("HEARTBEAT")
        assert beats, "no GCS heartbeat"
        _, beat = beats[0]
        assert (beat.type, beat.get_srcSystem(), beat.get_srcComponent()) == (mavutil.mavlink.MAV_TYPE_GCS, 255, 231)
        asked = {int(m.param1): m.param2 for _, m in vehicle.messages("COMMAND_LONG") if m.command == 511}
        assert asked == {32: pytest.approx(1e5), 30: pytest.approx(1e5), 245: pytest.approx(1e6),
                         33: pytest.approx(5e5), 132: pytest.approx(1e5),
                         1: pytest.approx(1e6), 193: pytest.approx(1e6)}  # readiness: SYS_STATUS, EKF flags
        # the .tlog holds both directions and reads back with pymavlink
        log = mavutil.mavlink_connection(str(tmp_path / "flight.tlog"))
        senders = set()
        while (msg := log.recv_match()) is not None:
            senders.add(msg.get_srcSystem())
        assert senders == {1, 255}


def test_arducopter_arm_retries_until_accepted_and_reports_reasons(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot", arm_refusals=2) as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            refused = link.arm(timeout_s=1.5)  # GUIDED first, settled 1 s, then one refused ARM
            assert refused.status == REFUSED and "Arm: Need Position Estimate" in refused.reason
            assert "FAILED" in refused.reason
            result = link.arm(timeout_s=5)
            assert result.ok, result
            assert link.state.armed is True
        finally:
            link.close()
        arms = [m for _, m in vehicle.messages("COMMAND_LONG") if m.command == 400]
        assert len(arms) == 3


def test_arducopter_takeoff_then_stream_and_land(tmp_path: Path) -> None:
    events: list[str] = []
    with ScriptedVehicle("ardupilot") as vehicle:
        link = _link(vehicle, tmp_path, events)
        try:
            result = link.takeoff(2.0)
            assert result.ok, result
            assert vehicle.custom_mode == 4 and vehicle.armed
            takeoff = [m for _, m in vehicle.messages("COMMAND_LONG") if m.command == 22][-1]
            assert takeoff.param7 == pytest.approx(2.0)  # metres above home on ArduCopter
            time.sleep(0.5)
            assert link.streaming and vehicle.messages("SET_POSITION_TARGET_LOCAL_NED")
            refused = link.disarm()
            assert refused.status == REFUSED and "FAILED" in refused.reason
            assert link.streaming  # a refused disarm must not stop the setpoints mid-air
            assert link.land().ok
            assert not link.streaming
            assert link.wait_for(lambda s: s.armed is False, 3.0) is not None  # landed and disarmed by itself
            time.sleep(0.1)
        finally:
            link.close()
        said = [e for e in events if e.startswith("vehicle now")]
        assert said == ["vehicle now GUIDED, disarmed", "vehicle now GUIDED, armed", "vehicle now LAND, armed",
                        "vehicle now LAND, disarmed"]
        assert "vehicle: Arming motors" in events and "link up: ArduPilot system 1" in events


def test_arducopter_mode_reset_after_arming_is_caught(tmp_path: Path) -> None:
    """ArduCopter may drop GUIDED (end of init, RC mode switch): take-off sets it again before NAV_TAKEOFF."""
    with ScriptedVehicle("ardupilot", mode_after_arm=0) as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            result = link.takeoff(1.0)
            assert result.ok, result
        finally:
            link.close()
        commands = [(m.command, m.param2) for _, m in vehicle.messages("COMMAND_LONG") if m.command in (176, 400, 22)]
        assert commands == [(176, 4.0), (400, 0.0), (176, 4.0), (22, 0.0)]


def test_refusals_without_a_usable_vehicle(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot", mav_type=mavutil.mavlink.MAV_TYPE_FIXED_WING) as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            result = link.takeoff(1.0)
            assert result.status == REFUSED and "not a multicopter" in result.reason
        finally:
            link.close()
        assert not [m for _, m in vehicle.messages("COMMAND_LONG")]
    with pytest.raises(LinkError, match="cannot open"):
        VehicleLink("udpin:256.0.0.1:14550").open()  # not an address: one line, no traceback


def test_px4_offboard_needs_setpoints_first(tmp_path: Path) -> None:
    """PX4: the first DO_SET_MODE ACK is always ACCEPTED; only the HEARTBEAT says OFFBOARD."""
    with ScriptedVehicle("px4") as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            refused = link.set_mode("OFFBOARD")  # nothing streamed: second ACK refuses
            assert refused.status == REFUSED
            assert "Switching to Offboard is currently not available" in refused.reason
            assert link.state.mode == "LOITER"
            result = link.set_velocity_mode()
            assert result.ok, result
            assert link.state.custom_mode == PX4_OFFBOARD
        finally:
            link.close()
        mode_cmds = [(t, m) for t, m in vehicle.messages("COMMAND_LONG") if m.command == 176]
        assert [(m.param1, m.param2, m.param3) for _, m in mode_cmds] == [(1, 6, 0)] * 2
        switch_t = mode_cmds[-1][0]
        before = [t for t, _ in vehicle.messages("SET_POSITION_TARGET_LOCAL_NED") if t < switch_t]
        assert len(before) >= 5 and before[-1] - before[0] >= 0.4
        gaps = [b - a for a, b in zip(before, before[1:])]
        assert max(gaps) < 0.5  # > 2 Hz
        for _, sp in vehicle.messages("SET_POSITION_TARGET_LOCAL_NED"):
            assert sp.coordinate_frame == mavutil.mavlink.MAV_FRAME_LOCAL_NED
            # the link's own hold: where the vehicle is, position + velocity + yaw (docs/link.md)
            assert sp.type_mask == TYPE_MASK_POSITION_VELOCITY_YAW and math.isfinite(sp.yaw)


def test_px4_arms_in_hold_when_left_in_offboard(tmp_path: Path) -> None:
    """After a failsafe landing PX4 sits in OFFBOARD, disarmed, where arming is refused: arm() goes to Hold."""
    with ScriptedVehicle("px4", custom_mode=PX4_OFFBOARD) as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            assert link.state.mode == "OFFBOARD"
            result = link.arm(timeout_s=2.0)
            assert result.ok, result
            assert link.state.mode == "LOITER" and link.state.armed
        finally:
            link.close()
        modes = [(m.param2, m.param3) for _, m in vehicle.messages("COMMAND_LONG") if m.command == 176]
        assert modes == [(4.0, 3.0)]  # AUTO.LOITER (Hold)


def test_px4_takeoff_uses_amsl_then_offboard(tmp_path: Path) -> None:
    with ScriptedVehicle("px4") as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            result = link.takeoff(3.0)
            assert result.ok, result
            assert link.state.mode == "OFFBOARD" and link.state.armed
        finally:
            link.close()
        takeoff = [m for _, m in vehicle.messages("COMMAND_LONG") if m.command == 22][-1]
        assert takeoff.param7 == pytest.approx(488.0 + 3.0)  # home AMSL + 3 m
        assert all(math.isnan(p) for p in (takeoff.param4, takeoff.param5, takeoff.param6))
        modes = [(m.param2, m.param3) for _, m in vehicle.messages("COMMAND_LONG") if m.command == 176]
        assert modes == [(6.0, 0.0)]  # already in Hold; then OFFBOARD; never ArduCopter's 4


@pytest.mark.slow
def test_link_loss_stops_commanding_and_resumes_with_a_stop(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot", heading_deg=30.0) as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            assert link.request_telemetry().ok
            seen_lost = []
            link.start_stream(lambda state: seen_lost.append(not state.link_ok) or Setpoint(0.5, 0.0, 0.0, 30.0))
            time.sleep(0.5)
            assert link.state.link_ok
            vehicle.sending = False
            silent_from = time.monotonic()
            assert link.wait_for(lambda s: not s.link_ok, 3.0) is not None
            lost_after = time.monotonic() - silent_from
            assert link.send_setpoint(Setpoint(0.5, 0.0, 0.0, 30.0)) is False  # direct sends refused too
            assert 1.8 <= lost_after <= 2.6
            lost_at = time.monotonic()
            time.sleep(1.0)
            vehicle.sending = True
            assert link.wait_for(lambda s: s.link_ok, 3.0) is not None
            time.sleep(0.5)
        finally:
            link.close()
        assert any(seen_lost), "the setpoint source was never told about the loss"
        setpoints = vehicle.messages("SET_POSITION_TARGET_LOCAL_NED")
        assert not [t for t, _ in setpoints if lost_at + 0.15 < t < lost_at + 1.0]
        after = [m for t, m in setpoints if t > lost_at + 1.0]
        assert after, "streaming did not resume"
        first = after[0]
        assert (first.vx, first.vy, first.vz) == (0.0, 0.0, 0.0)
        assert first.yaw == pytest.approx(math.radians(30.0), abs=1e-6)
        assert after[-1].vx == pytest.approx(0.5 * math.cos(math.radians(30)), abs=1e-6)
        intervals = [t for t, m in vehicle.messages("COMMAND_LONG") if m.command == 511]
        assert len(intervals) == 14 and intervals[-1] > lost_at  # 7 asked again after the link came back


def test_garbage_and_hostile_packets_do_not_break_the_link(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot") as vehicle:
        link = _link(vehicle, tmp_path)
        try:
            mav = vehicle.conn.mav
            vehicle.send_raw(b"\xfd\xff" + bytes(range(256)) * 4)
            vehicle.send_raw(b"\x00" * 300)
            vehicle.conn.mav.send(mav.attitude_encode(0, math.nan, math.nan, math.nan, 0, 0, 0))
            vehicle.conn.mav.send(mav.local_position_ned_encode(0, math.inf, math.nan, 1.0, 0, 0, 0))
            other = mavutil.mavlink.MAVLink(None, srcSystem=7, srcComponent=1)
            vehicle.send_raw(other.heartbeat_encode(2, 12, 128, PX4_OFFBOARD, 4).pack(other))
            time.sleep(0.5)
            state = link.state
            assert state.link_ok and state.autopilot == "ArduPilot" and state.system_id == 1
            assert state.heading_deg is not None and math.isfinite(state.heading_deg)
            assert state.north_m is not None and math.isfinite(state.north_m)
            assert link.set_mode("GUIDED").status == ACCEPTED
        finally:
            link.close()


def test_link_check_command_prints_state_and_commands_nothing(capsys) -> None:
    from gcs_voice.link.__main__ import main

    with ScriptedVehicle("px4") as vehicle:
        assert main(["--connect", vehicle.connection, "--seconds", "1.5", "--wait", "5"]) == 0
        commanded = {m.command for _, m in vehicle.messages("COMMAND_LONG")}
        assert commanded <= {511, 512}  # telemetry requests only
        assert not vehicle.messages("SET_POSITION_TARGET_LOCAL_NED")
    out = capsys.readouterr().out
    assert "link ok | PX4 sys 1 | mode LOITER | disarmed | ON_GROUND | height 0.00 m | heading 0.0 deg" in out
    assert main(["--connect", "udpin://0.0.0.0:14540"]) == 2
    assert "MAVSDK" in capsys.readouterr().err


def test_arm_when_already_armed_changes_nothing(tmp_path: Path) -> None:
    """"arm" heard while PX4 flies OFFBOARD must not send it to Hold (the arming mode)."""
    with ScriptedVehicle("px4", custom_mode=PX4_OFFBOARD) as vehicle:
        vehicle.armed = True
        link = _link(vehicle, tmp_path)
        try:
            assert link.wait_for(lambda s: s.armed is True, 3.0) is not None
            result = link.arm(timeout_s=2.0)
            assert result.ok and result.reason == "already armed"
        finally:
            link.close()
        assert not [m for _, m in vehicle.messages("COMMAND_LONG") if m.command in (176, 400)]
