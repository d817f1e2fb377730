"""End to end from a cold start: speech -> gcs-voice (the real CLI) -> gcs-sim booting like the real autopilot.

``python -m gcs_voice --takeoff 1.5 --say ...`` and ``gcs-sim --cold-start`` are started together, as a user who
starts both at once would: gcs-voice first, the simulator once gcs-voice has loaded its recogniser and says its
session has started (so the vehicle boots while the session watches, however slow the machine: boot times x0.2,
ArduCopter gets a position after 8.2 s; PX4 at real speed, 3.9 s; before, with the simulator first, a loaded
machine loaded the recogniser for longer than PX4 booted and the session never saw it waiting). The session must
say what the vehicle waits for, arm only in GUIDED / Hold once it is ready, fly the spoken commands, and end
after "land" only when the vehicle reports itself landed and disarmed. Checked from the session log and
the tlog it leaves.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink import mavutil

from e2e_support import FlyProcess, demo_wav, require_parts
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("parts")]
ARM_MODE = {"ardupilot": 4, "px4": 50593792}   # GUIDED; PX4 Hold (AUTO.LOITER)
#: ArduCopter's 41 s boot x0.2; PX4's 3.9 s at real speed
BOOT_SCALE = {"ardupilot": "0.2", "px4": "1.0"}


@pytest.fixture
def parts() -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry", "gcs_voice.audio.sources")


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_spoken_flight_from_a_cold_start(autopilot: str, tmp_path: Path) -> None:
    wavs = [demo_wav("go_forward"), demo_wav("hold"), demo_wav("land_the_drone")]
    sim = BundledSim(autopilot=autopilot, room="open_field", log_path=tmp_path / "sim.log",
                     extra_args=["--cold-start", "--boot-scale", BOOT_SCALE[autopilot]])
    # --wait: the simulator starts only now, and may take long to load beside other work
    fly = FlyProcess(sim.connection, wavs, tmp_path, gap_s=3.0, hold_s=1.0, extra=["--wait", "120"])
    try:
        fly.started()
        with sim:
            result = fly.finish(timeout_s=200.0)
    finally:
        if fly.proc.poll() is None:
            fly.proc.kill()
            fly.proc.communicate()
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    ready = [e for e in result.events if e["kind"] == "ready"]
    waited = {w for e in ready for w in e.get("waiting_for", "").split(", ") if w}
    assert ("position (EKF)" if autopilot == "ardupilot" else "pre-arm checks") in waited, ready
    flights = {e["what"]: e for e in result.kinds("flight") if e.get("ok") is not None}
    assert flights["take_off"]["ok"] and flights["land"]["ok"], result.kinds("flight")
    assert flights["landed"]["ok"], result.kinds("flight")   # "landed and disarmed" before the session ended
    assert [c["action"] for c in result.commands()] == ["go_forward", "stop", "land"]
    log = mavutil.mavlink_connection(str(result.tlog))
    mode, arms = None, []
    while (msg := log.recv_match(type=["HEARTBEAT", "COMMAND_LONG"])) is not None:
        if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1:
            mode = msg.custom_mode
        elif msg.get_type() == "COMMAND_LONG" and msg.command == 400 and msg.param1 == 1:
            arms.append(mode)
    assert arms and all(m == ARM_MODE[autopilot] for m in arms), arms
