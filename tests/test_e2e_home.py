"""End to end, "return home" (issue 33): espeak-ng speech -> Whisper scoring -> bridge -> MAVLink -> the bundled
simulator (real JSBSim physics).

return_home_lands = 0 (the default): the vehicle flies straight back to home at its height and holds there, by
itself, voice still in charge. return_home_lands = 1: the autopilot's own RTL flies it home and lands it.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from e2e_support import SPEEDUP, require_parts, run_fly, speech, speed_at
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_return_home_flies_back_at_its_height_and_holds(autopilot: str, tmp_path: Path, whisper_model_dir: Path) -> None:
    require_parts("sim_bridge.cli", "faster_whisper", "gcs_voice.audio.sources")
    wavs = [speech(tmp_path, "move forward three metres", speed_wpm=175),
            speech(tmp_path, "go left two metres", speed_wpm=175),
            speech(tmp_path, "return home", speed_wpm=175)]
    with BundledSim(autopilot=autopilot, speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, wavs, tmp_path, gap_s=9.0, hold_s=12.0, timeout_s=600.0,
                         extra=["--engine", "whisper", "--model", str(whisper_model_dir), "--no-stop-spotter"])
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    commands = result.commands()
    said = [e["msg"] for e in result.events]
    assert [(c["action"], c.get("amount")) for c in commands][:2] == [("go_forward", "3 m"), ("go_left", "2 m")], said
    assert [c["action"] for c in commands][2:] == ["return_home"], said
    assert any("home reached" in e["msg"] for e in result.kinds("warning")), said
    flight = result.flight()
    t_start, t_home = commands[0]["sent_t"], commands[2]["sent_t"]
    start, turned_home, end = (flight.position_at(t) for t in (t_start, t_home, flight.track.t_s[-1]))
    assert math.dist(start[:2], turned_home[:2]) > 3.0  # it was away (3 m forward, 2 m left)
    assert math.dist(start[:2], end[:2]) <= 0.2, (start, end)  # home: where it hovered after take-off
    assert abs(end[2] - turned_home[2]) <= 0.2, (turned_home, end)  # at the height it was flying
    assert speed_at(flight, flight.track.t_s[-1]) < 0.15  # holding there
    print(f"{autopilot}: {math.dist(start[:2], turned_home[:2]):.2f} m from home, ended "
          f"{math.dist(start[:2], end[:2]):.3f} m from it, {end[2] - turned_home[2]:+.3f} m in height")


def test_return_home_with_the_autopilot_rtl_lands_at_home(tmp_path: Path, whisper_model_dir: Path) -> None:
    require_parts("sim_bridge.cli", "faster_whisper", "gcs_voice.audio.sources")
    config = tmp_path / "rtl.toml"
    config.write_text("[motion]\nreturn_home_lands = 1\n", encoding="utf-8")
    wavs = [speech(tmp_path, "move forward three metres", speed_wpm=175),
            speech(tmp_path, "return home", speed_wpm=175)]
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, wavs, tmp_path, gap_s=9.0, hold_s=2.0, timeout_s=600.0,
                         extra=["--engine", "whisper", "--model", str(whisper_model_dir), "--no-stop-spotter",
                                "--config", str(config)])
    said = [e["msg"] for e in result.events]
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    assert [c["action"] for c in result.commands()] == ["go_forward", "return_home"], said
    assert any(e.get("what") == "return_home" and e.get("ok") for e in result.kinds("flight")), said
    assert any(e.get("what") == "landed" and e.get("ok") for e in result.kinds("flight")), said
    flight = result.flight()
    rtl = [t for t, mode, _armed in flight.modes if mode == 6]  # ArduCopter RTL
    assert rtl, "the vehicle never showed RTL"
    start = flight.position_at(result.commands()[0]["sent_t"])
    end = flight.position_at(flight.track.t_s[-1])
    assert math.dist(start[:2], end[:2]) <= 0.5 and end[2] > -0.3, (start, end)  # on the ground at home
    assert flight.modes[-1][2] is False  # disarmed
