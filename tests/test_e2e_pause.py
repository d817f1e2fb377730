"""The motion pauses while an utterance is decided: a stop counts from the end of the speech.

Flies the bundled simulator with ``python -m gcs_voice --say`` (PocketSphinx, the stop spotter off, so the
stop below waits for the main recogniser like a stop the spotter missed): "go forward", then real speech
that is not a command, then "hold" (a stop). The vehicle must hold from the end of each utterance (a zero-velocity
setpoint on the wire before the recogniser has said what it heard), go on forward after the speech that
was not understood, and stay stopped after the stop.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from e2e_support import SPEEDUP, demo_wav, require_parts, run_fly, speech
from gcs_voice.session.sim_process import BundledSim

pytestmark = [pytest.mark.slow]


def _stamp(t: float) -> float:
    """A UNIX time as a .tlog stamps it (whole microseconds), less half a microsecond: the bound that finds the
    record ``t`` stamped. pymavlink reads a stamp back as ``usec * 1e-6``, which can be one float step (0.24 us
    at today's epoch) below ``usec / 1e6``."""
    return (math.floor(t * 1e6) - 0.5) / 1e6


def _still(s) -> bool:
    return abs(s.vx_m_s) < 0.02 and abs(s.vy_m_s) < 0.02 and abs(s.vz_m_s) < 0.02


def _rejected_sentence(real_speech_dir: Path) -> Path:
    """A real spoken sentence of the held-out speakers that the session's pipeline does not act on, and that
    was not heard near a stop (after which the vehicle would stay stopped)."""
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.domain.text import normalize_text
    from gcs_voice.session.run import load_voice
    from tools.speech.real_speech import load_recordings

    recognizer, matcher, dictionaries, lang = load_voice("en", "sphinx", None, None)
    stop_phrases = {key for d in dictionaries for key, p in d.by_key.items() if p.action == "stop"}
    for rec in load_recordings(real_speech_dir, split="test"):
        if rec.kind != "sentence":
            continue
        stream = recognizer.start_stream(lang)
        stream.accept(read_wav(rec.path))
        recognition = stream.finish()
        heard = {normalize_text(recognition.text), normalize_text(recognition.best.text if recognition.best else "")}
        if not matcher.decide(recognition, dictionaries).accepted and not heard & stop_phrases:
            return rec.path
    pytest.fail("no held-out sentence is rejected by PocketSphinx")


def test_a_record_is_found_by_the_time_that_stamped_it(tmp_path: Path) -> None:
    """A fast decision leaves only the pause's own setpoint before "heard": ``_stamp`` must find that record."""
    import random

    from gcs_voice.link.tlog import TlogWriter
    from pymavlink import mavutil
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    mav = mavlink.MAVLink(None, srcSystem=255)
    rng = random.Random(7)
    times = [1.7e9 + rng.random() * 1e8 for _ in range(300)]
    writer = TlogWriter(tmp_path / "t.tlog")
    for t in times:
        writer.write(mav.heartbeat_encode(6, 8, 0, 0, 0).pack(mav), t)
    writer.close()
    log = mavutil.mavlink_connection(str(tmp_path / "t.tlog"))
    read = [log.recv_match()._timestamp for _ in times]
    # found from its own time on, and not from the next microsecond on
    assert all(_stamp(t) <= r < _stamp(t) + 1e-6 for t, r in zip(times, read))


def test_speech_pauses_the_motion_until_it_is_decided(tmp_path: Path, real_speech_dir: Path) -> None:
    require_parts("sim_bridge.cli", "pocketsphinx")
    sentence = _rejected_sentence(real_speech_dir)
    stop = demo_wav("hold")  # the demo's stop word
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, [demo_wav("go_forward"), sentence, stop], tmp_path, gap_s=3.0, hold_s=2.0,
                         extra=["--engine", "sphinx", "--no-stop-spotter"], timeout_s=300.0)
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    events = result.events
    msgs = [e["msg"] for e in events]
    paused = [e for e in events if e["kind"] == "paused"]
    # "go forward" was said to a hovering vehicle: nothing to pause; the sentence and the stop each pause it
    assert [e["state"] for e in paused] == ["paused", "resumed", "paused"], msgs
    assert all(e["action"] == "go_forward" for e in paused), msgs
    flight = result.flight()
    for source, pause in ((sentence.name, paused[0]), (stop.name, paused[2])):
        heard = next(e for e in events if e["kind"] == "heard" and e["source"] == source)
        # on the wire: the hold went out before the recogniser had said what it heard
        assert pause["sent_t"] < heard["t"], msgs
        # (a tlog record is stamped when its setpoint was decided: the pause's own, and every one after it)
        held = [s for s in flight.setpoints if _stamp(pause["decided_t"]) <= s.t_s < heard["t"]]
        assert held and all(_still(s) for s in held), held[:3]
    # the sentence was not understood: forward again, from the resume until the stop's pause
    resumed = paused[1]
    again = [s for s in flight.setpoints if _stamp(resumed["decided_t"]) <= s.t_s < _stamp(paused[2]["decided_t"])]
    assert again and all(s.vx_m_s ** 2 + s.vy_m_s ** 2 > 0.1 for s in again), again[:3]
    # the stop was understood: it replaced the pause, and nothing moves after it
    stop_cmd = next(e for e in events if e["kind"] == "command" and e.get("action") == "stop" and e["origin"] == "voice")
    assert stop_cmd["sent_t"] > paused[2]["sent_t"]
    after = [s for s in flight.setpoints if s.t_s >= _stamp(paused[2]["decided_t"])]
    assert after and all(_still(s) for s in after), [s for s in after if not _still(s)][:3]


def test_a_recording_heard_as_the_microphone_pauses_at_the_end_of_the_speech(tmp_path: Path,
                                                                              whisper_model_dir: Path) -> None:
    """``--listen-wav``: the microphone's path (real time, the segmenter) pauses at the segmenter's first sign
    that the speech ended, before the utterance has even closed, and the decided stop keeps the vehicle still."""
    require_parts("sim_bridge.cli", "faster_whisper")
    import numpy as np

    from gcs_voice.audio.sources import read_wav
    from tools.listen.streams import write_wav

    silence = lambda s: np.zeros(int(s * 16_000), np.float32)  # noqa: E731
    clip = lambda path: np.frombuffer(read_wav(path), "<i2").astype(np.float32) / 32768  # noqa: E731
    stream = tmp_path / "room.wav"
    stop = speech(tmp_path, "stop")  # espeak-ng; Whisper hears it as "Stop!" once the segmenter has cut it
    write_wav(stream, np.concatenate([silence(1.0), clip(demo_wav("go_forward")), silence(2.5), clip(stop),
                                      silence(1.5)]))
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        result = run_fly(sim.connection, [], tmp_path, hold_s=1.0, listen=stream, timeout_s=300.0,
                         extra=["--engine", "whisper", "--model", str(whisper_model_dir), "--no-stop-spotter"])
    assert result.returncode == 0, result.stderr + result.stdout[-2000:]
    events = result.events
    msgs = [e["msg"] for e in events]
    assert [e["phase"] for e in events if e["kind"] == "session"][:2] == ["start", "listening"], msgs
    assert [e["action"] for e in result.commands()] == ["go_forward", "stop"], msgs
    pause = next(e for e in events if e["kind"] == "paused")
    assert pause["state"] == "paused" and pause["action"] == "go_forward", msgs
    thinking = [e for e in events if e["kind"] == "thinking"]
    # the pause went out before the decision was taken, and it stayed: the decided stop replaced it
    assert pause["sent_t"] < thinking[-1]["t"], msgs
    flight = result.flight()
    after = [s for s in flight.setpoints if s.t_s >= _stamp(pause["decided_t"])]
    assert after and all(_still(s) for s in after), [s for s in after if not _still(s)][:3]
    assert not [e for e in events if e["kind"] == "paused" and e["state"] == "resumed"], msgs
