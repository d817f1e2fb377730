"""gcs-sim as a process on loopback, against real pymavlink clients: what any client may do must not hurt it."""

from __future__ import annotations

import pytest
from conftest import SimProcess
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

AUTOPILOTS = ["ardupilot", "px4"]


def _tcp(sim: SimProcess) -> mavutil.mavfile:
    return mavutil.mavlink_connection(f"tcp:127.0.0.1:{sim.tcp_port}", source_system=255, source_component=190,
                                      retries=0)


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_forty_short_tcp_sessions_leave_the_sim_serving(autopilot: str) -> None:
    """Issue 12: a client closing during a tick left fd -1 in the select list and killed the sim by the 8th."""
    with SimProcess(autopilot, "--tcp", "127.0.0.1:0", "--speedup", "5", udp=False) as sim:
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
