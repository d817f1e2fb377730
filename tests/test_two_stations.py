"""gcs-voice beside QGroundControl: two ground stations on one bundled-sim vehicle, in the usual setups.

Each test flies the same story with the real simulator process, the bridge (key requests, no speech
needed) and a second station that acts like QGroundControl (tools/flight/qgc_like.py: 255/190, HEARTBEAT at
1 Hz, parameter reads, its own mode change):

take off by voice; the QGroundControl-like station reads parameters meanwhile and sees the voice motion
on its "map" (LOCAL_POSITION_NED); it switches the vehicle to BRAKE (ArduCopter) or Hold (PX4); the
bridge says "another station took over" within one HEARTBEAT, stops its stream, never asks for the
velocity mode back, and refuses the next voice motion; every COMMAND_ACK reaches the station that sent
the command, and neither station takes the other's ACK as its own.

Setups: a MAVProxy fan-out (``--out`` to two ports, as sim_vehicle.py does), PX4's two links (one UDP
port per station, like 14550 and 14540), and one serial line (a pseudo-terminal standing in for a
telemetry radio) shared through MAVProxy.
"""

from __future__ import annotations

import os
import shutil
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import pytest
from conftest import IN_CI
from e2e_support import SPEEDUP, require_parts
from tools.flight.qgc_like import QGC_COMPONENT, QGC_SYSTEM, QgcLikeStation
from tools.flight.soak_two_stations import mavproxy_fan_out, stop_process
from pymavlink import mavutil

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.session.events import EventBus
from gcs_voice.session.sim_process import BundledSim, free_udp_port
from gcs_voice.settings import load_settings

pytestmark = pytest.mark.slow

ARDUCOPTER_BRAKE = 17
PX4_AUTO, PX4_LOITER = mavutil.PX4_CUSTOM_MAIN_MODE_AUTO, mavutil.PX4_CUSTOM_SUB_MODE_AUTO_LOITER


def _wait(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout_s:.0f} s")
        time.sleep(0.02)


def _need_mavproxy() -> None:
    if shutil.which("mavproxy.py") is None:
        if IN_CI:
            pytest.fail("mavproxy.py is missing in CI (it is in the [test] extra)")
        pytest.skip("mavproxy.py not installed")


class _SerialRadio:
    """A telemetry radio stand-in: the simulator's UDP link on one side, a serial device (a pseudo-terminal)
    on the other, bytes relayed both ways unchanged, as a radio pair does."""

    def __init__(self, sim_port: int) -> None:
        self.master_fd, slave_fd = os.openpty()
        self.device = os.ttyname(slave_fd)
        self._slave_fd = slave_fd   # kept open so the device exists until MAVProxy opens it
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", sim_port))
        self.sock.settimeout(0.05)
        self._peer: tuple[str, int] | None = None
        self._running = True
        self._threads = [threading.Thread(target=self._up, daemon=True), threading.Thread(target=self._down, daemon=True)]
        for thread in self._threads:
            thread.start()

    def _up(self) -> None:   # vehicle -> serial
        while self._running:
            try:
                data, self._peer = self.sock.recvfrom(65536)
            except OSError:
                continue
            try:
                os.write(self.master_fd, data)
            except OSError:
                return

    def _down(self) -> None:   # serial -> vehicle
        import select
        while self._running:
            ready, _, _ = select.select([self.master_fd], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self.master_fd, 4096)
            except OSError:
                return
            if self._peer is not None:
                self.sock.sendto(data, self._peer)

    def close(self) -> None:
        self._running = False
        for thread in self._threads:
            thread.join(timeout=2)
        self.sock.close()
        os.close(self.master_fd)
        os.close(self._slave_fd)


@dataclass
class Story:
    events: list[dict] = field(default_factory=list)
    takeover_t: float = 0.0
    takeover_heartbeat_t: float = 0.0
    setpoints_at_takeover: int = 0
    setpoints_later: int = 0
    modes_after: list[str] = field(default_factory=list)
    voice_commands: int = 0
    voice_acks: int = 0
    voice_mode_commands: int = 0
    voice_mode_acks: int = 0
    other_station: tuple[int, int] | None = None
    moved_m: float = 0.0
    status_mode: str | None = None


def _fly_beside_qgc(voice_connection: str, qgc: QgcLikeStation, autopilot: str) -> Story:
    """The story of the module docstring; returns what both stations saw."""
    settings = load_settings()
    bus = EventBus()
    story = Story()
    link = VehicleLink(voice_connection, settings)
    sent_commands: list[int] = []
    original_send = link.send

    def counting_send(msg, time_s=None):   # noqa: ANN001 - the link's own signature
        if msg.get_type() == "COMMAND_LONG":
            sent_commands.append(int(msg.command))
        original_send(msg, time_s)

    link.send = counting_send   # count what gcs-voice asks; the message still goes on the wire unchanged
    link.open()
    try:
        link.wait_vehicle(30)
        link.request_telemetry()
        qgc.wait_for(lambda q: q.vehicle is not None, 30, "the vehicle's HEARTBEAT")
        bridge = Bridge(link, ActionMapper(settings), bus, 1.5)
        failures: list[BaseException] = []

        def takeover_seen() -> bool:
            return any(e.kind == "takeover" for e in bus.history)

        def script() -> None:
            try:
                bridge.submit(Request("take_off", "key"))
                if not bridge.flying_ready.wait(90):
                    raise AssertionError("take-off did not finish within 90 s")
                qgc.wait_for(lambda q: q.param_values >= 2, 10, "parameter reads answered")
                start = qgc.position
                go = bridge.submit(Request("go_forward", "key"))
                assert go.done.wait(10) and go.accepted, "go_forward not accepted"
                # QGroundControl's map shows the voice-commanded motion
                qgc.wait_for(lambda q: q.position is not None and start is not None
                             and abs(q.position[0] - start[0]) > 0.3, 20, "the voice motion on its map")
                story.moved_m = abs(qgc.position[0] - start[0])
                story.setpoints_at_takeover = link.setpoints_sent
                if autopilot == "ardupilot":
                    qgc.set_mode(ARDUCOPTER_BRAKE)
                else:
                    qgc.set_mode(PX4_AUTO, PX4_LOITER)
                sent_t = time.monotonic()
                _wait(takeover_seen, 10, "the take-over event")
                story.takeover_t = time.monotonic() - sent_t
                story.takeover_heartbeat_t = (link.state.heartbeat_s or 0.0) - sent_t
                story.status_mode = bridge.status()["mode"]
                commands_at_takeover = len(sent_commands)
                left = bridge.submit(Request("go_left", "key"))
                assert left.done.wait(10) and not left.accepted, "go_left was flown after the take-over"
                beats = link.state.heartbeats
                _wait(lambda: link.state.heartbeats >= beats + 3, 10, "three more HEARTBEATs")
                story.setpoints_later = link.setpoints_sent
                story.modes_after = [link.state.mode or ""]
                assert sent_commands[commands_at_takeover:] == [], "gcs-voice sent a command after the take-over"
            except BaseException as exc:     # noqa: BLE001 - reported by the main thread
                failures.append(exc)
            finally:
                bridge.finish(0)

        worker = threading.Thread(target=script, daemon=True)
        worker.start()
        bridge.run()
        worker.join(15)
        assert not worker.is_alive(), "the script thread did not finish"
        if failures:
            raise failures[0]
        story.events = [e.to_dict() for e in bus.history]
        story.voice_commands = len(sent_commands)
        story.voice_acks = len(link.tracker.acks)
        story.voice_mode_commands = sent_commands.count(mavutil.mavlink.MAV_CMD_DO_SET_MODE)
        story.voice_mode_acks = sum(a.command == mavutil.mavlink.MAV_CMD_DO_SET_MODE for a in link.tracker.acks)
        story.other_station = link.state.other_station
    finally:
        link.close()
    return story


def _check_common(story: Story, qgc: QgcLikeStation, velocity_mode: str, taken_mode: str,
                  acks_per_mode_change: int = 1) -> None:
    takeovers = [e for e in story.events if e["kind"] == "takeover"]
    assert len(takeovers) == 1, takeovers
    assert takeovers[0]["mode"] == taken_mode and takeovers[0]["previous"] == velocity_mode
    # within one HEARTBEAT: the event comes with the first HEARTBEAT that shows the new mode
    assert story.takeover_t < 1.5, f"take-over said {story.takeover_t:.2f} s after the mode change was sent"
    refused = [e for e in story.events if e["kind"] == "refused" and e.get("action") == "go_left"]
    assert refused and f"{taken_mode}, not {velocity_mode}" in refused[0]["reason"]
    assert story.setpoints_later - story.setpoints_at_takeover <= 12, "the stream went on after the take-over"
    assert story.modes_after == [taken_mode], "the vehicle left the other station's mode"
    assert story.status_mode == taken_mode, "gcs-voice's view does not show the mode QGroundControl set"
    assert story.moved_m > 0.3
    # every voice command was answered to gcs-voice (one ACK each; PX4's DO_SET_MODE gets two)
    assert story.voice_acks >= story.voice_commands > 0
    # ... and gcs-voice took none of QGroundControl's: its DO_SET_MODE ACKs are exactly those of its own
    # mode changes (with QGroundControl's identity, 255/190, it would count QGroundControl's BRAKE too)
    assert story.voice_mode_acks == story.voice_mode_commands * acks_per_mode_change
    # QGroundControl's own command got its ACK; no ACK meant for gcs-voice was taken as its own (a
    # client that filters by its full identity, as gcs-voice does, never mixes them up)
    own = qgc.acks_to((QGC_SYSTEM, QGC_COMPONENT))
    assert [a[1] for a in own if a[1] == mavutil.mavlink.MAV_CMD_DO_SET_MODE], "no ACK for its mode change"
    sent = {command for _, command in qgc.sent}
    assert {a[1] for a in own} <= sent, "QGroundControl got an ACK for a command it never sent"


def _fly_through_mavproxy(master: str, ports: tuple[int, int], cwd: Path) -> tuple[Story, QgcLikeStation]:
    """MAVProxy on ``master`` with ``--out`` to gcs-voice (first port) and the QGroundControl-like station."""
    voice_port, qgc_port = ports
    router = mavproxy_fan_out(master, [voice_port, qgc_port], cwd)
    try:
        with QgcLikeStation(f"udpin:127.0.0.1:{qgc_port}") as qgc:
            return _fly_beside_qgc(f"udpin:127.0.0.1:{voice_port}", qgc, "ardupilot"), qgc
    finally:
        stop_process(router)


@pytest.fixture()
def ports() -> Iterator[tuple[int, int]]:
    yield free_udp_port(), free_udp_port()


def test_mavproxy_fan_out_arducopter(tmp_path: Path, ports: tuple[int, int]) -> None:
    """sim_vehicle.py's setup: vehicle -> MAVProxy -> --out to gcs-voice and to QGroundControl."""
    require_parts("sim_bridge.cli")
    _need_mavproxy()
    with BundledSim(speedup=SPEEDUP, room="open_field") as sim:
        story, qgc = _fly_through_mavproxy(f"udpin:127.0.0.1:{sim.port}", ports, tmp_path)
    _check_common(story, qgc, "GUIDED", "BRAKE")
    takeover = next(e for e in story.events if e["kind"] == "takeover")
    # behind a router gcs-voice hears the ACK meant for QGroundControl: it knows who took over, and says so
    assert takeover["by"] == "station" and takeover["station"] == [QGC_SYSTEM, QGC_COMPONENT]
    assert takeover["msg"].startswith("another station took over: BRAKE")
    assert story.other_station == (QGC_SYSTEM, QGC_COMPONENT)
    # QGroundControl hears gcs-voice's ACKs too (the router fans everything out): addressed to 255/231, so a
    # station that checks the addressee leaves them alone (tools/flight/qgc_like.py does; see docs/link.md for
    # QGroundControl itself)
    assert qgc.acks_to((QGC_SYSTEM, 231)), "the router did not fan gcs-voice's ACKs out (nothing to tell apart)"


def test_px4_two_links(tmp_path: Path, ports: tuple[int, int]) -> None:
    """PX4's own two UDP links (14550 for QGroundControl, 14540 for an API): no router in between."""
    require_parts("sim_bridge.cli")
    qgc_port, voice_port = ports
    with BundledSim("px4", speedup=SPEEDUP, room="open_field", port=qgc_port,
                    extra_args=["--out", f"udp:127.0.0.1:{voice_port}"]) as _sim:
        with QgcLikeStation(f"udpin:127.0.0.1:{qgc_port}") as qgc:
            story = _fly_beside_qgc(f"udpin:127.0.0.1:{voice_port}", qgc, "px4")
    takeover = next(e for e in story.events if e["kind"] == "takeover")
    _check_common(story, qgc, "OFFBOARD", "LOITER", acks_per_mode_change=2)
    # PX4 sends each station only the ACKs addressed to a component seen on its link
    assert all((a[3], a[4]) == (QGC_SYSTEM, QGC_COMPONENT) for a in qgc.acks), "an ACK for gcs-voice reached 14550"
    assert story.other_station is None, "an ACK for QGroundControl reached gcs-voice's link"
    assert takeover["by"] == "unknown"


def test_serial_radio_shared_through_mavproxy(tmp_path: Path, ports: tuple[int, int]) -> None:
    """One telemetry radio on a serial port (here a pseudo-terminal), shared by MAVProxy with both stations."""
    require_parts("sim_bridge.cli")
    _need_mavproxy()
    sim_port = free_udp_port()
    radio = _SerialRadio(sim_port)
    try:
        with BundledSim(speedup=SPEEDUP, room="open_field", port=sim_port) as _sim:
            story, qgc = _fly_through_mavproxy(f"{radio.device},57600", ports, tmp_path)
    finally:
        radio.close()
    _check_common(story, qgc, "GUIDED", "BRAKE")
    assert next(e for e in story.events if e["kind"] == "takeover")["by"] == "station"


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_sim_acks_reach_the_sender_only(autopilot: str, ports: tuple[int, int]) -> None:
    """Two stations on two links of gcs-sim (no router), each asking for a message interval: each gets the ACK
    addressed to it, on its own link only (ArduPilot answers on the command's channel; PX4 on every link that
    saw the addressee: here only the sender's), and a DO_SET_MODE likewise (PX4: both of its ACKs)."""
    require_parts("sim_bridge.cli")
    first_port, second_port = ports
    with BundledSim(autopilot, speedup=SPEEDUP, room="open_field", port=first_port,
                    extra_args=["--out", f"udp:127.0.0.1:{second_port}"]) as _sim:
        with QgcLikeStation(f"udpin:127.0.0.1:{first_port}") as qgc, \
                QgcLikeStation(f"udpin:127.0.0.1:{second_port}", component=231) as voice:
            for station in (qgc, voice):
                station.wait_for(lambda s: s.vehicle is not None, 30, "the vehicle's HEARTBEAT")
            qgc.command(mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 33, 500_000)
            voice.command(mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 200_000)
            hold = (ARDUCOPTER_BRAKE, 0) if autopilot == "ardupilot" else (PX4_AUTO, PX4_LOITER)
            voice.set_mode(*hold)
            expected = 3 if autopilot == "px4" else 2
            voice.wait_for(lambda s: len(s.acks) >= expected, 10, "its ACKs")
            qgc.wait_for(lambda s: len(s.acks) >= 1, 10, "its ACK")
            # a barrier instead of a pause: an ACK misrouted to the first link would come before the answer
            # to a later command of the first station (one simulator loop, one socket, in order)
            qgc.command(mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 33, 1_000_000)
            qgc.wait_for(lambda s: len(s.acks) >= 2, 10, "the barrier's ACK")
    interval = mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
    assert [(a[1], a[3], a[4]) for a in qgc.acks] == [(interval, 255, 190)] * 2
    assert all((a[3], a[4]) == (255, 231) for a in voice.acks) and len(voice.acks) == expected
