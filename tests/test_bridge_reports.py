"""What the bridge reports is true: the mode after a link returns, the mapper's limits and automatic stops as they
happen, a north heading as 0, a Ctrl-C stop at once.

The link tests run against ``link_peer.ScriptedVehicle`` (a MAVLink vehicle on 127.0.0.1) so that the
order of messages after a dropout can be chosen: telemetry first, the HEARTBEAT with the new mode last.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.actions.setpoint import round_deg
from gcs_voice.link import VehicleLink
from gcs_voice.link.state import VehicleState
from gcs_voice.session.bridge import Bridge, Request, status_of
from gcs_voice.session.events import Event, EventBus
from gcs_voice.settings import load_settings
from link_peer import PX4_HOLD, PX4_OFFBOARD, ScriptedVehicle


def _event(bus: EventBus, timeout_s: float, **fields) -> dict | None:
    """The first event whose fields match, said before or within ``timeout_s`` (None if it never comes)."""
    found: list[dict] = []
    said = threading.Event()

    def take(event: Event) -> None:
        record = event.to_dict()
        if not said.is_set() and all(record.get(k) == v for k, v in fields.items()):
            found.append(record)
            said.set()

    bus.subscribe(take)
    for event in list(bus.history):
        take(event)
    said.wait(timeout_s)
    return found[0] if found else None


def test_link_restored_reports_the_mode_the_vehicle_is_in_now(tmp_path: Path) -> None:
    """A PX4 failsafe changes the mode while the link is down; telemetry comes back before the HEARTBEAT."""
    settings = load_settings()
    bus = EventBus()
    with ScriptedVehicle(autopilot="px4", custom_mode=PX4_OFFBOARD) as vehicle:
        link = VehicleLink(vehicle.connection, settings, tlog_path=tmp_path / "s.tlog")
        link.open()
        try:
            link.wait_vehicle(10)
            bridge = Bridge(link, ActionMapper(settings), bus, 1.5)
            loop = threading.Thread(target=bridge.run, daemon=True)
            loop.start()
            connected = _event(bus, 10, kind="link", state="connected")
            assert connected is not None and connected["mode"] == "OFFBOARD"
            vehicle.sending = False
            assert _event(bus, 10, kind="link", state="lost") is not None
            vehicle.custom_mode = PX4_HOLD  # the failsafe, while nobody hears it
            vehicle.sending = True  # 10 Hz telemetry is heard before the next 1 Hz HEARTBEAT
            restored = _event(bus, 10, kind="link", state="restored")
            bridge.finish()
            loop.join(5)
        finally:
            link.close()
    assert restored is not None
    assert restored["mode"] == link.state.mode != "OFFBOARD", restored
    assert "OFFBOARD" not in restored["msg"]


def test_the_mappers_limits_and_automatic_stops_are_said_when_they_happen(tmp_path: Path) -> None:
    """The loop sleeps until something wakes it: a limit decided in its own thread (the command's first
    setpoint) and an automatic stop decided in the link's stream thread (the floor) are both said."""
    settings = replace(load_settings(), ceiling_m=1.5)
    bus = EventBus()
    with ScriptedVehicle("ardupilot") as vehicle:
        link = VehicleLink(vehicle.connection, settings, tlog_path=tmp_path / "s.tlog")
        link.connect(timeout_s=10)
        bridge = Bridge(link, ActionMapper(settings), bus, 1.5)   # take off to the ceiling
        loop = threading.Thread(target=bridge.run, daemon=True)
        loop.start()
        try:
            took_off = bridge.submit(Request("take_off", "script"))
            assert bridge.flying_ready.wait(20) and took_off.done.wait(5), [e.msg for e in bus.history][-10:]
            up = bridge.submit(Request("up", "script"))
            assert up.done.wait(5) and up.accepted
            assert _event(bus, 5, kind="refused", msg="up limited: ceiling 1.5 m"), [e.msg for e in bus.history][-10:]
            down = bridge.submit(Request("down", "script"))
            assert down.done.wait(5) and down.accepted
            vehicle.target_height_m = 0.3   # the vehicle sinks below the 0.5 m floor
            said = _event(bus, 10, kind="warning", source="mapper")
            assert said is not None and said["msg"] == "down -> stop: floor 0.5 m reached", said
        finally:
            bridge.finish()
            loop.join(10)
            link.close()
    assert not loop.is_alive()


def test_north_is_0_not_360_in_every_report() -> None:
    assert [round_deg(a, 1) for a in (359.97, 360.0, -0.01, 0.04, 720.0)] == [0.0, 0.0, 0.0, 0.0, 0.0]
    assert round_deg(359.94, 1) == 359.9 and round_deg(89.96, 1) == 90.0
    state = VehicleState(system_id=1, heading_deg=359.7, last_heard_s=0.0, link_ok=True)
    assert status_of(state, "stop")["heading_deg"] == 0.0
    # the command event of a turn that lands just short of north says 0.0
    settings = load_settings()
    mapper = ActionMapper(settings)
    state = VehicleState(system_id=1, heading_deg=269.97, north_m=0.0, east_m=0.0, down_m=-2.0, home_north_m=0.0,
                         home_east_m=0.0, home_down_m=0.0, last_heard_s=0.0, link_ok=True)
    assert round_deg(mapper.apply("turn_right", state).yaw_target_deg, 1) == 0.0


def test_halt_makes_the_very_next_setpoint_a_stop_from_any_thread() -> None:
    """Ctrl-C's handler halts the mapper; the stream thread's next setpoint is a stop, and stays one."""
    settings = load_settings()
    mapper = ActionMapper(settings)
    state = VehicleState(system_id=1, heading_deg=0.0, north_m=0.0, east_m=0.0, down_m=-2.0, home_north_m=0.0,
                         home_east_m=0.0, home_down_m=0.0, last_heard_s=0.0, link_ok=True)
    mapper.apply("go_forward", state)
    assert not mapper.setpoint(state).is_stop
    halter = threading.Thread(target=mapper.halt)
    halter.start()
    halter.join()
    assert mapper.setpoint(state).is_stop and mapper.action == "stop"
    mapper.apply("go_left", state)  # a command heard after the Ctrl-C moves nothing
    assert mapper.setpoint(state).is_stop



def test_the_bridge_says_battery_low_once_below_its_threshold_whatever_the_autopilot_says(tmp_path: Path) -> None:
    """The vehicle's SYS_STATUS falls through battery_low_pct: one "battery low" line (a warning, which the
    feedback says aloud), not one per message; said again only after a charge 5 points above (another battery).
    The vehicle sends no STATUSTEXT of its own: an autopilot whose warning is off is still covered."""
    from pymavlink.dialects.v20 import common as mavlink

    from gcs_voice.session.feedback import cue_for, load_phrases

    settings = replace(load_settings(), battery_low_pct=25.0)
    lines: list[str] = []

    def battery(pct: int) -> None:
        vehicle.conn.mav.send(mavlink.MAVLink_sys_status_message(0, 0, 0, 500, 11800, 1200, pct, 0, 0, 0, 0, 0, 0))

    with ScriptedVehicle() as vehicle:
        link = VehicleLink(vehicle.connection, settings, tlog_path=tmp_path / "b.tlog", on_event=lines.append)
        try:
            link.open()
            link.connect(timeout_s=10)
            for pct in (40, 26, 24, 23, 20, 27, 31, 22):
                battery(pct)
                deadline = threading.Event()
                for _ in range(200):  # the link's state follows each message (polled, never a fixed sleep)
                    if link.state.battery_pct == pct:
                        break
                    deadline.wait(0.05)
                assert link.state.battery_pct == pct
        finally:
            link.close()
    low = [line for line in lines if line.startswith("battery low")]
    assert low == ["battery low: 24 % left (warning below 25 %)", "battery low: 22 % left (warning below 25 %)"], lines
    cue = cue_for(Event("warning", low[0], data={"source": "link"}), load_phrases("en"))
    assert cue is not None and cue.words == "battery low"
