"""What happened in a session, as flat records: the one currency of the view, the console and the log.

Every event is a dict-like record with a UNIX time ``t``, a ``kind`` and a human sentence ``msg``,
plus kind-specific fields. The headless console prints them (``--json``: exactly the session-log
line), the live view folds them into its panels, the session log appends them to a JSON-lines file.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Event", "EventBus", "KINDS", "heard_words"]

#: Event kinds, with what they carry beyond t/kind/msg.
KINDS: dict[str, str] = {
    "session": "start/end of a session: phase, argv, versions, files",
    "link": "state connected|lost|restored, autopilot, vehicle ids",
    "spotted": "the stop spotter heard a stop word (a stop follows at once): word, utterance_end_t, spotted_t, "
               "over_voice; repeat (no stop follows: the stop just sent heard again over the bridge's voice); "
               "provisional (a moving vehicle is held instead, and the utterance's decision settles it)",
    "settled": "a provisional hold spotted over the bridge's voice, settled by the domain ear (no decision follows "
               "such audio): stay, ear_stop",
    "own_echo": "over the bridge's voice, the stop spotter heard a stop word in nothing but what the echo canceller "
                "left of the bridge's own sound (no stop): words",
    "paused": "the motion held while an utterance is decided (state paused), then resumed after speech that was "
              "not understood (resumed) or left stopped (stayed): action, utterance_end_t, decided_t (the setpoint's "
              "time stamp in the tlog), sent_t",
    "thinking": "an utterance ended and its decision is pending: source, utterance_end_t",
    "late": "a decision came more than LATE_S after its utterance ended: late_s, action, source",
    "heard": "what the recogniser heard: text (the best hypothesis), transcript (the engine's own words when its "
             "hypotheses are scored phrases, else empty), alternatives, engine, lang, audio_s, source, recognize_ms",
    "rejected": "no action: text, phrase (nearest), score, reason, matcher",
    "command": "an action sent to the vehicle: action, phrase, score, amount (3 m, 45°, to 5 m, or null), origin (voice|key|script), setpoint",
    "refused": "an action not sent, or cut short, by a safety rule: action, reason (link lost, fence, ...)",
    "flight": "arm / take-off / land / disarm / mode: what, ok, detail",
    "ready": "what the vehicle is waiting for before it can be armed (waiting_for), or the arming step taken",
    "vehicle": "STATUSTEXT from the vehicle: severity, text",
    "collision": "the vehicle said it hit something (SIM Hit ...), not a landing: obstacle, speed_m_s, text",
    "takeover": "the vehicle left the velocity mode while voice flew it (another station, the RC switch or a "
                "failsafe); the voice motion and the setpoint stream stopped: mode, previous, by (station when the "
                "ACK of another station's mode change was heard, else unknown), station ([system, component] or "
                "null); voice motions are refused until the vehicle is back in the velocity mode",
    "feedback": "a cue the pilot heard (--feedback): tone (doing|not_understood|refused|warning), words, played_t "
                "(UNIX time it started), seconds, player",
    "warning": "something the pilot should know that is not a refusal",
    "error": "the voice side or the link failed; the vehicle was stopped",
}


def heard_words(heard: Any) -> str:
    """The words of a ``heard`` event for people to read: the engine's own transcript (Whisper scoring wrote
    "Um" while the phrase it scored best was "ahead"), else its best hypothesis."""
    return heard.get("transcript") or heard.get("text", "")


@dataclass
class Event:
    kind: str
    msg: str
    t: float = field(default_factory=time.time)
    data: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Flat record: t, kind, msg, then the kind's fields (which never override the first three)."""
        record: dict[str, Any] = {"t": round(self.t, 4), "kind": self.kind, "msg": self.msg}
        for key, value in self.data.items():
            record.setdefault(key, value)
        return record


class EventBus:
    """Fan events out to subscribers (view, console, log); thread-safe, a failing subscriber is dropped."""

    def __init__(self) -> None:
        self._subscribers: list[Callable[[Event], None]] = []
        self._lock = threading.Lock()
        self.history: list[Event] = []

    def subscribe(self, callback: Callable[[Event], None]) -> None:
        with self._lock:
            self._subscribers.append(callback)

    def emit(self, kind: str, msg: str, **data: Any) -> Event:
        event = Event(kind, msg, time.time(), data)
        with self._lock:
            self.history.append(event)
            subscribers = list(self._subscribers)
        for callback in subscribers:
            try:
                callback(event)
            except Exception:  # a broken display must never stop the flight loop
                with self._lock:
                    if callback in self._subscribers:
                        self._subscribers.remove(callback)
        return event
