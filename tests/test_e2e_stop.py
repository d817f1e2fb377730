"""A stop is never late: the stop spotter's stop reaches the vehicle while the main recogniser is still busy.

Flies the bundled simulator with ``python -m gcs_voice --say`` and Whisper base as the main recogniser
(seconds per utterance on a busy machine): "go forward", then a real recorded "stop". The stop setpoint
must be on the wire (the tlog) before the recogniser has even said what it heard in that "stop".
"""

from __future__ import annotations

from pathlib import Path

import pytest

from e2e_support import SPEEDUP, demo_wav, require_parts, run_fly, speed_at
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow]


def test_the_spotted_stop_is_on_the_wire_before_the_main_decision(tmp_path: Path, whisper_model_dir: Path,
                                                                   real_speech_dir: Path) -> None:
    require_parts("sim_bridge.cli", "faster_whisper")
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.audio.sources import read_wav
    from tools.speech.real_speech import load_recordings

    spotter = load_stop_spotter(["en"])
    stop = next(r.path for r in load_recordings(real_speech_dir, split="test")
                if r.action == "stop" and spotter.spot(read_wav(r.path)).fired)
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, [demo_wav("go_forward"), stop], tmp_path, gap_s=3.0, hold_s=3.0,
                         extra=["--engine", "whisper", "--model", str(whisper_model_dir)], timeout_s=600.0)
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    events = result.events
    # the spotter's stop: a stop command, or (Whisper has a domain ear to settle it) a hold of the moving vehicle
    spotted = next((e for e in events if e["kind"] == "spotted"), None)
    assert spotted is not None, [e["msg"] for e in events]
    held = [e for e in events if e["t"] >= spotted["t"] and e.get("sent_t")
            and ((e["kind"] == "command" and e.get("origin") == "spotter" and e["action"] == "stop")
                 or (e["kind"] == "paused" and e.get("state") == "paused"))]
    assert held, [e["msg"] for e in events]
    heard_stop = next(e for e in events if e["kind"] == "heard" and e["source"] == stop.name)
    stop_cmd = held[0]
    # order of events: utterance end -> spotted stop sent -> thinking... -> the recogniser's answer
    assert stop_cmd["sent_t"] < heard_stop["t"]
    assert any(e["kind"] == "thinking" and e["source"] == stop.name for e in events)
    # on the wire: a zero-velocity setpoint went out before the main recogniser had heard the word
    flight = result.flight()
    zero = [s for s in flight.setpoints if stop_cmd["sent_t"] - 0.01 <= s.t_s < heard_stop["t"]
            and abs(s.vx_m_s) < 0.02 and abs(s.vy_m_s) < 0.02 and abs(s.vz_m_s) < 0.02]
    assert zero, "no stop setpoint on the wire before the main decision"
    # that zero setpoint was a change: the vehicle was flying forward until the spotted stop
    go = [e for e in events if e["kind"] == "command" and e.get("action") == "go_forward"]
    assert go and go[0]["sent_t"] < stop_cmd["sent_t"], [e["msg"] for e in events]
    # from go_forward's own setpoint on the wire (file order is send order) to the spotted stop, every
    # setpoint moves: no stale hold, read before the command, went out after it
    first_go = next(i for i, s in enumerate(flight.setpoints)
                    if s.t_s >= go[0]["sent_t"] - 1.0 and abs(s.vx_m_s) + abs(s.vy_m_s) > 0.1)
    moving = [s for s in flight.setpoints[first_go:] if s.t_s < stop_cmd["sent_t"] - 0.01]
    assert moving and all(abs(s.vx_m_s) + abs(s.vy_m_s) > 0.1 for s in moving), moving[:3]
    assert speed_at(flight, flight.track.t_s[-1]) < 0.15
