"""gcs-sim as a process on loopback, against real pymavlink clients: what any client may do must not hurt it."""

from __future__ import annotations

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from gcs_voice.session.sim_process import BundledSim

AUTOPILOTS = ["ardupilot", "px4"]


def _tcp(sim: BundledSim) -> mavutil.mavfile:
    return mavutil.mavlink_connection(f"tcp:127.0.0.1:{sim.tcp_port}", source_system=255, source_component=190,
                                      retries=0)


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_forty_short_tcp_sessions_leave_the_sim_serving(autopilot: str) -> None:
    """Issue 12: a client closing during a tick left fd -1 in the select list and killed the sim by the 8th."""
    with BundledSim(autopilot, speedup=5, room="open_field", tcp=True, udp=False) as sim:
        for session in range(40):
            conn = _tcp(sim)
            hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=10)
            conn.close()
            assert hb is not None, f"session {session}: no HEARTBEAT"
            assert sim.alive(), f"gcs-sim died after {session + 1} sessions:\n{sim.stderr}"
        conn = _tcp(sim)
        try:
            assert conn.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
        finally:
            conn.close()
        assert sim.alive(), sim.stderr
        assert "Traceback" not in sim.stderr, sim.stderr


def _command(conn: mavutil.mavfile, command: int, *params: float) -> int:
    """COMMAND_LONG from this client; the result of its COMMAND_ACK (the sim answers every one)."""
    args = [*params, *[0.0] * (7 - len(params))]
    conn.mav.command_long_send(1, 1, command, 0, *args)
    ack = conn.recv_match(type="COMMAND_ACK", condition=f"COMMAND_ACK.command=={command}", blocking=True, timeout=10)
    assert ack is not None, f"no COMMAND_ACK for {command}"
    return ack.result


def _heartbeat_gaps_ms(conn: mavutil.mavfile, beats: int) -> list[int]:
    """Simulated ms between HEARTBEATs on this link, clocked by GLOBAL_POSITION_INT.time_boot_ms (not wall time)."""
    clock_ms, stamps = None, []
    while len(stamps) < beats:
        msg = conn.recv_match(type=["HEARTBEAT", "GLOBAL_POSITION_INT"], blocking=True, timeout=10)
        assert msg is not None, f"link went quiet after {len(stamps)} heartbeats"
        if msg.get_type() == "GLOBAL_POSITION_INT":
            clock_ms = msg.time_boot_ms
        elif clock_ms is not None and msg.get_srcSystem() == 1:
            stamps.append(clock_ms)
    return [b - a for a, b in zip(stamps, stamps[1:])]


@pytest.mark.slow
@pytest.mark.parametrize("autopilot, refusal", [("ardupilot", M.MAV_RESULT_DENIED), ("px4", M.MAV_RESULT_FAILED)])
def test_no_client_can_silence_the_heartbeat_and_intervals_are_per_link(autopilot: str, refusal: int) -> None:
    """PX4 refuses any HEARTBEAT interval; ArduPilot would let -1 or 60 s hide that link, the sim refuses too.

    Other intervals change only the asking link, as both firmwares keep them per MAVLink channel.
    """
    with BundledSim(autopilot, speedup=4, room="open_field", tcp=True, udp=False) as sim:
        a, b = _tcp(sim), _tcp(sim)
        try:
            for interval_us in (-1, 1e30, 60e6):
                assert _command(a, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_HEARTBEAT, interval_us) == refusal
            assert _command(a, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, -1) == M.MAV_RESULT_ACCEPTED
            for conn in (a, b):
                gaps = _heartbeat_gaps_ms(conn, 4)
                assert all(800 <= gap <= 1200 for gap in gaps), gaps
            assert a.recv_match(type="ATTITUDE", blocking=True, timeout=1.5) is None, "ATTITUDE off on this link"
            assert b.recv_match(type="ATTITUDE", blocking=True, timeout=5) is not None, "the other link still has it"
        finally:
            a.close()
            b.close()
        out = sim.stop()
    assert "handler errors" not in out, out


@pytest.mark.slow
@pytest.mark.parametrize("autopilot, longest_us", [("ardupilot", 60_000_000), ("px4", 2**31 - 1)])
def test_very_long_intervals_are_clamped_and_reported(autopilot: str, longest_us: int) -> None:
    """1e30 or 2.2e9 µs: ArduPilot caps at 60 s; PX4 keeps it, reported within MESSAGE_INTERVAL's int32."""
    with BundledSim(autopilot, room="open_field", tcp=True, udp=False) as sim:
        conn = _tcp(sim)
        try:
            for interval in (1e30, 2.2e9, 5e5):
                expected = 500_000 if interval == 5e5 else longest_us
                assert _command(conn, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, interval) \
                    == M.MAV_RESULT_ACCEPTED
                assert _command(conn, M.MAV_CMD_GET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE) == M.MAV_RESULT_ACCEPTED
                reply = conn.recv_match(type="MESSAGE_INTERVAL", blocking=True, timeout=5)
                assert reply is not None, f"no MESSAGE_INTERVAL after {interval:g}"
                assert (reply.message_id, reply.interval_us) == (M.MAVLINK_MSG_ID_ATTITUDE, expected)
            assert _command(conn, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, -1) == M.MAV_RESULT_ACCEPTED
            _command(conn, M.MAV_CMD_GET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE)
            assert conn.recv_match(type="MESSAGE_INTERVAL", blocking=True, timeout=5).interval_us == -1
        finally:
            conn.close()
        out = sim.stop()
    assert "handler errors" not in out, out
