"""What the pilot sees and what is kept: live view panels, headless lines, the session log."""

from __future__ import annotations

import io
import json
from pathlib import Path

from gcs_voice.session.events import EventBus
from gcs_voice.session.headless import HeadlessPrinter
from gcs_voice.session.session_log import SessionLog, read_session_log, session_paths
from gcs_voice.session.view import ViewState, render


def _bus_with_a_session(tmp_path: Path) -> tuple[EventBus, io.StringIO, io.StringIO, Path]:
    bus = EventBus()
    human, machine = io.StringIO(), io.StringIO()
    log_path = tmp_path / "s.jsonl"
    log = SessionLog(log_path)
    for subscriber in (log, HeadlessPrinter(stream=human), HeadlessPrinter(as_json=True, stream=machine)):
        bus.subscribe(subscriber)
    bus.emit("link", "link connected: ArduPilot, mode GUIDED", state="connected", autopilot="ArduPilot")
    bus.emit("heard", "heard 'banana split' (sphinx, en)", text="banana split", engine="sphinx", lang="en")
    bus.emit("rejected", "no action for 'banana split': too far", text="banana split", reason="too far from any phrase")
    bus.emit("heard", "heard 'go forward' (sphinx, en)", text="go forward", engine="sphinx", lang="en")
    bus.emit("command", "'go forward' -> go_forward (score 0.97)", action="go_forward", phrase="go forward",
             score=0.97, origin="voice")
    bus.emit("refused", "go_forward limited: fence 20 m from home", action="go_forward",
             reason="fence 20 m from home")
    bus.emit("link", "link LOST", state="lost")
    log.close()
    return bus, human, machine, log_path


def test_headless_json_lines_are_the_session_log(tmp_path: Path) -> None:
    bus, human, machine, log_path = _bus_with_a_session(tmp_path)
    printed = [json.loads(line) for line in machine.getvalue().splitlines()]
    assert printed == read_session_log(log_path)
    assert [e["kind"] for e in printed] == ["link", "heard", "rejected", "heard", "command", "refused", "link"]
    assert printed[2]["reason"] == "too far from any phrase" and printed[4]["score"] == 0.97
    lines = human.getvalue().splitlines()
    assert len(lines) == 7 and "rejected" in lines[2] and lines[4].rstrip().endswith("go_forward (score 0.97)")


def test_view_shows_state_heard_did_rejected_and_warnings(tmp_path: Path) -> None:
    from rich.console import Console

    bus, *_ = _bus_with_a_session(tmp_path)
    state = ViewState()
    for event in bus.history:
        state(event)
    console = Console(width=110, record=True, file=io.StringIO())
    console.print(render(state, {"link": "lost", "autopilot": "ArduPilot", "mode": "GUIDED", "armed": True,
                                 "alt_m": 1.52, "heading_deg": 90.0, "speed_m_s": 0.31, "action": "stop"}))
    text = console.export_text()
    for expected in ("LOST", "ArduPilot", "GUIDED", "ARMED", "1.52 m", "90 deg", "0.31 m/s",
                     '"go forward"', "go forward -> go_forward  score 0.97",
                     '"banana split" - too far from any phrase', "fence 20 m from home", "link LOST"):
        assert expected in text, expected


def test_session_paths_never_overwrite(tmp_path: Path) -> None:
    first = session_paths(tmp_path)
    first[0].write_bytes(b"")
    second = session_paths(tmp_path)
    assert second[0] != first[0] and second[0].suffix == ".tlog" and second[1].suffix == ".jsonl"
    assert session_paths(tmp_path, "named") == (tmp_path / "named.tlog", tmp_path / "named.jsonl")


def test_view_says_what_the_vehicle_waits_for() -> None:
    """Disarmed: the vehicle panel shows the readiness line (link.readiness), from a real VehicleState."""
    from rich.console import Console

    from gcs_voice.link.autopilots import ARDUPILOT
    from gcs_voice.link.state import VehicleState
    from gcs_voice.session.bridge import status_of

    booting = VehicleState(system_id=1, profile=ARDUPILOT, heartbeats=3, armed=False, mode="GUIDED",
                           system_status=3, sensors_present=0x10000000, sensors_enabled=0x10000000,
                           sensors_health=0, ekf_flags=167, prearm_text="PreArm: Need Position Estimate",
                           last_heard_s=0.0, link_ok=True)
    status = status_of(booting, "take_off")
    assert status["ready"] == ("waiting for: pre-arm checks, position (EKF) "
                               "(vehicle: PreArm: Need Position Estimate)")
    console = Console(width=140, record=True, file=io.StringIO())
    console.print(render(ViewState(), status))
    assert "waiting for: pre-arm checks, position (EKF)" in console.export_text()
    armed = status_of(VehicleState(system_id=1, profile=ARDUPILOT, heartbeats=3, armed=True), "stop")
    assert armed["ready"] is None


def _shown(state: ViewState) -> str:
    """The live view as text, as a 110-column terminal would show it."""
    from rich.console import Console

    console = Console(width=110, record=True, file=io.StringIO())
    console.print(render(state, {"link": "ok"}))
    return console.export_text()


def test_view_says_thinking_while_a_decision_is_pending() -> None:
    bus, state = EventBus(), ViewState()
    bus.subscribe(state)

    bus.emit("thinking", "thinking… (1.0 s from stop.wav)", source="stop.wav", utterance_end_t=1.0)
    assert "thinking…" in _shown(state)
    bus.emit("spotted", "stop word 'stop' heard: stopping now", word="stop")
    bus.emit("heard", "heard 'stop' (whisper, en)", text="stop", engine="whisper", lang="en")
    text = _shown(state)
    assert "thinking…" not in text and "stop word 'stop' heard" in text


def test_the_view_shows_the_words_whisper_wrote_not_the_phrase_it_scored() -> None:
    """Whisper scoring ranks dictionary phrases; what it heard is its own transcript ("Um" for a real "up",
    scored best as "ahead"). The view and the heard line show the transcript; other engines their text."""
    from gcs_voice.asr.base import Hypothesis, Recognition

    bus, state = EventBus(), ViewState()
    bus.subscribe(state)

    scored = Recognition((Hypothesis("ahead", 0.01, -4.2),), "whisper-score", "en", 1.0, transcript="Um")
    assert scored.heard == "Um" and scored.text == "ahead"
    bus.emit("heard", "heard 'Um'", text=scored.text, transcript=scored.transcript, engine="whisper-score", lang="en")
    assert '"Um"' in _shown(state) and "ahead" not in _shown(state)
    plain = Recognition((Hypothesis("go up", 0.9),), "sphinx", "en", 1.0)
    assert plain.heard == "go up"
    bus.emit("heard", "heard 'go up'", text=plain.text, transcript=plain.transcript, engine="sphinx", lang="en")
    assert '"go up"' in _shown(state)


def test_a_decision_later_than_late_s_is_said(tmp_path: Path, monkeypatch) -> None:
    """Real PocketSphinx on espeak-ng speech; the late limit set to 0 s and to 60 s."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session import listen
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from tests.asr_speech import pcm_of

    en = load_language("en")
    bus = EventBus()
    pipeline = listen.VoicePipeline(load_recognizer("sphinx", [en]), get_matcher(DEFAULT_MATCHER), [en], "en", bus,
                                    realtime=False)
    pcm = pcm_of("go up", tmp_path)
    monkeypatch.setattr(listen, "LATE_S", 60.0)
    pipeline.hear(pcm, "up.wav", recorded=True)
    kinds = [e.kind for e in bus.history]
    assert kinds.index("thinking") < kinds.index("heard") and "late" not in kinds
    monkeypatch.setattr(listen, "LATE_S", 0.0)
    pipeline.hear(pcm, "up.wav", recorded=True)
    late = [e for e in bus.history if e.kind == "late"]
    assert len(late) == 1 and late[0].data["late_s"] >= 0.0 and "late: decided" in late[0].msg


def test_a_speculated_decision_is_the_decision_and_only_for_its_own_audio(tmp_path: Path, whisper_model_dir: Path) -> None:
    """Whisper (the default engine): an utterance recognised while its closing silence ran out is decided
    exactly as it would be afresh; a guess for other audio is not used."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session import listen
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from tests.asr_speech import pcm_of

    en = load_language("en")
    bus = EventBus()
    pipeline = listen.VoicePipeline(load_recognizer("whisper", [en], model=str(whisper_model_dir)),
                                    get_matcher(DEFAULT_MATCHER), [en], "en", bus, realtime=False)
    up, stop = pcm_of("go up", tmp_path), pcm_of("stop", tmp_path)

    def heard() -> dict:
        return [e for e in bus.history if e.kind == "heard"][-1].data

    fresh = pipeline.hear(up, "microphone", utterance_end_t=1.0)
    assert heard()["speculated"] is False
    pipeline.speculate(up)
    early = pipeline.hear(up, "microphone", utterance_end_t=2.0)
    assert heard()["speculated"] is True and early == fresh and early.action == "up"
    pipeline.speculate(up)  # the utterance went on: what ends is other audio
    other = pipeline.hear(stop, "microphone", utterance_end_t=3.0)
    assert heard()["speculated"] is False and other.action == "stop"
    pipeline.hear(up, "microphone", utterance_end_t=4.0)  # a guess is used once at most
    assert heard()["speculated"] is False


def test_a_stale_guess_is_given_up_between_the_engine_stages(tmp_path: Path, whisper_model_dir: Path) -> None:
    """A speculation whose utterance went on stops after the encoder (its check is asked, it raises nothing
    out of ``speculate``, no guess is kept), and the real utterance is then decided afresh, as usual."""
    import queue

    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session import listen
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from tests.asr_speech import pcm_of

    en = load_language("en")
    bus = EventBus()
    pipeline = listen.VoicePipeline(load_recognizer("whisper", [en], model=str(whisper_model_dir)),
                                    get_matcher(DEFAULT_MATCHER), [en], "en", bus, realtime=False)
    up = pcm_of("go up", tmp_path)
    asked: list[bool] = []

    def stale() -> bool:
        asked.append(True)
        return True

    pipeline.speculate(up, stale=stale)
    assert asked == [True] and pipeline.abandoned == 1  # asked once: after the encoder, and it stopped there
    decision = pipeline.hear(up, "microphone", utterance_end_t=1.0)
    heard = [e for e in bus.history if e.kind == "heard"][-1].data
    assert heard["speculated"] is False and decision.action == "up"

    asked.clear()
    pipeline.speculate(up, stale=lambda: asked.append(False) or False)  # still the utterance: runs through
    assert len(asked) == 2 and pipeline.abandoned == 1  # after the encoder and after the free pass
    assert pipeline.hear(up, "microphone", utterance_end_t=2.0) == decision
    assert [e for e in bus.history if e.kind == "heard"][-1].data["speculated"] is True

    # what makes a guess stale in run_microphone: anything queued after it but its own utterance
    heard_q: queue.Queue = queue.Queue()
    assert not listen._superseded(heard_q, up)
    heard_q.put((up, 2.0))
    assert not listen._superseded(heard_q, up)
    heard_q.put((up + b"\0\0", 3.0))
    assert listen._superseded(heard_q, up)


def test_a_voice_barely_above_the_room_that_was_not_understood_is_told_so(tmp_path: Path) -> None:
    """Issue 30: in a loud room the pilot can help the recogniser (speak up, or nearer the microphone), so a
    rejection says how far the voice stood above the room when that was less than ``loud_room_snr_db``; aloud
    ("too noisy") at most every LOUD_ROOM_REPEAT_S, the low tone alone in between. Real PocketSphinx on espeak-ng
    speech; the SNR as the segmenter would give it."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session import listen
    from gcs_voice.session.feedback import cue_for, load_phrases
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from tests.asr_speech import pcm_of

    en = load_language("en")
    bus = EventBus()
    pipeline = listen.VoicePipeline(load_recognizer("sphinx", [en]), get_matcher(DEFAULT_MATCHER), [en], "en", bus,
                                    realtime=False, loud_room_snr_db=10.0)
    other, command = pcm_of("the garden is green today", tmp_path), pcm_of("go up", tmp_path)
    talk = pcm_of("go up and then the garden is green today", tmp_path)
    phrases = load_phrases("en")

    def rejected() -> list:
        return [e for e in bus.history if e.kind == "rejected"]

    # talk that went on past a command's words is not asked to speak up, and does not use up the spoken hint
    assert pipeline.hear(talk, "microphone", utterance_end_t=0.5, snr_db=5.0).action is None
    assert rejected()[-1].data["loud_room"] and not rejected()[-1].data["hint"], rejected()[-1].msg
    assert not rejected()[-1].data["say_loud_room"] and "loud" not in rejected()[-1].msg
    assert pipeline.hear(other, "microphone", utterance_end_t=1.0, snr_db=6.0).action is None
    first = rejected()[-1]
    assert first.data["loud_room"] and first.data["say_loud_room"] and "the room is loud" in first.msg, first.msg
    assert "6 dB above it" in first.msg and cue_for(first, phrases).words == "too noisy"
    pipeline.hear(other, "microphone", utterance_end_t=2.0, snr_db=4.0)
    again = rejected()[-1]  # said in the text each time, aloud only every LOUD_ROOM_REPEAT_S
    assert again.data["loud_room"] and not again.data["say_loud_room"] and cue_for(again, phrases).words == ""
    pipeline.hear(other, "microphone", utterance_end_t=3.0, snr_db=25.0)
    assert not rejected()[-1].data["loud_room"] and "loud" not in rejected()[-1].msg
    pipeline.hear(other, "microphone", utterance_end_t=4.0)  # no room heard (a recording, --say): nothing said of it
    assert not rejected()[-1].data["loud_room"]
    assert pipeline.hear(command, "microphone", utterance_end_t=5.0, snr_db=6.0).action == "up"  # understood: no hint
    assert len(rejected()) == 5
    heard = [e for e in bus.history if e.kind == "heard"]
    assert [e.data["snr_db"] for e in heard] == [5.0, 6.0, 4.0, 25.0, None, 6.0]
    # and the pilot's screen says it beside the reason
    from rich.console import Console

    state = ViewState()
    for event in bus.history:
        state(event)
    console = Console(width=200, record=True, file=io.StringIO())
    console.print(render(state, {"link": "ok"}))
    assert "the room is loud: the voice was 4 dB above it; speak up, or nearer the microphone" in console.export_text()


def test_a_loud_room_is_told_for_what_may_have_been_a_command_not_for_other_words(
        real_speech_dir: Path, whisper_model_dir: Path) -> None:
    """The hint is for a pilot whose command was lost in the room, not for every word said near the microphone: with
    Whisper scoring, only when a command phrase came within ``loud_room_min_margin`` of what Whisper heard. Real dev
    recordings of ../shared/speech: a "left" that Whisper writes "Weft" (a command phrase near: told), and a "tree"
    (no command near: not told), both as if heard 5 dB above the room."""
    import pytest

    pytest.importorskip("faster_whisper")
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session import listen
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    en = load_language("en")
    bus = EventBus()
    recognizer = load_recognizer("whisper", [en], model=str(whisper_model_dir), mode="score")
    # The hint's rule reads Whisper's margin alone. The domain ear hears this "left" rightly (it acts on it), so the
    # rule is checked without the ear, on a command Whisper alone loses in the room.
    recognizer.ear = None
    pipeline = listen.VoicePipeline(recognizer, get_matcher(DEFAULT_MATCHER), [en], "en", bus, realtime=False)
    assert pipeline.loud_room_min_margin > -5.0, "the test's words sit either side of the shipped margin"
    for t, (folder, name) in enumerate((("go_left", "sc_left_2313e093_nohash_0.wav"),
                                        ("_none", "sc_tree_23059a35_nohash_3.wav"))):
        assert pipeline.hear(read_wav(real_speech_dir / "en" / folder / name), "microphone",
                             utterance_end_t=float(t), snr_db=5.0).action is None
    left, tree = [e for e in bus.history if e.kind == "rejected"]
    heard = {e.data["transcript"]: e for e in bus.history if e.kind == "heard"}
    assert left.data["loud_room"] and left.data["hint"] and left.data["say_loud_room"], (left.msg, list(heard))
    assert tree.data["loud_room"] and not tree.data["hint"] and not tree.data["say_loud_room"], (tree.msg, list(heard))
