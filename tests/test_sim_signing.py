"""MAVLink 2 signing and ``--allow`` in the real gcs-sim process, with signed and unsigned pymavlink clients.

Every verdict is checked twice: on the wire (a refused message gets no reply, a signed one does) and in
the simulator's own exit line, which counts what it refused and why. The exit line is read after the
process ended, so everything sent before it was read and judged.
"""

from __future__ import annotations

import hashlib
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as M  # noqa: E402

from gcs_voice.session.sim_process import BundledSim  # noqa: E402
from sim_bridge.signing import SimSigning, SigningKeyError, key_from_flag, passphrase_key, timestamp_now  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
PASSPHRASE = "correct horse battery staple"
KEY = hashlib.sha256(PASSPHRASE.encode()).digest()
OTHER_KEY = hashlib.sha256(b"not the key").digest()


class SignedSim:
    """gcs-sim on TCP only, in real time, and its ground stations; ``stop()`` returns its exit line."""

    def __init__(self, autopilot: str, *args: str) -> None:
        self.sim = BundledSim(autopilot, room="open_field", tcp=True, udp=False,
                              extra_args=["--duration", "300", *args]).start()
        self.port = self.sim.tcp_port
        self.clients: list = []

    def client(self, key: bytes | None = None, strict: bool = True):
        """A ground station on TCP; with ``key`` it signs, and (``strict``) hears only what is signed with it."""
        conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{self.port}", source_system=255,
                                          source_component=190 + len(self.clients))
        if key is not None:
            conn.setup_signing(key, sign_outgoing=True,
                               allow_unsigned_callback=None if strict else (lambda _mav, _msg_id: True))
        self.clients.append(conn)
        assert conn.recv_match(type="HEARTBEAT", blocking=True, timeout=20) is not None, "no HEARTBEAT"
        return conn

    def stop(self) -> str:
        """SIGTERM, wait for the exit; the clients stay open so what was sent to them can still be read."""
        out = self.sim.stop()
        assert self.sim.process.returncode == 0, self.sim.stderr
        return out.strip().splitlines()[-1]

    def close_clients(self) -> None:
        for conn in self.clients:
            conn.close()


def _ack(conn, command: int, timeout: float = 10.0):
    return conn.recv_match(type="COMMAND_ACK", condition=f"COMMAND_ACK.command=={command}", blocking=True,
                           timeout=timeout)


def _request_version(conn) -> bytes:
    """Send REQUEST_MESSAGE(AUTOPILOT_VERSION), answered in any state; return the bytes as sent."""
    msg = conn.mav.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0,
                                       M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
    conn.mav.send(msg)
    return bytes(msg.get_msgbuf())


def _drain(conn) -> list:
    """Every message still waiting on a closed-down link (the simulator has exited: nothing more comes)."""
    out = []
    while True:
        try:
            msg = conn.recv_match(blocking=True, timeout=0.5)
        except OSError:       # the simulator's side is gone
            return out
        if msg is None:
            return out
        out.append(msg)


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_only_messages_signed_with_the_key_command_the_vehicle(autopilot: str, tmp_path: Path) -> None:
    key_file = tmp_path / "key.txt"
    key_file.write_text(PASSPHRASE + "\n")
    sim = SignedSim(autopilot, "--signing-key", f"@{key_file}")
    try:
        signed = sim.client(KEY)
        heartbeat = signed.recv_match(type="HEARTBEAT", blocking=True, timeout=10)
        assert heartbeat is not None and heartbeat._signed, "the vehicle signs what it sends"
        unsigned = sim.client(None)
        wrong = sim.client(OTHER_KEY, strict=False)

        # unsigned: arm, mode, a setpoint, a parameter, the mission, a request -- none may act or be answered
        unsigned.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 21196, 0, 0, 0, 0, 0)
        unsigned.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 9, 0, 0, 0, 0, 0)
        unsigned.mav.set_position_target_local_ned_send(0, 1, 1, M.MAV_FRAME_LOCAL_NED, 3527, 0, 0, 0, 1, 0, 0,
                                                        0, 0, 0, 0, 0)
        unsigned.mav.param_set_send(1, 1, b"WPNAV_SPEED" if autopilot == "ardupilot" else b"MPC_XY_VEL_MAX",
                                    1.0, M.MAV_PARAM_TYPE_REAL32)
        unsigned.mav.mission_clear_all_send(1, 1)
        _request_version(unsigned)
        # signed with another key
        _request_version(wrong)
        # the right key: answered
        sent = _request_version(signed)
        assert _ack(signed, M.MAV_CMD_REQUEST_MESSAGE).result == M.MAV_RESULT_ACCEPTED
        # the same signed bytes again, on the same link and on another: replays, refused
        signed.write(sent)
        unsigned.write(sent)
        # a fresh signed message still works after the replays, and is answered once
        signed.mav.command_long_send(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_HOME_POSITION,
                                     0, 0, 0, 0, 0, 0)
        assert _ack(signed, M.MAV_CMD_REQUEST_MESSAGE) is not None
        line = sim.stop()
        late = {conn.mav.srcComponent: _drain(conn) for conn in (signed, unsigned, wrong)}
    finally:
        sim.stop()
        sim.close_clients()
    assert "signing on:" in line and "refused 6 unsigned, 1 bad signature, 2 replayed" in line, line
    everything = [m for msgs in late.values() for m in msgs]
    assert not {m.get_type() for m in everything} & {"MISSION_ACK", "PARAM_VALUE"}, "no reply to PARAM_SET, MISSION"
    for component in (unsigned.mav.srcComponent, wrong.mav.srcComponent):
        assert not [m for m in everything if m.get_type() == "COMMAND_ACK" and m.target_component == component]
    assert [m for m in everything if m.get_type() == "HEARTBEAT" and m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED] == []


@pytest.mark.slow
def test_setup_signing_sets_rotates_and_clears_the_key() -> None:
    sim = SignedSim("ardupilot")
    try:
        gcs = sim.client(None)
        # MAVProxy's 'signing setup PASSPHRASE': SETUP_SIGNING (unsigned: the vehicle has no key yet), then sign
        gcs.mav.setup_signing_send(1, 1, list(KEY), timestamp_now(time.time()))
        gcs.setup_signing(KEY, sign_outgoing=True, allow_unsigned_callback=None)
        assert gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=10)._signed
        stranger = sim.client(None)
        stranger.mav.setup_signing_send(1, 1, list(OTHER_KEY), timestamp_now(time.time()))   # refused: unsigned
        gcs.mav.command_long_send(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                  0, 0, 0, 0, 0, 0)
        assert _ack(gcs, M.MAV_CMD_REQUEST_MESSAGE) is not None, "the stranger did not change the key"
        # rotation: signed with the current key
        gcs.mav.setup_signing_send(1, 1, list(OTHER_KEY), timestamp_now(time.time()))
        gcs.setup_signing(OTHER_KEY, sign_outgoing=True, allow_unsigned_callback=None)
        assert gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=10)._signed
        # all zeros, signed: signing off; then an unsigned client is obeyed again
        gcs.mav.setup_signing_send(1, 1, [0] * 32, 0)
        plain = sim.client(None)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:      # the vehicle stops signing
            heartbeat = plain.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
            if heartbeat is not None and not heartbeat.get_header().incompat_flags & M.MAVLINK_IFLAG_SIGNED:
                break
        else:
            raise AssertionError("the vehicle still signs after an all-zero SETUP_SIGNING")
        _request_version(plain)
        assert _ack(plain, M.MAV_CMD_REQUEST_MESSAGE) is not None
    finally:
        line = sim.stop()
        sim.close_clients()
    assert "signing off:" in line and "refused 1 unsigned" in line and "key changed 3x" in line, line


@pytest.mark.slow
@pytest.mark.parametrize("autopilot, text", [("ardupilot", "Won't setup signing when armed"),
                                             ("px4", "MAVLink signing: rejected while armed")])
def test_no_key_change_while_armed(autopilot: str, text: str) -> None:
    sim = SignedSim(autopilot, "--signing-key", PASSPHRASE)
    try:
        gcs = sim.client(KEY)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:     # forced arm; refused until the autopilot has booted
            gcs.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 21196, 0, 0, 0, 0, 0)
            ack = _ack(gcs, M.MAV_CMD_COMPONENT_ARM_DISARM, timeout=2)
            if ack is not None and ack.result == M.MAV_RESULT_ACCEPTED:
                break
        assert gcs.recv_match(type="HEARTBEAT", condition="HEARTBEAT.base_mode & 128", blocking=True, timeout=10)
        gcs.mav.setup_signing_send(1, 1, list(OTHER_KEY), timestamp_now(time.time()))
        said = gcs.recv_match(type="STATUSTEXT", condition=f"STATUSTEXT.text == {text!r}", blocking=True, timeout=10)
        assert said is not None and said._signed, "refused, and still signed with the old key"
        _request_version(gcs)
        assert _ack(gcs, M.MAV_CMD_REQUEST_MESSAGE) is not None, "the old key still commands"
    finally:
        line = sim.stop()
        sim.close_clients()
    assert "key changed" not in line, line


@pytest.mark.slow
def test_allow_refuses_other_hosts_on_tcp_and_udp() -> None:
    """--allow 127.0.0.1; the stranger speaks from 127.0.0.2 (also loopback, another address)."""
    gcs_udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs_udp.bind(("127.0.0.1", 0))
    gcs_udp.settimeout(10)
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    stranger.bind(("127.0.0.2", 0))
    sim = BundledSim(room="open_field", port=gcs_udp.getsockname()[1], tcp=True,
                     extra_args=["--allow", "127.0.0.1", "--duration", "300"]).start()
    parser, acks = M.MAVLink(None), []
    try:
        with socket.create_connection(("127.0.0.1", sim.tcp_port), timeout=10, source_address=("127.0.0.2", 0)) as tcp:
            assert tcp.recv(4096) == b"", "a TCP client from a host not allowed is closed at once"
        _data, sim_addr = gcs_udp.recvfrom(65535)
        gcs = M.MAVLink(None, srcSystem=255, srcComponent=190)
        for _ in range(3):
            stranger.sendto(gcs.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
                            .pack(gcs), sim_addr)
        # the allowed station, after the stranger on the same socket: its answer means the others were read
        gcs_udp.sendto(gcs.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 242, 0, 0, 0, 0, 0, 0).pack(gcs),
                       sim_addr)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not acks:
            acks = [m for m in parser.parse_buffer(gcs_udp.recv(65535)) or [] if m.get_type() == "COMMAND_ACK"]
        assert acks, "the allowed host is answered"
    finally:
        out = sim.stop()
    assert sim.process.returncode == 0, sim.stderr
    line = out.strip().splitlines()[-1]
    assert "--allow 127.0.0.1/32 refused 4" in line, line
    gcs_udp.settimeout(0.2)
    try:
        while True:       # replies go to --out: any answer to the stranger's requests would be here
            acks += [m for m in parser.parse_buffer(gcs_udp.recv(65535)) or [] if m.get_type() == "COMMAND_ACK"]
    except socket.timeout:
        pass
    gcs_udp.close()
    stranger.close()
    assert len(acks) == 1, acks


@pytest.mark.parametrize("args, words", [
    (["--signing-key", ""], "--signing-key: the passphrase is empty"),
    (["--signing-key", "@/no/such/key.txt"], "--signing-key @/no/such/key.txt: no such file"),
    (["--allow", "not a host!"], "--allow 'not a host!'"),
])
def test_bad_signing_and_allow_flags_give_one_line(args: list[str], words: str) -> None:
    out = subprocess.run([sys.executable, "-m", "sim_bridge", *args], cwd=REPO, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gcs-sim: error:") and words in lines[0], out.stderr


def test_empty_key_file_is_one_clear_error(tmp_path: Path) -> None:
    empty = tmp_path / "empty.txt"
    empty.write_text("\n\n")
    with pytest.raises(SigningKeyError, match="holds no passphrase"):
        key_from_flag(f"@{empty}")


def test_the_key_is_mavproxys_sha256_of_the_passphrase(tmp_path: Path) -> None:
    # MAVProxy mavproxy_signing.py passphrase_to_key: hashlib sha256 over the passphrase
    assert passphrase_key(PASSPHRASE) == KEY
    (tmp_path / "k").write_text(PASSPHRASE + "\r\n")
    assert key_from_flag(f"@{tmp_path / 'k'}") == KEY
    assert key_from_flag(PASSPHRASE) == KEY


def test_timestamps_count_10us_since_2015() -> None:
    assert timestamp_now(1420070400.0) == 0
    assert timestamp_now(1420070401.0) == 100_000
    assert timestamp_now(0.0) == 0


def _signed_frame(key: bytes, timestamp: int, link_id: int = 0, sender: int = 255):
    """A COMMAND_LONG signed by a real pymavlink MAVLink object, parsed back as the simulator receives it."""
    mav = M.MAVLink(None, srcSystem=sender, srcComponent=190)
    mav.signing.secret_key, mav.signing.sign_outgoing = key, True
    mav.signing.link_id, mav.signing.timestamp = link_id, timestamp
    data = mav.command_long_encode(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(mav)
    return M.MAVLink(None).parse_buffer(data)[0]


def test_a_forged_packet_cannot_push_a_stream_into_the_future() -> None:
    """pymavlink's own check stores the timestamp before it checks the signature; the C library (and we) do not."""
    signing = SimSigning("ardupilot", KEY)
    now = timestamp_now(time.time())
    forged = _signed_frame(OTHER_KEY, now + 10**12)       # same stream, far future, wrong key
    assert not signing.accept(forged)
    genuine = _signed_frame(KEY, now + 5)
    assert signing.accept(genuine)
    assert not signing.accept(genuine), "the same packet twice is a replay"
    assert signing.accept(_signed_frame(KEY, now + 6))
    assert not signing.accept(_signed_frame(KEY, now - 61 * 100_000, link_id=7)), "a new stream a minute behind"
    assert (signing.counts.bad_signature, signing.counts.replayed, signing.counts.old_stream) == (1, 1, 1)


def test_packets_stamped_before_the_key_was_set_are_refused() -> None:
    """A restarted simulator has an empty stream table: the start time is the floor, not a minute before."""
    before = timestamp_now(time.time())
    signing = SimSigning("px4", KEY)
    assert not signing.accept(_signed_frame(KEY, before - 1)), "captured before the simulator started"
    assert signing.accept(_signed_frame(KEY, timestamp_now(time.time()) + 1, link_id=1))
    assert signing.counts.old_stream == 1


def test_mutated_signed_frames_never_pass() -> None:
    """Any change to a signed frame that still parses (CRC recomputed) fails the signature; nothing raises."""
    import random

    rng = random.Random(12)
    mav = M.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.signing.secret_key, mav.signing.sign_outgoing = KEY, True
    mav.signing.timestamp = timestamp_now(time.time()) + 100_000
    signing = SimSigning("ardupilot", KEY)
    passed = 0
    for n in range(2000):
        good = bytearray(mav.command_long_encode(1, 1, 400, 0, 1, 21196, 0, 0, 0, 0, n).pack(mav))
        bad = bytearray(good)
        for _ in range(rng.randint(1, 3)):
            bad[rng.randrange(3, len(bad))] ^= 1 << rng.randrange(8)
        if bad[2] & M.MAVLINK_IFLAG_SIGNED:       # keep it parseable: recompute the CRC over the mutation
            crc = mavutil.x25crc(bytes(bad[1:-15]))
            crc.accumulate(bytes([M.MAVLink_command_long_message.crc_extra]))
            bad[-15:-13] = crc.crc.to_bytes(2, "little")
        parser = M.MAVLink(None)
        parser.robust_parsing = True          # as the simulator parses
        for msg in parser.parse_buffer(bytes(bad)) or []:
            if msg.get_type() != "BAD_DATA" and bytes(msg.get_msgbuf()) != bytes(good):
                passed += signing.accept(msg)
    assert passed == 0
    assert signing.counts.bad_signature > 1000


def test_the_firmwares_unsigned_exceptions_pass_and_nothing_else() -> None:
    for autopilot, passes in (("ardupilot", "radio_status"), ("px4", "collision")):
        signing = SimSigning(autopilot, KEY)
        mav = M.MAVLink(None, srcSystem=3, srcComponent=68)
        radio = mav.radio_status_encode(200, 190, 100, 0, 0, 0, 0).pack(mav)
        collision = mav.collision_encode(0, 1, 1, 0, 10.0, 1.0, 1.0).pack(mav)
        heartbeat = mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav)
        verdicts = {name: signing.accept(M.MAVLink(None).parse_buffer(data)[0])
                    for name, data in (("radio_status", radio), ("collision", collision), ("heartbeat", heartbeat))}
        assert verdicts["radio_status"] and verdicts[passes] and not verdicts["heartbeat"], (autopilot, verdicts)
        assert verdicts["collision"] == (autopilot == "px4")
