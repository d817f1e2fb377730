"""The bridge never hears itself, end to end: ``gcs-voice --listen-wav`` flying the bundled simulator with
``--feedback speech --feedback-echo``, where every cue it plays is mixed back into the recording it listens
to (as loud as the pilot's voice, 60 ms late: a speaker beside the microphone), decides exactly what the
same recording decides with ``--feedback off``: the same actions, no extra rejection.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from e2e_support import SPEEDUP, demo_wav, require_parts, run_fly, speech
from gcs_voice.session.sim_process import BundledSim

pytestmark = pytest.mark.slow
#: the echo's delay: the sound card's output buffer and half a metre of air
ECHO_DELAY_MS = 60


def _voiced_dbfs(x: np.ndarray) -> float:
    from tools.listen.streams import voiced_level

    return float(20 * np.log10(voiced_level(x)[0] + 1e-9))


def _decisions(result) -> tuple[list[tuple[str, str]], int]:
    commands = [(e["origin"], e["action"]) for e in result.events
                if e["kind"] == "command" and e.get("origin") in ("voice", "spotter")]
    return commands, len(result.kinds("rejected"))


def test_the_bridge_own_speech_mixed_into_the_microphone_changes_no_decision(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli")
    from gcs_voice.audio.sounds import Speech, tone
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.session.feedback import load_sound_settings
    from tools.listen.streams import write_wav

    silence = lambda s: np.zeros(int(s * 16_000), np.float32)  # noqa: E731
    clip = lambda path: np.frombuffer(read_wav(path), "<i2").astype(np.float32) / 32768  # noqa: E731
    chat = speech(tmp_path, "what a lovely day it is")  # not a command: rejected, and its tone played
    # 4 s first: the take-off's own cues are over before the pilot speaks (the pilot hears them out)
    parts = [silence(4.0), clip(demo_wav("go_forward")), silence(3.0), clip(demo_wav("move_left")), silence(3.0),
             clip(chat), silence(3.0), clip(demo_wav("hold")), silence(2.0)]
    stream = tmp_path / "room.wav"
    write_wav(stream, np.concatenate(parts))
    # the bridge's voice at the microphone as loud as the pilot's (voiced parts)
    s = load_sound_settings()
    bridge = np.frombuffer(tone(s.tones["doing"], s.amplitude, s.fade_s) + Speech("en-us", s.speed_wpm).say(
        "going left"), "<i2").astype(np.float32) / 32768
    gain_db = _voiced_dbfs(clip(demo_wav("move_left"))) - _voiced_dbfs(bridge)
    results = {}
    for mode, extra in (("off", ["--feedback", "off"]),
                        ("echo", ["--feedback", "speech", f"--feedback-echo={gain_db:.1f}:{ECHO_DELAY_MS}"])):
        out = tmp_path / mode
        out.mkdir()
        with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=out / "sim.log") as sim:
            results[mode] = run_fly(sim.connection, [], out, hold_s=1.0, listen=stream, timeout_s=300.0,
                                    extra=extra)
        assert results[mode].returncode == 0, results[mode].stderr + results[mode].stdout[-2000:]
    off, echo = results["off"], results["echo"]
    msgs = [e["msg"] for e in echo.events]
    # the bridge did speak into the microphone while it listened: decisions and rejections were said
    t0 = next(e["audio_t0"] for e in echo.events if e.get("phase") == "listening")
    said = [e for e in echo.kinds("feedback") if e["played_t"] > t0]
    assert {e["tone"] for e in said} >= {"doing", "not_understood"}, msgs
    assert all(e["player"] == "echo room" for e in said), msgs
    # and decided exactly what it decided without hearing itself
    assert _decisions(off)[0] and ("voice", "go_left") in _decisions(off)[0], [e["msg"] for e in off.events]
    assert _decisions(echo) == _decisions(off), (msgs, [e["msg"] for e in off.events])
