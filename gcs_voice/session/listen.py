"""The voice side of a session: utterances -> recogniser -> matcher -> requests for the bridge.

Runs in its own thread. An utterance is either a recorded WAV from ``--say`` (fed whole, as if just
spoken) or a segment of the microphone cut by ``gcs_voice.audio.sources``. Every utterance leaves a ``heard``
event, then either a ``rejected`` event (no action: nothing happens) or a request to the bridge.
Any exception here is a crash of the voice side: it is reported and the session ends with the
vehicle stopped (the bridge's ``finish`` leads to its ``shutdown``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.understanding.decision import Decision
from gcs_voice.session.events import EventBus

__all__ = ["VoicePipeline", "ScriptStep", "read_utterance", "run_script", "run_microphone", "start_voice_thread"]

CHUNK_BYTES = 3200  # 0.1 s of 16 kHz int16: what a microphone callback would deliver
BYTES_PER_S = 32_000


@dataclass(frozen=True)
class ScriptStep:
    """One recorded utterance of a script and how long (wall seconds) its action runs before the next."""

    path: Path
    after_s: float
    #: done by the script anyway (origin "script") when the utterance is not heard as an action;
    #: the demo uses it for take-off and landing, so a missed word never leaves it on the ground or flying
    fallback_action: str | None = None


def read_utterance(path: str | Path) -> bytes:
    """16 kHz mono int16 PCM of a WAV file (through gcs_voice.audio.sources, which converts and validates)."""
    from gcs_voice.audio.sources import read_wav

    return read_wav(path)


class VoicePipeline:
    """One recogniser, one matcher, the dictionaries; ``hear(pcm)`` -> Decision, with events."""

    def __init__(self, recognizer: Any, matcher: Any, dictionaries: Sequence[Any], lang: str | None,
                 bus: EventBus, realtime: bool = True) -> None:
        self.recognizer = recognizer
        #: feed recorded PCM at the pace it was spoken (as a microphone would), so streaming engines
        #: work during the utterance and latency counts from its real end
        self.realtime = realtime
        self.last_end_t = 0.0
        self.matcher = matcher
        self.dictionaries = list(dictionaries)
        self.lang = lang  # None = let the engine / matcher choose among the dictionaries (--lang auto)
        self.bus = bus

    def hear(self, pcm: bytes, source: str, utterance_end_t: float | None = None,
             recorded: bool = False) -> Decision:
        """Recognise and decide one utterance; ``recorded`` PCM is fed chunk by chunk (real time if set)."""
        stream = self.recognizer.start_stream(self.lang)
        started = time.monotonic()
        for n, i in enumerate(range(0, len(pcm), CHUNK_BYTES)):
            if recorded and self.realtime:
                lag_s = started + n * CHUNK_BYTES / BYTES_PER_S - time.monotonic()
                if lag_s > 0:
                    time.sleep(lag_s)
            stream.accept(pcm[i:i + CHUNK_BYTES])
        if recorded and self.realtime:
            lag_s = started + len(pcm) / BYTES_PER_S - time.monotonic()
            if lag_s > 0:
                time.sleep(lag_s)
        end_t = time.time() if recorded or utterance_end_t is None else utterance_end_t
        recognition = stream.finish()
        heard_t = time.time()
        self.last_end_t = end_t
        alternatives = [h.text for h in recognition.hypotheses[:5]]
        self.bus.emit("heard", f"heard {recognition.text!r} ({recognition.engine}"
                      f"{', ' + recognition.lang if recognition.lang else ''}) from {source}",
                      text=recognition.text, alternatives=alternatives, engine=recognition.engine,
                      lang=recognition.lang, audio_s=round(recognition.audio_s, 3), source=source,
                      utterance_end_t=end_t, recognize_ms=round((heard_t - end_t) * 1000, 1))
        decision = self.matcher.decide(recognition, self.dictionaries)
        if not decision.accepted:
            self.bus.emit("rejected", f"no action for {decision.text!r}: {decision.reason}",
                          text=decision.text, phrase=decision.phrase, score=round(decision.score, 3),
                          reason=decision.reason, matcher=decision.matcher, source=source,
                          utterance_end_t=end_t, decided_t=time.time())
        return decision

    def submit(self, bridge: Bridge, pcm: bytes, source: str, utterance_end_t: float | None = None,
               recorded: bool = False) -> Request | None:
        """Hear one utterance and hand an accepted action to the bridge (None when rejected)."""
        decision = self.hear(pcm, source, utterance_end_t, recorded)
        if not decision.accepted:
            return None
        return bridge.submit(Request(decision.action, "voice", decision, self.last_end_t, time.time()))


def run_script(pipeline: VoicePipeline, bridge: Bridge, steps: Sequence[ScriptStep], wait_before_s: float = 0.0,
               ready: threading.Event | None = None, ready_timeout_s: float = 120.0) -> None:
    """Feed recorded utterances in order, each ``after_s`` apart, then end the session."""
    if ready is not None and not ready.wait(ready_timeout_s):
        bridge.bus.emit("error", f"the vehicle did not become ready within {ready_timeout_s:g} s; ending")
        bridge.finish(1)
        return
    if _sleep_unless_finished(bridge, wait_before_s):
        return
    pcms = [(step, read_utterance(step.path)) for step in steps]  # read all first: bad files fail early
    for step, pcm in pcms:
        request = pipeline.submit(bridge, pcm, step.path.name, recorded=True)
        if request is not None:
            request.done.wait(10.0)
        if step.fallback_action and (request is None or request.action != step.fallback_action):
            bridge.bus.emit("warning", f"{step.path.name} was not heard as {step.fallback_action}: "
                            f"the script does it instead", source="script")
            request = bridge.submit(Request(step.fallback_action, "script"))
            request.done.wait(10.0)
        if request is not None and request.action in ("take_off", "land"):
            _wait_operation(bridge)  # then hold: after_s counts from the vehicle being up (or landing)
        if _sleep_unless_finished(bridge, step.after_s):
            return
    bridge.bus.emit("session", "script done: holding and ending", phase="script-done")
    bridge.finish(0)


def _wait_operation(bridge: Bridge, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while bridge.busy and not bridge.finished and time.monotonic() < deadline:
        time.sleep(0.05)


def _sleep_unless_finished(bridge: Bridge, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if bridge.finished:
            return True
        time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))
    return bridge.finished


def run_microphone(pipeline: VoicePipeline, bridge: Bridge, utterances: Iterable[tuple[bytes, float]]) -> None:
    """Serve utterances from a live source (PCM, end time) until the bridge finishes."""
    for pcm, end_t in utterances:
        if bridge.finished:
            break
        pipeline.submit(bridge, pcm, "microphone", end_t)


def start_voice_thread(bridge: Bridge, target: Callable[..., None], *args: Any) -> threading.Thread:
    """Run the voice side; an exception in it ends the session (vehicle stopped) with exit code 1."""

    def guarded() -> None:
        try:
            target(*args)
        except BaseException as exc:  # noqa: BLE001 - any failure here must stop the vehicle
            message = str(exc) or type(exc).__name__
            bridge.bus.emit("error", f"voice side failed ({type(exc).__name__}: {message}); stopping the vehicle",
                            error=type(exc).__name__)
            bridge.finish(2 if _is_user_error(exc) else 1)

    thread = threading.Thread(target=guarded, name="voice", daemon=True)
    thread.start()
    return thread


def _is_user_error(exc: BaseException) -> bool:
    from gcs_voice.errors import GcsVoiceError

    return isinstance(exc, GcsVoiceError)
