"""After a rejected utterance the voice side resumes the paused motion, unless what was heard was nearest a stop.

Real Whisper decisions on real held-out recordings in real kitchen noise (12 dB): a real "stop" that the
decision rejects but hears nearest a stop leaves the vehicle stopped (STAY); a real sentence that it rejects
resumes the motion (RESUME). The bridge is a real one whose loop does not run: its queue shows what was asked.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from e2e_support import require_parts
from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link.vehicle_link import VehicleLink
from gcs_voice.session.bridge import RESUME, STAY, Bridge
from gcs_voice.session.events import EventBus
from gcs_voice.session.listen import VoicePipeline


def test_a_rejected_stop_stays_stopped_and_rejected_speech_resumes(whisper_model_dir: Path,
                                                                    real_speech_dir: Path) -> None:
    require_parts("faster_whisper")
    from gcs_voice.session.run import load_voice
    from tools.speech.real_speech import condition_audio, load_recordings

    recognizer, matcher, dictionaries, lang = load_voice("en", "whisper", str(whisper_model_dir), None)
    bridge = Bridge(VehicleLink("udpin:127.0.0.1:0"), ActionMapper(), EventBus(), 1.5)  # never opened
    pipeline = VoicePipeline(recognizer, matcher, dictionaries, lang, EventBus(), realtime=False)
    recordings = load_recordings(real_speech_dir, split="test")
    asked: dict[tuple[str, str], str] = {}
    for rec in [r for r in recordings if r.action == "stop"] + [r for r in recordings if r.kind == "sentence"]:
        audio = condition_audio(rec, "kitchen12")
        pcm = (np.clip(audio, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
        decision = pipeline.hear(pcm, rec.path.name)
        if decision.accepted:
            continue
        pipeline.settle_pause(bridge, decision)
        request = bridge._inbox.get_nowait()
        asked.setdefault(("stop" if rec.action == "stop" else rec.kind, request.action), rec.path.name)
        if request.action == STAY:  # the log says what said stop: Whisper's words
            assert request.why.startswith("Whisper"), request.why  # wrote, or ranked first
        if ("stop", STAY) in asked and ("sentence", RESUME) in asked:
            break
    assert ("stop", STAY) in asked and ("sentence", RESUME) in asked, asked


def test_what_keeps_a_held_motion_stopped_after_speech_not_understood() -> None:
    """The rule of settle_pause, as bench_ear tune chose its limits for it (thresholds.toml [ear.whisper-score])."""
    from gcs_voice.session.listen import stays_stopped

    spotted, nearest = 0.3, 0.02
    assert stays_stopped(True, False, 0.0, False, spotted, nearest)          # Whisper wrote "stop"
    assert stays_stopped(False, True, 0.05, False, spotted, nearest)         # ranked a stop first, ear not against
    assert not stays_stopped(False, True, 0.01, False, spotted, nearest)     # ... the ear all but rules it out
    assert stays_stopped(False, False, 0.4, True, spotted, nearest)          # the spotter held it, the ear agrees
    assert not stays_stopped(False, False, 0.2, True, spotted, nearest)      # ... the ear gives it too little
    assert not stays_stopped(False, False, 0.9, False, spotted, nearest)     # nothing heard a stop: the ear alone
    assert stays_stopped(False, False, None, True, None, None)               # no ear: a spotted stop stands
