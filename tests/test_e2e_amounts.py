"""End to end with amounts (issue 33): espeak-ng "move forward three metres" and "turn left forty five degrees"
-> Whisper scoring -> bridge -> MAVLink -> the bundled simulator, ArduPilot and PX4 personalities.

The vehicle's own telemetry (the tlog) must show 3 m flown along the heading, within 0.2 m, ending by itself
(no stop was said), and a 45 degree turn, within 3 degrees.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from e2e_support import SPEEDUP, angle_diff_deg, require_parts, run_fly, speech, speed_at
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_bounded_motions_fly_the_amount_said(autopilot: str, tmp_path: Path, whisper_model_dir: Path) -> None:
    require_parts("sim_bridge.cli", "faster_whisper", "gcs_voice.audio.sources")
    wavs = [speech(tmp_path, "move forward three metres", speed_wpm=175),
            speech(tmp_path, "turn left forty five degrees", speed_wpm=175)]
    with BundledSim(autopilot=autopilot, speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, wavs, tmp_path, gap_s=9.0, hold_s=5.0, timeout_s=600.0,
                         extra=["--engine", "whisper", "--model", str(whisper_model_dir), "--no-stop-spotter"])
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    commands = result.commands()
    assert [(c["action"], c.get("amount")) for c in commands] == [("go_forward", "3 m"), ("turn_left", "45°")], \
        [e["msg"] for e in result.events]
    # what the feedback says back ("going forward, 3 metres": tests/test_feedback.py) is the amount as said
    assert [c.get("said_amount") for c in commands] == [{"value": 3, "unit": "m", "height": False, "label": "3 m"},
                                                        {"value": 45, "unit": "deg", "height": False, "label": "45°"}]
    flight = result.flight()
    t_fwd, t_turn = (c["sent_t"] for c in commands)
    # the forward leg ended by itself: stopped before the turn was said, 3 m along the heading
    assert any("3 m reached" in e["msg"] for e in result.events if e["kind"] == "warning"), \
        [e["msg"] for e in result.events]
    h0 = math.radians(flight.heading_at(t_fwd))
    p0, p1 = flight.position_at(t_fwd), flight.position_at(t_turn)
    forward = (p1[0] - p0[0]) * math.cos(h0) + (p1[1] - p0[1]) * math.sin(h0)
    sideways = -(p1[0] - p0[0]) * math.sin(h0) + (p1[1] - p0[1]) * math.cos(h0)
    assert abs(forward - 3.0) <= 0.2 and abs(sideways) <= 0.2, (forward, sideways)
    assert speed_at(flight, t_turn) < 0.15
    # the turn: 45 degrees left of the heading the vehicle held, and the point held while turning
    turned = angle_diff_deg(flight.heading_at(flight.track.t_s[-1]), flight.heading_at(t_turn))
    assert abs(turned + 45.0) <= 3.0, turned
    p2 = flight.position_at(flight.track.t_s[-1])
    assert math.dist(p1[:2], p2[:2]) <= 0.2
    print(f"{autopilot}: said 3 m, flew {forward:.3f} m (sideways {sideways:+.3f}); said 45 deg left, "
          f"turned {-turned:.2f} deg")  # the figures for docs/bench/amounts.md (pytest -s)
