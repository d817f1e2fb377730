"""A few seconds of fuzz on UDP and TCP against each personality (the long run: ``python -m tools.sim.fuzz_sim``).

The simulated clock never runs ahead of the wall clock (it did under a flood, then froze every stream until
the wall clock caught up). Afterwards the process is alive, HEARTBEAT comes at 1 Hz on a fresh link and on UDP, a normal take-off
(GUIDED for ArduPilot, take-off then OFFBOARD for PX4) works, and the resident memory has not grown.
"""

from __future__ import annotations

import random
import socket
import time

import pytest
from gcs_voice.session.sim_process import BundledSim
from tools.sim.fuzz_sim import Station, check_serving, fuzz, learn_sim_address, rss_kb

#: Resident memory may move by allocator noise, never by a leak of every message (4000+ are sent).
RSS_GROWTH_LIMIT_KB = 8 * 1024


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_fuzz_on_udp_and_tcp_then_it_still_serves_and_flies(autopilot: str) -> None:
    started_s = time.monotonic()
    with BundledSim(autopilot, room="open_field", tcp=True) as sim:
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind(("127.0.0.1", sim.port))
        try:
            sim_addr = learn_sim_address(udp)
            rss_before = rss_kb(sim.process.pid)
            counts = fuzz(udp, sim_addr, sim.tcp_port, 4.0, random.Random(20261202), max_rate_hz=1000.0)
            assert counts.udp_datagrams > 500 and counts.tcp_writes > 500 and counts.tcp_resets > 0, counts
            assert sim.alive(), sim.stderr
            station = Station(sim.tcp_port)
            try:
                clock = station.wait("GLOBAL_POSITION_INT", 10.0)
            finally:
                station.close()
            wall_s = time.monotonic() - started_s
            assert clock is not None and clock.time_boot_ms / 1000.0 <= wall_s + 1.0, \
                "a flood must not run the simulated clock ahead of the wall clock"
            rss_after = rss_kb(sim.process.pid)
            health = check_serving(sim.tcp_port, autopilot, udp)
        finally:
            udp.close()
        assert sim.alive(), sim.stderr
        out = sim.stop()
    assert health.heartbeat_1hz, health
    assert health.udp_heartbeats >= 2, health
    assert health.took_off and health.mode_ok, health
    assert rss_after - rss_before < RSS_GROWTH_LIMIT_KB, (rss_before, rss_after)
    assert "handler errors" not in out, out
    assert "Traceback" not in sim.stderr, sim.stderr
