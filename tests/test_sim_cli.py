"""The gcs-sim process: flags, one-line errors, UDP out + several TCP clients in real time, clean SIGTERM, tlog."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from gcs_voice.session.sim_process import BundledSim, SimError

REPO = Path(__file__).resolve().parent.parent


def test_help_explains_every_flag() -> None:
    out = subprocess.run([sys.executable, "-m", "sim_bridge", "--help"], cwd=REPO, capture_output=True, text=True,
                         timeout=30)
    assert out.returncode == 0
    for flag in ("--out", "--tcp", "--room", "--autopilot", "--speedup", "--home", "--tlog"):
        assert flag in out.stdout


@pytest.mark.parametrize("args, words", [
    (["--bogus"], "unrecognized arguments"),
    (["--home", "1,2"], "--home"),
    (["--speedup", "-3"], "--speedup"),
    (["--out", "tcp:1.2.3.4:5"], "--out"),
    (["--room", "no_such_room"], "no_such_room"),
    (["--autopilot", "inav"], "invalid choice"),
])
def test_bad_flags_give_one_line(args: list[str], words: str) -> None:
    out = subprocess.run([sys.executable, "-m", "sim_bridge", *args], cwd=REPO, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gcs-sim: error:") and words in lines[0], out.stderr


def test_a_simulator_without_udp_has_no_udpin_connection() -> None:
    """``udp=False`` gives the TCP string once the port is known (test_link_sim), never ``udpin:...:None``."""
    for sim in (BundledSim(udp=False), BundledSim(udp=False, tcp=True)):
        with pytest.raises(SimError, match="udp=False"):
            sim.connection
    assert BundledSim(port=14550).connection == "udpin:127.0.0.1:14550"


@pytest.mark.slow
def test_udp_out_and_two_tcp_clients_then_sigterm_closes_the_tlog(tmp_path: Path) -> None:
    gcs_udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs_udp.bind(("127.0.0.1", 0))
    gcs_udp.settimeout(5.0)
    tlog = tmp_path / "flight.tlog"
    sim = BundledSim(room="open_field", port=gcs_udp.getsockname()[1], tcp=True, sim_tlog=tlog)
    clients = []
    try:
        sim.start()
        assert sim.ready.startswith("gcs-sim: ArduCopter quad ready"), sim.ready
        # the UDP ground station hears the vehicle and answers to its source address
        data, sim_addr = gcs_udp.recvfrom(65535)
        parser = M.MAVLink(None)
        assert parser.parse_buffer(data), "a MAVLink datagram from the sim"
        for _ in range(2):
            conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{sim.tcp_port}", source_system=255, source_component=190)
            clients.append(conn)
            hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=10)
            assert hb is not None and hb.autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA
        a, b = clients
        booted = a.recv_match(type="SYS_STATUS", blocking=True, timeout=30,
                              condition=f"SYS_STATUS.onboard_control_sensors_health & {M.MAV_SYS_STATUS_PREARM_CHECK}")
        assert booted is not None, "the pre-arm checks never passed (boot)"
        a.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 4, 0, 0, 0, 0, 0)
        ack = a.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack.command == M.MAV_CMD_DO_SET_MODE and ack.result == M.MAV_RESULT_ACCEPTED
        hb = b.recv_match(type="HEARTBEAT", condition="HEARTBEAT.custom_mode==4", blocking=True, timeout=5)
        assert hb is not None, "the other client sees the mode change"
        gcs = M.MAVLink(None, srcSystem=255, srcComponent=190)
        gcs_udp.sendto(gcs.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(gcs),
                       sim_addr)
        deadline = time.monotonic() + 5
        got_version = False
        while time.monotonic() < deadline and not got_version:
            got_version = any(m.get_type() == "AUTOPILOT_VERSION" for m in parser.parse_buffer(gcs_udp.recv(65535)) or [])
        assert got_version
    finally:
        for conn in clients:
            conn.close()
        out = sim.stop()     # SIGTERM
        gcs_udp.close()
    assert sim.process.returncode == 0, sim.stderr
    summary = out.strip().splitlines()[-1]
    assert summary.startswith("gcs-sim: stopped after") and "records" in summary
    dump = subprocess.run(["mavlogdump.py", "--types", "COMMAND_LONG,COMMAND_ACK,HEARTBEAT", str(tlog)],
                          capture_output=True, text=True, timeout=60)
    assert dump.returncode == 0
    assert "COMMAND_LONG" in dump.stdout and "COMMAND_ACK" in dump.stdout and "HEARTBEAT" in dump.stdout
