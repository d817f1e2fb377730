"""Bad input on the wire: ignored or clamped, counted, never a crash, never a stall of the physics."""

from __future__ import annotations

import math
import random

import pytest
from tools.flight.lockstep_gcs import VELOCITY_YAW, LockstepGcs

from pymavlink.dialects.v20 import ardupilotmega as M

NAN = math.nan


def _fly(g: LockstepGcs) -> None:
    g.boot()
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == [M.MAV_RESULT_ACCEPTED]
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [M.MAV_RESULT_ACCEPTED]
    assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, 1.5) == [M.MAV_RESULT_ACCEPTED]
    g.run(8.0)


def _state_is_sane(g: LockstepGcs) -> None:
    s = g.server.vehicle.state
    assert all(math.isfinite(float(v)) for v in [*s.pos_ned_m, *s.vel_ned_m_s, s.yaw_rad])


@pytest.fixture
def gcs():
    g = LockstepGcs("ardupilot", room="open_field")
    yield g
    g.close()


def test_malformed_frames_are_counted_and_ignored(gcs: LockstepGcs) -> None:
    g = gcs
    _fly(g)
    good = g.mav.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(g.mav)
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    unknown = bytearray(good)
    unknown[7:10] = (60000).to_bytes(3, "little")     # message id nobody knows (MAVLink 2 header bytes 7-9)
    for data in (b"\x00garbage\xff" * 5, bad_crc, good[:-5], bytes(unknown), b"\xfd", b""):
        g.send_raw(data)
    g.send(g.mav.command_long_encode(7, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0))
    g.send(g.mav.set_position_target_local_ned_encode(0, 9, 1, 1, VELOCITY_YAW, 0, 0, 0, 5, 0, 0, 0, 0, 0, 0, 0))
    g.run(0.5)
    stats = g.server.stats
    assert stats.bad_frames >= 3 and stats.unknown_messages == 1 and stats.foreign == 2
    assert stats.handler_errors == 0
    assert g.server.vehicle.armed and -g.last("LOCAL_POSITION_NED").z > 1.2, "the foreign disarm was ignored"
    assert not g.of_type("AUTOPILOT_VERSION"), "no broken frame was taken for a request"
    assert g.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == [M.MAV_RESULT_ACCEPTED]


def test_nan_and_absurd_setpoints_are_dropped_or_clamped(gcs: LockstepGcs) -> None:
    g = gcs
    _fly(g)
    g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=NAN)
    g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=1.0, yaw=math.inf)
    g.run(0.3)
    assert g.server.autopilot.rejected_setpoints == 2
    g.run(1.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vx=1e9, vz=-1e9))
    assert g.server.vehicle.clamped_setpoints >= 1
    vel = g.last("LOCAL_POSITION_NED")
    assert math.hypot(vel.vx, vel.vy) <= 10.5 and vel.vz >= -2.6, "WPNAV_SPEED and WPNAV_SPEED_UP hold"
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW))
    _state_is_sane(g)
    assert abs(g.last("LOCAL_POSITION_NED").vx) < 0.2
    g.run(10.0)
    summary = [t for t in g.texts() if t.startswith("SIM rx bad,unk,fgn,drop,clamp ")][-1]
    bad, unknown, foreign, dropped, clamped = (int(n) for n in summary.rsplit(" ", 1)[1].split(","))
    assert (bad, unknown, foreign, dropped) == (0, 0, 0, 2) and clamped >= 1, "the periodic SIM rx summary"


def test_flood_does_not_stall_the_physics(gcs: LockstepGcs) -> None:
    g = gcs
    _fly(g)
    hb = g.mav.heartbeat_encode(6, 8, 0, 0, 0, 3).pack(g.mav)

    def flood() -> None:
        for _ in range(50):
            g.send_raw(hb)

    t0 = g.t_s
    g.run(1.0, every=flood, every_s=0.01)           # 5000 messages per simulated second
    assert g.t_s == pytest.approx(t0 + 1.0), "every tick ran"
    assert g.server.stats.received > 4000
    for _ in range(20000):                          # and a burst far beyond what the socket holds
        g.send_raw(hb)
    g.run(0.5)
    assert g.t_s == pytest.approx(t0 + 1.5)
    assert g.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == [M.MAV_RESULT_ACCEPTED]
    assert -g.last("LOCAL_POSITION_NED").z == pytest.approx(1.5, abs=0.15)


def _random_message(rng: random.Random, mav: M.MAVLink):
    """A well-formed message of a type the sim handles, with hostile field values."""
    def num() -> float:
        return rng.choice([0.0, 1.0, -1.0, NAN, math.inf, -math.inf, 1e9, -1e9, rng.uniform(-1e4, 1e4)])

    def small() -> int:
        return rng.randrange(0, 256)

    kind = rng.randrange(8)
    if kind == 0:
        return mav.command_long_encode(rng.choice([0, 1, 7]), rng.choice([0, 1]), rng.choice(
            [400, 176, 22, 21, 20, 115, 207, 511, 512, 510, 410, 520, rng.randrange(65536)]), 0,
            *(num() for _ in range(7)))
    if kind == 1:
        return mav.set_position_target_local_ned_encode(0, 1, 1, rng.randrange(0, 22), rng.randrange(65536),
                                                        *(num() for _ in range(11)))
    if kind == 2:
        return mav.set_mode_encode(1, small(), rng.choice([0, 2, 5, 99, rng.randrange(2**32)]))
    if kind == 3:
        return mav.param_set_encode(1, 1, rng.choice([b"GUID_TIMEOUT", b"WPNAV_SPEED", b"FENCE_ENABLE", b"X" * 16,
                                                      b"MAV1_EXTRA1"]), num(), small())
    if kind == 4:
        return mav.param_request_read_encode(1, 1, b"", rng.randrange(-1, 32767))
    if kind == 5:
        return mav.mission_request_int_encode(1, 1, rng.randrange(65536), small())
    if kind == 6:
        return mav.request_data_stream_encode(1, 1, small(), rng.randrange(65536), small())
    return mav.command_int_encode(1, 1, rng.randrange(0, 22), rng.randrange(65536), 0, 0, num(), num(), num(), num(),
                                  rng.randrange(-2**31, 2**31), rng.randrange(-2**31, 2**31), num())


@pytest.mark.slow
def test_fuzz_random_and_mutated_frames_then_still_flies(gcs: LockstepGcs) -> None:
    g = gcs
    rng = random.Random(20261125)
    _fly(g)
    pool = [g.mav.command_long_encode(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0).pack(g.mav),
            g.mav.set_position_target_local_ned_encode(0, 1, 1, 1, 3527, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0).pack(g.mav),
            g.mav.param_request_list_encode(1, 1).pack(g.mav)]

    def burst() -> None:
        for _ in range(20):
            choice = rng.random()
            if choice < 0.3:
                g.send_raw(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300))))
            elif choice < 0.6:
                frame = bytearray(rng.choice(pool))
                for _ in range(rng.randrange(1, 4)):
                    frame[rng.randrange(len(frame))] = rng.randrange(256)
                g.send_raw(bytes(frame[: rng.randrange(1, len(frame) + 1)]))
            else:
                g.send(_random_message(rng, g.mav))

    g.run(20.0, every=burst, every_s=0.05)     # 400 messages per simulated second, 8000 in all
    stats = g.server.stats
    assert stats.handler_errors == 0
    assert stats.bad_frames > 100 and stats.received > 1000
    _state_is_sane(g)
    # it still answers and, put back in GUIDED and in the air, still flies where it is told
    assert g.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == [M.MAV_RESULT_ACCEPTED]
    g.server.params.set("FENCE_ENABLE", 0)
    g.server.params.set("GUID_TIMEOUT", 3.0)
    g.server.params.set("WPNAV_SPEED", 1000)
    g.server.params.set("WP_YAW_BEHAVIOR", 2)
    assert g.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == [M.MAV_RESULT_ACCEPTED]
    if not g.server.vehicle.armed or g.server.vehicle.landed:
        g.run(1.0)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == [M.MAV_RESULT_ACCEPTED]
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, NAN, NAN, NAN, 1.5) == [M.MAV_RESULT_ACCEPTED]
        g.run(8.0)
    start = g.last("LOCAL_POSITION_NED")
    g.run(3.0, every=lambda: g.setpoint(M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, vy=1.0, yaw=0.0))
    assert g.last("LOCAL_POSITION_NED").y - start.y > 2.0


def test_tcp_clients_garbage_split_frames_and_abrupt_disconnects() -> None:
    import socket

    from sim_bridge.build import build_sim

    server = build_sim("ardupilot", "open_field", tcp=["127.0.0.1:0"])
    port = server.tcp_servers[0].port
    gcs = M.MAVLink(None, srcSystem=255, srcComponent=190)
    try:
        quitter = socket.create_connection(("127.0.0.1", port))
        quitter.sendall(b"\xfd\x09\x00")                        # half a header, then gone
        client = socket.create_connection(("127.0.0.1", port))
        client.settimeout(0.0)
        server.run_for(0.1)
        quitter.close()
        request = gcs.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(gcs)
        # garbage (no stray 0xFD/0xFE: like any MAVLink parser, a false start swallows what follows), then a
        # frame split across two TCP segments
        client.sendall(b"\x00\x11 garbage \x22" + request[:7])
        server.run_for(0.05)
        client.sendall(request[7:])
        server.run_for(0.2)
        parser = M.MAVLink(None)
        parser.robust_parsing = True
        data = b""
        while True:
            try:
                chunk = client.recv(65536)
            except BlockingIOError:
                break
            if not chunk:
                break
            data += chunk
        kinds = [m.get_type() for m in parser.parse_buffer(data) or []]
        assert "COMMAND_ACK" in kinds and "AUTOPILOT_VERSION" in kinds
        assert server.stats.bad_frames >= 1 and server.stats.handler_errors == 0
        assert len([link for link in server.links if not link.closed]) == 1, "the quitter's link was dropped"
    finally:
        client.close()
        server.close()
