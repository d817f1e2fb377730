"""``gcs-voice`` (fly) user mistakes: each is one line on stderr and exit status 2, never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from e2e_support import REPO, demo_wav
from gcs_voice.session.sim_process import free_udp_port


def _fly(*args: str, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gcs_voice", *args, "--headless", "--log-dir", str(tmp_path)],
                          cwd=REPO, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("args, message", [
    (["--connect", "udpin://0.0.0.0:14540"], "udpin"),
    (["--udp", "70000"], "70000"),
    (["--say", "/no/such/file.wav", "--engine", "sphinx"], "/no/such/file.wav"),
    (["--listen-wav", "/no/such/room.wav", "--engine", "sphinx"], "/no/such/room.wav"),
    (["--listen-wav", __file__, "--engine", "sphinx"], "not a WAV"),
    (["--listen-wav", "a.wav", "--say", "b.wav"], "not allowed with"),
    (["--engine", "nonsense"], "nonsense"),
    (["--matcher", "nonsense", "--engine", "sphinx"], "nonsense"),
])
def test_bad_input_is_one_line(args: list[str], message: str, tmp_path: Path) -> None:
    proc = _fly(*args, tmp_path=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("gcs-voice: error:") and proc.stderr.count("\n") == 1, proc.stderr
    assert message in proc.stderr
    assert list(tmp_path.iterdir()) == []  # nothing was flown, so no session logs


def test_no_vehicle_is_one_line_exit_2_as_logged_and_leaves_no_files(tmp_path: Path) -> None:
    import json

    port = free_udp_port()
    proc = _fly("--connect", f"udpin:127.0.0.1:{port}", "--wait", "1", "--engine", "sphinx", "--say",
                str(demo_wav("hold")), "--log-name", "s", "--json", tmp_path=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("gcs-voice: error: no vehicle heard") and proc.stderr.count("\n") == 1
    end = [json.loads(line) for line in proc.stdout.splitlines() if '"phase": "end"' in line]
    assert [e["exit_code"] for e in end] == [proc.returncode]  # what the log says is what the process did
    assert list(tmp_path.iterdir()) == []  # nothing heard, nothing flown: no empty .tlog / .jsonl


@pytest.mark.parametrize("args, flag", [
    (["--speed", "1e9"], "--speed"),
    (["--vertical-speed", "0"], "--vertical-speed"),
    (["--fence", "-1"], "--fence"),
    (["--floor", "nan"], "--floor"),
    (["--ceiling", "1e6"], "--ceiling"),
    (["--takeoff", "1e6"], "--takeoff"),
    (["--takeoff", "-3"], "--takeoff"),
    (["--takeoff", "0"], "--takeoff"),
    (["--takeoff-alt", "0.1"], "--takeoff-alt"),
    (["--floor", "3", "--ceiling", "2"], "--floor"),
    (["--takeoff", "8", "--ceiling", "5"], "--takeoff"),
    (["--wait", "nan"], "--wait"),  # waited forever
    (["--wait", "-1"], "--wait"),
    (["--gap", "-1"], "--gap"),
    (["--hold", "inf"], "--hold"),
    (["--log-name", ""], "--log-name"),  # wrote hidden .tlog / .jsonl
    (["--log-name", "../x/y"], "--log-name"),
])
def test_motion_settings_out_of_range_are_refused_naming_the_flag(args: list[str], flag: str,
                                                                   tmp_path: Path) -> None:
    # No vehicle and a WAV that does not exist: only parsing can have refused it, before anything else.
    proc = _fly(*args, "--say", "/no/such.wav", "--wait", "0.1", tmp_path=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("gcs-voice: error:") and proc.stderr.count("\n") == 1, proc.stderr
    assert flag in proc.stderr and "_m" not in proc.stderr.split("ceiling_m")[0], proc.stderr
    assert "/no/such.wav" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_help_states_every_motion_range() -> None:
    from gcs_voice.cli import build_parser
    from gcs_voice.settings import setting_limits

    text = " ".join(build_parser("fly").format_help().split())
    limits = setting_limits()
    for setting in ("horizontal_speed_m_s", "vertical_speed_m_s", "floor_m", "ceiling_m", "fence_radius_m",
                    "takeoff_altitude_m"):
        assert f"({limits[setting].describe()})" in text, setting


def test_kill_while_waiting_for_the_vehicle_exits_143_and_leaves_no_files(tmp_path: Path) -> None:
    """SIGTERM (kill, a service manager, ``timeout``) used to end the process on the spot, logs left behind."""
    import json
    import signal

    port = free_udp_port()
    proc = subprocess.Popen([sys.executable, "-m", "gcs_voice", "--connect", f"udpin:127.0.0.1:{port}", "--wait", "120",
                             "--engine", "sphinx", "--say", str(demo_wav("hold")), "--headless", "--json",
                             "--log-dir", str(tmp_path)], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        first = json.loads(proc.stdout.readline())  # the session has started: it is waiting for a vehicle
        assert first["phase"] == "start"
        proc.send_signal(signal.SIGTERM)
        rest, _err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 143
    assert json.loads(rest.splitlines()[-1])["exit_code"] == 143
    assert list(tmp_path.iterdir()) == []


def test_a_refused_takeoff_ends_the_session_at_once(tmp_path: Path) -> None:
    """--takeoff that the vehicle refuses (arming never allowed) ends the session with exit 1 right away,
    instead of the script waiting out its ready timeout (arm + take-off timeouts + 30 s)."""
    import json

    from link_peer import ScriptedVehicle

    config = tmp_path / "quick.toml"
    config.write_text("[link]\narm_timeout_s = 2.0\narm_retry_s = 0.5\n")
    with ScriptedVehicle(autopilot="ardupilot", arm_refusals=10_000) as vehicle:
        proc = _fly("--connect", vehicle.connection, "--wait", "10", "--engine", "sphinx", "--say",
                    str(demo_wav("hold")), "--takeoff", "1.5", "--config", str(config), "--json",
                    "--log-name", "s", tmp_path=tmp_path)
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert any(e["kind"] == "error" and "take_off failed" in e["msg"] for e in events)
    assert not any("did not become ready" in e["msg"] for e in events)  # the old way out: a 60 s wait
    assert events[-1]["phase"] == "end" and events[-1]["exit_code"] == 1
