"""How tools.listen.bench_room_stops counts a session log: what it calls a motion cancelled by a stop for nothing,
and a real stop held (the live test, test_room_stops.py, relies on these counts)."""

from __future__ import annotations

import json
from pathlib import Path

from tools.listen.bench_room_stops import count
from tools.listen.streams import Placed
from tools.speech.real_speech import Recording

T0 = 1000.0


def _placed() -> list[Placed]:
    def clip(action: str | None, word: str) -> Recording:
        return Recording(Path(f"{word}.wav"), action, word, "s", "test", "command" if action else "word", "en")
    # a motion at 0-1 s, other talk at 3-4 s, a real stop at 6-7 s, other talk at 9-10 s
    return [Placed(clip("go_forward", "forward"), 0.0, 1.2, 0.1, 1.0), Placed(clip(None, "house"), 3.0, 4.2, 3.1, 4.0),
            Placed(clip("stop", "stop"), 6.0, 7.2, 6.1, 7.0), Placed(clip(None, "bird"), 9.0, 10.2, 9.1, 10.0)]


def _log(tmp_path: Path, events: list[dict]) -> Path:
    path = tmp_path / "s.jsonl"
    start = {"kind": "session", "phase": "listening", "audio_t0": T0, "t": T0}
    path.write_text("\n".join(json.dumps(e) for e in [start, *events]) + "\n", encoding="utf-8")
    return path


def _command(action: str, origin: str, end_s: float, sent_s: float) -> dict:
    return {"kind": "command", "action": action, "origin": origin, "utterance_end_t": T0 + end_s, "sent_t": T0 + sent_s}


def _paused(state: str, action: str, end_s: float, sent_s: float) -> dict:
    return {"kind": "paused", "state": state, "action": action, "utterance_end_t": T0 + end_s, "sent_t": T0 + sent_s}


def test_a_hard_stop_for_nothing_while_a_motion_is_paused_is_a_motion_cancelled(tmp_path: Path) -> None:
    events = [_command("go_forward", "voice", 1.0, 1.2),
              _paused("paused", "go_forward", 4.0, 4.05),                          # the other talk is being decided
              {"kind": "spotted", "spotted_t": T0 + 4.1},                           # ... and the spotter stops
              _command("stop", "spotter", 4.1, 4.1)]
    out = count(_log(tmp_path, events), _placed(), 0.2)
    assert (out.spotted_nothing, out.changed, out.cancelled) == (1, 1, 1)


def test_a_hold_for_nothing_that_resumes_cancels_nothing(tmp_path: Path) -> None:
    events = [_command("go_forward", "voice", 1.0, 1.2),
              {"kind": "spotted", "spotted_t": T0 + 3.5, "provisional": True},
              _paused("paused", "go_forward", 3.5, 3.5), _paused("resumed", "go_forward", 4.0, 4.3)]
    out = count(_log(tmp_path, events), _placed(), 0.2)
    assert (out.spotted_nothing, out.changed, out.cancelled, out.resumed) == (1, 0, 0, 1)


def test_a_real_stop_held_and_then_let_go_is_no_stop_held(tmp_path: Path) -> None:
    events = [_command("go_forward", "voice", 1.0, 1.2),
              {"kind": "spotted", "spotted_t": T0 + 6.8, "provisional": True},
              _paused("paused", "go_forward", 6.8, 6.8), _paused("resumed", "go_forward", 7.0, 7.3)]
    out = count(_log(tmp_path, events), _placed(), 0.2)
    assert (out.stops, out.stops_held) == (1, 0)
    events[-1] = _paused("stayed", "go_forward", 7.0, 7.3)
    out = count(_log(tmp_path, events), _placed(), 0.2)
    assert (out.stops, out.stops_held, out.cancelled) == (1, 1, 0)
