"""End to end: espeak-ng speech -> PocketSphinx -> matcher -> bridge -> MAVLink -> the bundled simulator.

Each test starts ``python -m sim_bridge.cli`` on a free loopback port and flies it with
``python -m gcs_voice --connect ... --say ... --takeoff 1.5 --headless --json``, then checks what the
vehicle did from the tlog the session left (its own telemetry), not from what the bridge believed.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from e2e_support import SPEEDUP, angle_diff_deg, demo_wav, require_parts, run_fly, speech, speed_at
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("parts")]


@pytest.fixture
def parts() -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry", "gcs_voice.audio.sources")


def test_voice_flight_moves_turns_stops_and_lands_on_the_floor_rule(tmp_path: Path) -> None:
    out_of_domain = speech(tmp_path, "open the window")
    wavs = [out_of_domain, demo_wav("go_forward"), demo_wav("hold"), speech(tmp_path, "turn right"),
            demo_wav("go_forward"), demo_wav("go_down")]
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, wavs, tmp_path, gap_s=2.5, hold_s=5.0)
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    flight = result.flight()

    # What was heard and done: the out-of-domain sentence rejected with a reason, the rest acted on.
    rejected = result.kinds("rejected")
    assert len(rejected) == 1 and rejected[0]["source"] == out_of_domain.name and rejected[0]["reason"]
    commands = result.commands()
    assert [c["action"] for c in commands] == ["go_forward", "stop", "turn_right", "go_forward", "down"]
    t_fwd1, t_stop, t_turn, t_fwd2, t_down = (c["sent_t"] for c in commands)

    # Rejection: from the rejected utterance to the first command the vehicle stayed where it was.
    p_rej, p_fwd1 = flight.position_at(rejected[0]["t"]), flight.position_at(t_fwd1)
    assert math.dist(p_rej[:2], p_fwd1[:2]) < 0.3 and abs(p_rej[2] - p_fwd1[2]) < 0.2

    # go_forward at heading ~0: north, not east.
    h0 = flight.heading_at(t_fwd1)
    p_stop = flight.position_at(t_stop)
    leg1 = (p_stop[0] - p_fwd1[0], p_stop[1] - p_fwd1[1])
    forward1 = leg1[0] * math.cos(math.radians(h0)) + leg1[1] * math.sin(math.radians(h0))
    assert forward1 > 1.0 and abs(leg1[0] * -math.sin(math.radians(h0)) + leg1[1] * math.cos(math.radians(h0))) < 0.3

    # stop holds: slow by the time of the turn command.
    assert speed_at(flight, t_turn) < 0.15

    # turn_right: exactly 90 deg from the heading target, held.
    h_after_turn = flight.heading_at(t_fwd2)
    assert abs(angle_diff_deg(h_after_turn, h0) - 90.0) < 5.0

    # second go_forward is along the new heading (to the old right), and the shorter leg.
    p_down = flight.position_at(t_down)
    leg2 = (p_down[0] - flight.position_at(t_fwd2)[0], p_down[1] - flight.position_at(t_fwd2)[1])
    h2 = math.radians(h_after_turn)
    forward2 = leg2[0] * math.cos(h2) + leg2[1] * math.sin(h2)
    sideways2 = -leg2[0] * math.sin(h2) + leg2[1] * math.cos(h2)
    assert forward2 > 0.5 and abs(sideways2) < 0.3
    # Distances match the commanded speed and how long each action lasted on the vehicle's own (simulated)
    # clock, less the ~0.5 s the vehicle takes to reach the speed.
    speed_m_s = 0.5  # horizontal_speed_m_s in gcs_voice/data/settings.toml
    # A leg ends at the next command of any origin: the stop spotter may stop the vehicle while the next
    # utterance is still being said (a stop word, or a false alarm that the main decision then overrides).
    def leg_end(start: float) -> float:
        return min(c["sent_t"] for c in result.kinds("command") if c.get("sent_t") and c["sent_t"] > start)

    for travelled, start, end in ((forward1, t_fwd1, leg_end(t_fwd1)), (forward2, t_fwd2, leg_end(t_fwd2))):
        expected = speed_m_s * (flight.vehicle_time_at(end) - flight.vehicle_time_at(start))
        assert 0.75 * expected < travelled < 1.1 * expected, (travelled, expected)

    # down stops by itself 0.5 m above the ground; the session ends with the vehicle stopped.
    final_alt = flight.track.alt_m[-1]
    assert 0.4 <= final_alt <= 0.6, final_alt
    assert min(flight.track.alt_m[-20:]) > 0.35
    assert speed_at(flight, flight.track.t_s[-1]) < 0.15
    assert any(e["kind"] == "warning" and "floor" in e["msg"] for e in result.events)
    assert result.events[-1]["kind"] == "session" and result.events[-1]["phase"] == "end"


def test_px4_personality_and_fence(tmp_path: Path) -> None:
    config = tmp_path / "settings.toml"
    config.write_text("[safety]\nfence_radius_m = 5.0\n")  # the --fence flag below wins over the file
    with BundledSim(autopilot="px4", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, [demo_wav("go_forward")], tmp_path, hold_s=6.0,
                         extra=["--config", str(config), "--fence", "2"])
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    flight = result.flight()
    assert flight.autopilot == 12  # MAV_AUTOPILOT_PX4
    assert [c["action"] for c in result.commands()] == ["go_forward"]
    # PX4 flies our setpoints in OFFBOARD (custom_mode main mode 6).
    assert any((mode >> 16) & 0xFF == 6 for _t, mode, armed in flight.modes if armed)
    # The mapper stops outward motion at the fence; the vehicle brakes and stays inside with a small overrun.
    t_cmd = result.commands()[0]["sent_t"]
    distances = [math.hypot(n, e) for t, n, e in zip(flight.track.t_s, flight.track.north_m, flight.track.east_m)
                 if t > t_cmd]
    assert 1.7 < max(distances) < 2.7
    assert any(e["kind"] == "refused" and "fence" in e.get("reason", "") for e in result.events)
    assert speed_at(flight, flight.track.t_s[-1]) < 0.15


@pytest.mark.parametrize("signame, status", [("SIGINT", 130), ("SIGTERM", 143)])
def test_ctrl_c_stops_the_vehicle_before_exit(signame: str, status: int, tmp_path: Path) -> None:
    """Ctrl-C, and a plain ``kill`` (SIGTERM: a service manager, ``timeout``), stop the vehicle first."""
    import json
    import signal
    import subprocess
    import sys

    from e2e_support import REPO
    from gcs_voice.session.flight_log import read_flight

    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        cmd = [sys.executable, "-m", "gcs_voice", "--connect", sim.connection, "--say", str(demo_wav("go_forward")),
               "--hold", "60", "--takeoff", "1.5", "--engine", "sphinx", "--headless", "--json",
               "--log-dir", str(tmp_path), "--log-name", "flight"]
        proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            moving = False
            for line in proc.stdout:
                event = json.loads(line)
                if event["kind"] == "command" and event.get("action") == "go_forward":
                    moving = True
                    break
            assert moving, proc.stderr.read()
            import time

            time.sleep(1.0)
            interrupted_at = time.time()
            proc.send_signal(getattr(signal, signame))
            rest, err = proc.communicate(timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == status, err
    events = [json.loads(line) for line in rest.splitlines() if line.startswith("{")]
    interrupt = [e for e in events if e["kind"] == "session" and e.get("phase") == "interrupt"]
    assert interrupt and interrupt[0]["halted_t"] >= interrupted_at and interrupt[0]["signal"] == signame
    assert events[-1]["phase"] == "end" and events[-1]["exit_code"] == status
    # The SIGINT handler itself switches the setpoint source to stop: every setpoint decided after it ran
    # is a stop, whatever the load (the .tlog stamps a setpoint with the time it was decided). The
    # reference is the process's own handler time, not ours: under load the signal can wait a while
    # for the process to be scheduled, and nothing can stop a vehicle before it knows.
    halted_t = interrupt[0]["halted_t"]
    setpoints = read_flight(tmp_path / "flight.tlog").setpoints
    after = [s for s in setpoints if s.t_s > halted_t]
    assert after and all((s.vx_m_s, s.vy_m_s, s.vz_m_s) == (0.0, 0.0, 0.0) for s in after)
    assert any(abs(s.vx_m_s) + abs(s.vy_m_s) > 0.4 for s in setpoints if s.t_s < interrupted_at)
