"""The ground station's side of signing and of the vehicle lock, against the real gcs-sim on loopback.

End to end: ``gcs-voice --signing-key @FILE --require-signed --say go_forward.wav --takeoff 1.5`` flies
``gcs-sim --signing-key @FILE``; the vehicle's own telemetry in the tlog says it climbed and moved, and
every packet the bridge sent carries a signature. A wrong key is said in one line; the signing timestamp
never goes back, across sessions too; ``--lock-vehicle`` stops a stranger getting our setpoints.
"""

from __future__ import annotations

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

from e2e_support import SPEEDUP, demo_wav, require_parts, run_fly  # noqa: E402
from gcs_voice.link import VehicleLink  # noqa: E402
from gcs_voice.link.security import LinkSecurity  # noqa: E402
from gcs_voice.link.signing import (GroundSigning, TimestampStore, verify_signature, key_from_flag,  # noqa: E402
                                    timestamp_now)
from gcs_voice.session.sim_process import BundledSim  # noqa: E402
from gcs_voice.settings import load_settings  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
PASSPHRASE = "tres tristes tigres"


def _key_file(tmp_path: Path, passphrase: str = PASSPHRASE) -> Path:
    path = tmp_path / "signing.key"
    path.write_text(passphrase + "\n")
    path.chmod(0o600)
    return path


def _signed_frames(tlog: Path, sender: int) -> tuple[int, int, list[int]]:
    """(signed, unsigned, timestamps) of the packets ``sender`` wrote to a .tlog."""
    signed = unsigned = 0
    stamps = []
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    while True:
        msg = log.recv_match()
        if msg is None:
            break
        if msg.get_srcSystem() != sender or msg.get_type() == "BAD_DATA":
            continue
        buf = bytes(msg.get_msgbuf())
        if buf[2] & M.MAVLINK_IFLAG_SIGNED:
            signed += 1
            stamps.append(int.from_bytes(buf[-12:-6], "little"))
        else:
            unsigned += 1
    return signed, unsigned, stamps


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_bridge_flies_a_signed_vehicle(autopilot: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry")
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    key = _key_file(tmp_path)
    with BundledSim(autopilot=autopilot, speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log",
                    extra_args=["--signing-key", f"@{key}"]) as sim:
        result = run_fly(sim.connection, [demo_wav("go_forward")], tmp_path, hold_s=4.0,
                         extra=["--signing-key", f"@{key}", "--require-signed"])
    assert result.returncode == 0, result.stderr + result.stdout[-3000:]
    assert [c["action"] for c in result.commands()] == ["go_forward"]
    assert not [e for e in result.events if "sign" in e.get("msg", "")], "no signing warning with the right key"
    flight = result.flight()
    t_forward = result.commands()[0]["sent_t"]
    p0, p1 = flight.position_at(t_forward), flight.position_at(flight.track.t_s[-1])
    assert 1.2 < p0[2] < 1.9, p0                                  # took off to 1.5 m
    assert (p1[0] - p0[0]) ** 2 + (p1[1] - p0[1]) ** 2 > 1.0, (p0, p1)   # and moved over a metre
    signed, unsigned, stamps = _signed_frames(result.tlog, sender=255)
    assert signed > 50 and unsigned == 0, (signed, unsigned)
    assert all(b > a for a, b in zip(stamps, stamps[1:])), "our timestamps only go forward"
    vehicle_signed, vehicle_unsigned, _ = _signed_frames(result.tlog, sender=1)
    assert vehicle_signed > 50 and vehicle_unsigned == 0
    saved = (tmp_path / "state" / "gcs-voice" / "signing-timestamp").read_text().split()
    assert saved[1] == "clean" and int(saved[0]) >= stamps[-1]


@pytest.mark.slow
def test_a_wrong_key_is_said_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    key = _key_file(tmp_path)
    with BundledSim(autopilot="ardupilot", room="open_field", extra_args=["--signing-key", f"@{key}"]) as sim:
        strict = subprocess.run([sys.executable, "-m", "gcs_voice.link", "--connect", sim.connection,
                                 "--signing-key", "another passphrase", "--require-signed", "--wait", "3"],
                                cwd=REPO, capture_output=True, text=True, timeout=60)
        lenient = subprocess.run([sys.executable, "-m", "gcs_voice.link", "--connect", sim.connection,
                                  "--signing-key", "another passphrase", "--seconds", "1"],
                                 cwd=REPO, capture_output=True, text=True, timeout=60)
    assert strict.returncode == 2
    lines = strict.stderr.strip().splitlines()
    assert len(lines) == 1 and "no vehicle heard" in lines[0] and "packets were refused" in lines[0], strict.stderr
    assert lenient.returncode == 0, lenient.stderr
    assert lenient.stdout.count("the vehicle signs with another key") == 1, lenient.stdout


@pytest.mark.slow
def test_an_unsigned_vehicle_is_flown_but_the_user_is_told(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    with BundledSim(autopilot="px4", room="open_field") as sim:
        out = subprocess.run([sys.executable, "-m", "gcs_voice.link", "--connect", sim.connection,
                              "--signing-key", PASSPHRASE, "--seconds", "1"],
                             cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("packets are not signed") == 1 and "link ok | PX4" in out.stdout, out.stdout


@pytest.mark.parametrize("value, words", [
    ("", "--signing-key: the passphrase is empty"),
    ("@/no/such/file", "--signing-key @/no/such/file: no such file"),
])
def test_bad_keys_are_one_line_before_anything_opens(value: str, words: str, tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, "-m", "gcs_voice", "--udp", "14551", "--signing-key", value,
                          "--log-dir", str(tmp_path)], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [f"gcs-voice: error: {words}"]
    assert list(tmp_path.iterdir()) == [], "no empty logs are left behind"


def test_an_empty_key_file_and_require_without_key_are_refused(tmp_path: Path) -> None:
    (tmp_path / "empty").write_text("\n")
    from gcs_voice.errors import LinkError

    with pytest.raises(LinkError, match="holds no passphrase"):
        key_from_flag(f"@{tmp_path / 'empty'}")
    with pytest.raises(LinkError, match="--require-signed needs --signing-key"):
        LinkSecurity(require_signed=True)


def _first_timestamp(store: TimestampStore) -> int:
    """Open a real pymavlink link with GroundSigning, send one HEARTBEAT, read its signature's timestamp."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx:
        rx.bind(("127.0.0.1", 0))
        rx.settimeout(5)
        conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{rx.getsockname()[1]}", source_system=255)
        signing = GroundSigning(key_from_flag(PASSPHRASE), store=store)
        signing.attach(conn)
        conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        data = rx.recv(512)
        signing.close()
        conn.close()
    assert data[2] & M.MAVLINK_IFLAG_SIGNED
    return int.from_bytes(data[-12:-6], "little")


def test_the_timestamp_survives_a_clock_set_back(tmp_path: Path) -> None:
    store = TimestampStore(tmp_path / "ts")
    first = _first_timestamp(store)
    assert abs(first - timestamp_now()) < 5 * 100_000, "10 µs units since 2015-01-01, near now"
    future = timestamp_now() + 3600 * 100_000          # as if the last session ran with a clock an hour ahead
    store.save(future, clean=True)
    assert _first_timestamp(store) == future + 1
    store.save(future, clean=False)                     # that session crashed: start a minute later
    assert _first_timestamp(store) == future + 60 * 100_000
    assert store.path.read_text().split()[1] == "clean"


def test_a_forged_packet_cannot_push_the_vehicles_stream_ahead() -> None:
    key = key_from_flag(PASSPHRASE)
    receiver = M.MAVLink(None)
    receiver.signing.secret_key = key
    now = timestamp_now()

    def frame(secret: bytes, stamp: int):
        mav = M.MAVLink(None, srcSystem=1, srcComponent=1)
        mav.signing.secret_key, mav.signing.sign_outgoing, mav.signing.timestamp = secret, True, stamp
        return bytearray(mav.heartbeat_encode(2, 3, 0, 0, 4).pack(mav))

    forged = frame(b"\x01" * 32, now + 10**12)
    assert not verify_signature(receiver, forged, 1, 1)
    assert verify_signature(receiver, frame(key, now), 1, 1), "the real vehicle is still heard"
    assert not verify_signature(receiver, frame(key, now), 1, 1), "a replay is not"
    # pymavlink's own check, for the record: the forged packet would have locked the real one out
    stock = M.MAVLink(None)
    stock.signing.secret_key = key
    assert not stock.check_signature(forged, 1, 1)
    assert not stock.check_signature(frame(key, now + 1), 1, 1)


@pytest.mark.slow
@pytest.mark.parametrize("lock", [False, True])
def test_lock_vehicle_keeps_setpoints_from_a_stranger(lock: bool, tmp_path: Path) -> None:
    settings = load_settings()
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    stranger.bind(("127.0.0.1", 0))
    events: list[str] = []
    with BundledSim(autopilot="ardupilot", room="open_field") as sim, \
            VehicleLink(sim.connection, settings, on_event=events.append,
                        security=LinkSecurity(lock_vehicle=lock)) as link:
        link.wait_vehicle(timeout_s=30)
        link.hold()
        parser = M.MAVLink(None)
        stranger.sendto(parser.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(parser),
                        ("127.0.0.1", sim.port))
        sent_before = link.setpoints_sent
        stranger.settimeout(0.1)
        got = []
        deadline = time.monotonic() + 30
        while link.setpoints_sent < sent_before + 20 and time.monotonic() < deadline:   # 2 s of stream
            try:
                got += [m.get_type() for m in parser.parse_buffer(stranger.recv(65535)) or []]
            except socket.timeout:
                pass
        assert link.setpoints_sent >= sent_before + 20
        assert link.state.link_ok, "the vehicle is still heard"
        assert link.request_telemetry().ok, "and still hears us: its ACKs come back"
    stranger.close()
    if lock:
        assert "SET_POSITION_TARGET_LOCAL_NED" not in got, got
        assert any(e.startswith("locked to vehicle system 1 at 127.0.0.1:") for e in events), events
    else:   # pymavlink's udpin: whoever sent one datagram gets a copy of the stream (docs/link.md)
        assert "SET_POSITION_TARGET_LOCAL_NED" in got, got
