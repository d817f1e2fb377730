"""The voice side of a session: utterances -> recogniser -> matcher -> requests for the bridge.

Runs in its own thread. An utterance is either a recorded WAV from ``--say`` (fed whole, as if just
spoken) or a segment of the microphone cut by ``gcs_voice.audio.vad``. Every utterance leaves a ``heard``
event, then either a ``rejected`` event (no action: nothing happens) or a request to the bridge.

A stop is never late: the stop spotter (``gcs_voice.asr.stop_spotter``, a few milliseconds per piece of
audio) hears each utterance while it arrives, before the main recogniser, and a stop word goes to the
bridge at once (a ``spotted`` event, then the stop command); the main decision follows when ready and
may command something else. The microphone is read and spotted in its own thread (``ear``), so a stop
is heard even while the recogniser is still busy with the utterance before it. Between the end of an
utterance and its decision a ``thinking`` event is out; a decision more than ``LATE_S`` after the end
of its utterance is said (a ``late`` event). From the end of each utterance to its decision a moving
vehicle is paused (``bridge.PAUSE``: the segmenter's first sign that the speech has ended, or the end
of a recorded utterance), so a stop the spotter missed still takes effect at the end of the speech, not
when the recogniser is done; speech that is not understood then resumes the motion (``RESUME``), unless
what was heard was nearest a stop, too unsurely to act on (``STAY``: stopping is always safe).
Any exception here is a crash of the voice side: it is reported and the session ends with the
vehicle stopped (the bridge's ``finish`` leads to its ``shutdown``).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gcs_voice.actions.mapper import TRANSLATING_MOTIONS
from gcs_voice.asr.base import Abandoned, BufferedStream
from gcs_voice.asr.ear import ear_evidence
from gcs_voice.audio.microphone import HeardUtterance
from gcs_voice.audio.vad import load_vad_settings
from gcs_voice.audio.sources import pcm_to_chunks
from gcs_voice.domain.text import normalize_text
from gcs_voice.session.bridge import PAUSE, RESUME, STAY, Bridge, Request
from gcs_voice.understanding.decision import Decision
from gcs_voice.understanding.thresholds import ear_limits
from gcs_voice.session.events import EventBus

if TYPE_CHECKING:  # annotations only: the engines, the spotter and the matchers load when a session picks them
    from gcs_voice.asr.base import Recognition, Recognizer
    from gcs_voice.asr.stop_spotter import SpotStream, StopSpotter
    from gcs_voice.domain.dictionary import Dictionary
    from gcs_voice.understanding.matcher import Matcher

__all__ = ["VoicePipeline", "loud_room_hint", "StopPath", "ScriptStep", "TentativeUtterances", "read_utterance", "run_script", "run_microphone", "run_recording",
           "start_voice_thread", "LATE_S"]

BYTES_PER_S = 32_000
#: a decision later than this after the end of its utterance is said: the pilot may have moved on
LATE_S = 2.0
#: how long the voice side waits for the bridge to send a spotted stop before it goes on
STOP_WAIT_S = 1.0
#: a stop word heard over the bridge's own voice this soon after a stop this path sent, with the vehicle still
#: holding on it, is that stop heard again (the end of the pilot's word under the bridge's "braking"): not re-sent
REPEAT_OVER_VOICE_S = 3.0
#: how long a script waits for its take-off or landing to end before it goes on
OPERATION_WAIT_S = 60.0
#: the pilot is told aloud that the room is loud at most this often (the rejection's text says it every time)
LOUD_ROOM_REPEAT_S = 30.0


def loud_room_hint(snr_db: float | None, limit_db: float, went_on: bool, margin: float | None = None,
                   min_margin: float = -float("inf")) -> str:
    """What a rejected utterance tells the pilot of the room: that it is loud, when the voice stood less than
    ``limit_db`` above it, since the pilot can help (speak up, or nearer the microphone); but only when it may have
    been a command: not for talk that went on past a command's words (``Decision.went_on``), nor when Whisper scoring
    found no command phrase within ``min_margin`` of what it heard (``margin``: a word like "bird", not a command
    misheard). Empty: nothing to say."""
    if snr_db is None or snr_db >= limit_db or went_on or (margin is not None and margin < min_margin):
        return ""
    return f"the room is loud: the voice was {snr_db:.0f} dB above it; speak up, or nearer the microphone"


class StopPath:
    """The stop spotter between the ear and the bridge: a stop word is a stop request at once.

    ``feed`` takes the audio of the utterance in progress (the segmenter's listener, or the recorded
    chunks) and ``None`` at its end. One utterance at a time, from one thread. ``own_echo`` says when what is
    heard over the bridge's voice is only what the echo canceller left of it (``PlayedEcho.only_remains``).
    """

    def __init__(self, spotter: StopSpotter, bus: EventBus) -> None:
        self.spotter = spotter
        self.bus = bus
        self.own_echo: Callable[[], bool] | None = None
        #: a spotted stop holds a moving vehicle (PAUSE) and the utterance's decision settles it, instead of
        #: cancelling the motion (set when the recogniser has a domain ear to settle it with: issue 52)
        self.provisional = False
        #: a provisional hold was asked and no decision has settled it yet
        self.holding = False
        #: the domain ear's probability of "stop" for some audio, and the least that keeps a hold stopped: settles a
        #: hold spotted over the bridge's own voice, which no decision follows (set with ``provisional``)
        self.ear_stop: Callable[[bytes], float | None] | None = None
        self.over_voice_stop_min = 0.0
        self._pcm: list[bytes] = []
        self._stream: SpotStream | None = None
        self._fired = False
        self._last_stop: Request | None = None  # the stop this path sent last

    def feed(self, bridge: Bridge, pcm: bytes | None, end_t: float | None = None, over_voice: bool = False) -> None:
        """``over_voice``: heard while the bridge itself was speaking (the spotter's over_voice_threshold)."""
        if pcm is None:
            self.end(bridge, end_t)
            return
        if self._stream is not None and self._stream.over_voice != over_voice:
            self.end(bridge)  # the bridge started or stopped speaking: what came before is decided on its own
        if self._stream is None:
            self._stream = self.spotter.start_stream(over_voice, self.own_echo if over_voice else None)
            self._fired = False
            self._pcm = []
        if over_voice and self.provisional:
            self._pcm.append(pcm)
        word = self._stream.accept(pcm)
        if word and not self._fired:
            self._fired = True
            self._stop(bridge, word, None, during=True, over_voice=over_voice)

    def end(self, bridge: Bridge, end_t: float | None = None) -> str | None:
        """The utterance is over: stop now if a stop word was in it (and not already sent); the word."""
        if self._stream is None:
            return None
        stream, self._stream = self._stream, None
        hit = stream.finish()
        if stream.dismissed:
            heard = ", ".join(map(repr, stream.dismissed))
            self.bus.emit("own_echo", f"heard {heard} in what was left of the bridge's own voice: not a stop",
                          words=stream.dismissed)
        if hit.fired and not self._fired:
            self._stop(bridge, hit.word, end_t, during=False, over_voice=stream.over_voice)
        self._fired = False
        if stream.over_voice and self.holding:
            self._settle_over_voice(bridge, b"".join(self._pcm), end_t)
        self._pcm = []
        return hit.word

    def _settle_over_voice(self, bridge: Bridge, pcm: bytes, end_t: float | None) -> None:
        """A hold spotted over the bridge's own voice: no decision will settle it (the segmenter gives what was
        heard over its voice no decision of its own), so the domain ear does, on the audio the spotter heard:
        stopped, unless the ear is sure it was no stop."""
        self.holding = False
        p = self.ear_stop(pcm) if self.ear_stop is not None else None
        stay = p is None or p >= self.over_voice_stop_min
        self.bus.emit("settled", f"the stop heard over the bridge's voice was "
                      f"{'taken as a stop' if stay else 'no stop'} (domain ear: stop {p if p is not None else float('nan'):.0%})",
                      stay=stay, ear_stop=p, utterance_end_t=end_t)
        now = time.time()
        why = (f"the stop heard over the bridge's voice: the over-voice ear gave stop {p:.0%}" if p is not None
               else "the stop heard over the bridge's voice: no ear to settle it")
        bridge.submit(Request(STAY if stay else RESUME, "spotter", None, end_t if end_t is not None else now, now,
                              why=why))

    def take_hold(self) -> bool:
        """Whether a provisional hold waits for a decision; the decision at hand settles it."""
        holding, self.holding = self.holding, False
        return holding

    def _repeat(self, bridge: Bridge, now: float) -> float | None:
        """Seconds since the stop this path sent last, if the vehicle still holds on it and it is recent."""
        last = self._last_stop
        if last is None or not last.accepted or now - last.decided_t > REPEAT_OVER_VOICE_S:
            return None
        mapper = bridge.mapper
        if mapper.action != "stop" or mapper.paused is not None or bridge.busy:
            return None  # something was commanded since: a stop now is a new one
        return now - last.decided_t

    def _stop(self, bridge: Bridge, word: str | None, end_t: float | None, during: bool, over_voice: bool) -> None:
        now = time.time()
        where = " over the bridge's voice" if over_voice else ""
        since = self._repeat(bridge, now) if over_voice else None
        if since is not None:
            # The bridge's voice that it was heard over is, most likely, the cue of that very stop; the vehicle
            # already holds, so sending it again would change nothing but the decisions the pilot hears of.
            self.bus.emit("spotted", f"stop word {word!r} heard again{where} {since:.1f} s after the stop just sent: "
                          "already holding, not sent again", word=word, utterance_end_t=end_t, spotted_t=now,
                          over_voice=over_voice, repeat=True)
            return
        end = end_t if end_t is not None else now
        mapper = bridge.mapper
        if self.provisional and (mapper.action in TRANSLATING_MOTIONS or mapper.paused in TRANSLATING_MOTIONS):
            # Held at once, as a stop would be; the decision of the utterance settles it: a stop, another command,
            # or speech that was no stop (the motion goes on: a stop for nothing must not cancel it). A motion
            # already paused while an utterance before is decided is held the same way, not cancelled.
            self.bus.emit("spotted", f"stop word {word!r} heard{where}{' (still speaking)' if during else ''}: "
                          "holding until it is decided", word=word, utterance_end_t=end_t, spotted_t=now,
                          over_voice=over_voice, provisional=True)
            self.holding = True
            request = bridge.submit(Request(PAUSE, "spotter", None, end, now))
            request.done.wait(STOP_WAIT_S)
            return
        self.bus.emit("spotted", f"stop word {word!r} heard{where}{' (still speaking)' if during else ''}: stopping now",
                      word=word, utterance_end_t=end_t, spotted_t=now, over_voice=over_voice)
        request = bridge.submit(Request("stop", "spotter", None, end, now))
        self._last_stop = request
        # Wait (a few ms) until the bridge has sent it: the main recogniser that runs next may hold the
        # interpreter for a second (PocketSphinx decodes without releasing the GIL) and starve the bridge.
        request.done.wait(STOP_WAIT_S)


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

    def __init__(self, recognizer: Recognizer, matcher: Matcher, dictionaries: Sequence[Dictionary],
                 lang: str | None, bus: EventBus, realtime: bool = True,
                 stop_spotter: StopSpotter | None = None, pause_while_deciding: bool = True,
                 loud_room_snr_db: float | None = None) -> None:
        self.recognizer = recognizer
        #: hold a moving vehicle from the end of each utterance to its decision (see the module's docstring)
        self.pause_while_deciding = pause_while_deciding
        #: heard before the recogniser (None: no spotter, stops wait for the main decision like any word)
        self.stop_path = StopPath(stop_spotter, bus) if stop_spotter is not None else None
        #: a spotted stop is settled by the decision when the recogniser has a domain ear (gcs_voice/asr/ear.py):
        #: the motion resumes after speech that was not understood only if the ear gives "stop" less than
        #: ``spotted_stop``; Whisper's best phrase being a stop keeps it stopped if the ear gives ``nearest_stop``
        limits = _ear_stop_limits(recognizer)
        self.spotted_stop_min = limits.get("spotted_stop")
        self.nearest_stop_min = limits.get("nearest_stop")
        if self.stop_path is not None and self.spotted_stop_min is not None:
            self.stop_path.provisional = True
            self.stop_path.over_voice_stop_min = limits.get("over_voice_stop", self.spotted_stop_min)
            self.stop_path.ear_stop = lambda pcm: _ear_stop(recognizer, pcm)
        #: the domain ear's probability of "stop" for the last utterance heard (None: no ear)
        self.last_ear_stop: float | None = None
        #: feed recorded PCM at the pace it was spoken (as a microphone would), so streaming engines
        #: work during the utterance and latency counts from its real end
        self.realtime = realtime
        self.last_end_t = 0.0
        self.last_heard_words: tuple[str, ...] = ()
        self.matcher = matcher
        self.dictionaries = list(dictionaries)
        self.lang = lang  # None = let the engine / matcher choose among the dictionaries (--lang auto)
        self.bus = bus
        #: (PCM, its recognition) decided while the end-of-utterance silence ran out (``speculate``)
        self._speculated: tuple[bytes, Recognition] | None = None
        #: speculations given up half-way because their utterance went on (``speculate(stale=...)``)
        self.abandoned = 0
        #: a rejected voice less than this far above the room is told that the room is loud (vad.toml)
        vad = load_vad_settings()
        self.loud_room_snr_db = vad.loud_room_snr_db if loud_room_snr_db is None else loud_room_snr_db
        self.loud_room_min_margin = vad.loud_room_min_margin
        self._loud_room_said_t = -float("inf")

    def pause_motion(self, bridge: Bridge, utterance_end_t: float | None = None) -> None:
        """An utterance has ended: hold a moving vehicle until it is decided (the bridge ignores it otherwise)."""
        if self.pause_while_deciding:
            now = time.time()
            request = bridge.submit(Request(PAUSE, "voice", None, utterance_end_t if utterance_end_t is not None
                                            else now, now))
            # Wait (a few ms) until the bridge has sent it, as for a spotted stop: the recogniser that runs
            # next may hold the interpreter (PocketSphinx decodes without releasing the GIL).
            request.done.wait(STOP_WAIT_S)

    def settle_pause(self, bridge: Bridge, decision: Decision, more_waiting: bool = False) -> None:
        """After a rejected decision: resume the paused motion, or stay stopped if what was heard was nearest a
        stop: Whisper wrote a stop phrase; or its best-scored phrase is one and the domain ear gives "stop" at least
        ``nearest_stop``; or the stop spotter held it and the ear gives "stop" at least ``spotted_stop``. Heard, but
        not surely enough to act on: stopping is safe, but a stop for nothing cancels the pilot's motion, so the
        thresholds keep 95 % of the dev speakers' stops and no more (``python -m tools.speech.bench_ear tune``).

        Nothing while another utterance waits for its decision (its end paused the vehicle too)."""
        spotted = self.stop_path is not None and not more_waiting and self.stop_path.take_hold()
        if not (self.pause_while_deciding or spotted) or decision.accepted or more_waiting:
            return
        written, best_phrase = self.last_heard_words or ("", "")
        wrote, best = self._class_of(written) == "stop", self._class_of(best_phrase) == "stop"
        p = self.last_ear_stop
        near_stop = stays_stopped(wrote, best, p, spotted, self.spotted_stop_min, self.nearest_stop_min)
        ear = f" and the domain ear gave stop {p:.0%}" if p is not None else ""
        why = (f"Whisper heard '{written}'" if wrote else f"Whisper's nearest phrase was '{best_phrase}'{ear}" if best
               else f"the stop spotter heard a stop{ear}")
        bridge.submit(Request(STAY if near_stop else RESUME, "voice", decision, self.last_end_t, time.time(),
                              why=why if near_stop else ""))

    def _class_of(self, words: str) -> str | None:
        """The action class of a dictionary phrase that is exactly these words (normalised), or None."""
        key = normalize_text(words)
        for d in self.dictionaries:
            phrase = d.by_key.get(key) if key else None
            if phrase is not None:
                return phrase.action
        return None

    def speculate(self, pcm: bytes, stale: Callable[[], bool] | None = None) -> None:
        """Recognise a tentative utterance now; ``hear`` uses the result if the utterance ends as it is.

        Every engine decides the same PCM the same way (the engine conformance test), so the early
        result is the one ``hear`` would compute: only the time the silence took is saved. ``stale`` is
        asked between the engine's stages (engines that have them: :class:`BufferedStream`): when it says
        the guess is no longer the utterance, the rest of the work is skipped, so it delays the real one less.
        """
        self._speculated = None
        stream = self.recognizer.start_stream(self.lang)
        if stale is not None and isinstance(stream, BufferedStream):
            stream.abandon = stale
        for chunk in pcm_to_chunks(pcm):
            stream.accept(chunk.pcm)
        try:
            recognition = stream.finish()
        except Abandoned:
            self.abandoned += 1
            return
        self._speculated = (pcm, recognition)

    def hear(self, pcm: bytes, source: str, utterance_end_t: float | None = None,
             recorded: bool = False, bridge: Bridge | None = None, began_deaf: bool = False,
             snr_db: float | None = None) -> Decision:
        """Recognise and decide one utterance; ``recorded`` PCM is fed chunk by chunk (real time if set).

        With a ``bridge``, recorded audio also goes through the stop spotter as it is fed (the
        microphone's is spotted by the ear thread as it is spoken). An utterance that ``began_deaf`` (the pilot
        was speaking as the bridge's own sound ended: only its end was heard) is acted on only if it is a stop.
        ``snr_db``: how far the voice stood above the room (the segmenter's); a rejection of a voice less than
        ``loud_room_snr_db`` above it says so, since the pilot can help it (speak up, or nearer the microphone),
        where a command may have been lost (``loud_room_hint``): where people talk in a loud room, a hint for every
        rejection came about once a minute, for talk as much as for commands (docs/bench/listen.md).
        """
        spot = self.stop_path if recorded and bridge is not None else None
        speculated, self._speculated = self._speculated, None
        early = speculated[1] if speculated is not None and not recorded and speculated[0] == pcm else None
        stream = self.recognizer.start_stream(self.lang) if early is None else None
        started = time.monotonic()
        for chunk in (pcm_to_chunks(pcm) if stream is not None else ()):
            if recorded and self.realtime:
                lag_s = started + chunk.start_s - time.monotonic()
                if lag_s > 0:
                    time.sleep(lag_s)
            if spot is not None:
                spot.feed(bridge, chunk.pcm)
            stream.accept(chunk.pcm)
        if recorded and self.realtime:
            lag_s = started + len(pcm) / BYTES_PER_S - time.monotonic()
            if lag_s > 0:
                time.sleep(lag_s)
        end_t = time.time() if recorded or utterance_end_t is None else utterance_end_t
        if recorded and bridge is not None:
            self.pause_motion(bridge, end_t)  # (the microphone's utterances are paused for by the ear thread)
        if spot is not None:
            spot.end(bridge, end_t)
        self.bus.emit("thinking", f"thinking… ({len(pcm) / BYTES_PER_S:.1f} s from {source})", source=source,
                      utterance_end_t=end_t)
        recognition = stream.finish() if stream is not None else early
        assert recognition is not None
        heard_t = time.time()
        self.last_end_t = end_t
        #: the engine's own words (Whisper's free transcript when its hypotheses are scored phrases), and its best
        #: hypothesis (a scored phrase)
        self.last_heard_words = (recognition.transcript or recognition.text,
                                 recognition.best.text if recognition.best else "")
        self.last_ear_stop = ear_evidence(recognition.extra).get("stop")
        alternatives = [h.text for h in recognition.hypotheses[:5]]
        self.bus.emit("heard", f"heard {recognition.heard!r} ({recognition.engine}"
                      f"{', ' + recognition.lang if recognition.lang else ''}) from {source}",
                      text=recognition.text, transcript=recognition.transcript, alternatives=alternatives,
                      engine=recognition.engine, lang=recognition.lang, audio_s=round(recognition.audio_s, 3), source=source,
                      utterance_end_t=end_t, recognize_ms=round((heard_t - end_t) * 1000, 1),
                      speculated=early is not None, snr_db=snr_db)
        decision = self.matcher.decide(recognition, self.dictionaries)
        if began_deaf and decision.accepted and decision.action != "stop":
            decision = replace(decision, action=None, amount=None,
                               reason=f"heard only the end of it ('{decision.text}'): it began while the bridge was "
                                      "speaking; say it again")
        late_s = time.time() - end_t
        if late_s > LATE_S:
            self.bus.emit("late", f"late: decided {late_s:.1f} s after the utterance ended "
                          f"({decision.action or 'no action'}; the recogniser or the CPU is slow)",
                          late_s=round(late_s, 2), action=decision.action, source=source, utterance_end_t=end_t)
        if not decision.accepted:
            loud = snr_db is not None and snr_db < self.loud_room_snr_db
            hint = loud_room_hint(snr_db, self.loud_room_snr_db, decision.went_on, recognition.extra.get("margin"),
                                  self.loud_room_min_margin)
            say_loud = bool(hint) and time.time() - self._loud_room_said_t >= LOUD_ROOM_REPEAT_S
            if say_loud:
                self._loud_room_said_t = time.time()
            self.bus.emit("rejected", f"no action for {decision.text!r}: {decision.reason}{f' ({hint})' if hint else ''}",
                          text=decision.text, phrase=decision.phrase, score=round(decision.score, 3),
                          reason=decision.reason, matcher=decision.matcher, source=source,
                          utterance_end_t=end_t, decided_t=time.time(), snr_db=snr_db, loud_room=loud,
                          say_loud_room=say_loud, hint=hint)
        return decision

    def submit(self, bridge: Bridge, pcm: bytes, source: str, utterance_end_t: float | None = None,
               recorded: bool = False, more_waiting: Callable[[], bool] | None = None,
               began_deaf: bool = False, snr_db: float | None = None) -> Request | None:
        """Hear one utterance and hand an accepted action to the bridge (None when rejected: then the paused
        motion resumes, unless ``more_waiting`` says another utterance waits for its decision)."""
        decision = self.hear(pcm, source, utterance_end_t, recorded, bridge, began_deaf, snr_db)
        if not decision.accepted:
            self.settle_pause(bridge, decision, more_waiting is not None and more_waiting())
            return None
        if self.stop_path is not None:
            self.stop_path.take_hold()  # the decided action replaces a provisional hold
        return bridge.submit(Request(decision.action, "voice", decision, self.last_end_t, time.time()))


def run_script(pipeline: VoicePipeline, bridge: Bridge, steps: Sequence[ScriptStep], wait_before_s: float = 0.0,
               ready: threading.Event | None = None, ready_timeout_s: float = 120.0) -> None:
    """Feed recorded utterances in order, each ``after_s`` apart, then end the session."""
    if ready is not None and not ready.wait(ready_timeout_s):
        bridge.bus.emit("error", f"the vehicle did not become ready within {ready_timeout_s:g} s; ending")
        bridge.finish(1)
        return
    if bridge.wait_finished(wait_before_s):
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
            bridge.wait_idle(OPERATION_WAIT_S)  # then hold: after_s counts from the vehicle being up (or landing)
        if bridge.wait_finished(step.after_s):
            return
    bridge.bus.emit("session", "script done: holding and ending", phase="script-done")
    bridge.finish(0)


class TentativeUtterances:
    """Where the segmenter's tentative utterances go: to the voice thread of ``run_microphone``.

    Pass it to ``microphone_utterances(on_tentative=...)`` and to ``run_microphone``; until the voice
    thread runs (or without it) tentative utterances are dropped.
    """

    def __init__(self) -> None:
        self.sink: Callable[[bytes], None] | None = None

    def __call__(self, pcm: bytes) -> None:
        if self.sink is not None:
            self.sink(pcm)


@dataclass(frozen=True)
class _Tentative:
    pcm: bytes


def run_microphone(pipeline: VoicePipeline, bridge: Bridge, utterances: Iterable[HeardUtterance | tuple[bytes, float]],
                   spotted_while_spoken: bool = False, tentatives: TentativeUtterances | None = None) -> None:
    """Serve utterances from a live source (PCM, end time[, whether it began deaf]) until the bridge finishes.

    The source is read in its own thread (``ear``) and each utterance queued for the recogniser, so
    the next one is heard (and a stop in it spotted) while the recogniser is busy. Unless the source
    already fed the stop spotter as the words were spoken (``spotted_while_spoken``), the ear spots
    each whole utterance before queueing it. With ``tentatives``, an utterance the segmenter expects
    to end is recognised while its closing silence runs out (when nothing else waits), and its
    decision is taken at once if it does end that way.
    """
    heard: queue.Queue[tuple[bytes, float, bool, float | None] | _Tentative | BaseException | None] = queue.Queue()
    if tentatives is not None:
        def tentative(pcm: bytes) -> None:
            pipeline.pause_motion(bridge)  # the speech has ended (the first sign of it): hold until decided
            heard.put(_Tentative(pcm))

        tentatives.sink = tentative

    def ear() -> None:
        try:
            for utterance in utterances:
                pcm, end_t = utterance[0], utterance[1]
                began_deaf = isinstance(utterance, HeardUtterance) and utterance.began_deaf
                snr_db = utterance.snr_db if isinstance(utterance, HeardUtterance) else None
                if bridge.finished:
                    break
                pipeline.pause_motion(bridge, end_t)  # (already paused by its tentative one, if any)
                if pipeline.stop_path is not None and not spotted_while_spoken:
                    pipeline.stop_path.feed(bridge, pcm)
                    pipeline.stop_path.end(bridge, end_t)
                heard.put((pcm, end_t, began_deaf, snr_db))
        except BaseException as exc:  # noqa: BLE001 - handed to the voice thread, which ends the session
            heard.put(exc)
        finally:
            heard.put(None)

    threading.Thread(target=ear, name="ear", daemon=True).start()
    while not bridge.finished:
        item = heard.get()
        if item is None:
            break
        if isinstance(item, BaseException):
            raise item
        if isinstance(item, _Tentative):
            if heard.empty():  # a real utterance waiting comes first; a stale guess is skipped
                pipeline.speculate(item.pcm, stale=lambda pcm=item.pcm: _superseded(heard, pcm))
            continue
        pcm, end_t, began_deaf, snr_db = item
        pipeline.submit(bridge, pcm, "microphone", end_t, more_waiting=lambda: not heard.empty(),
                        began_deaf=began_deaf, snr_db=snr_db)


def run_recording(pipeline: VoicePipeline, bridge: Bridge, utterances: Iterable[HeardUtterance | tuple[bytes, float]],
                  spotted_while_spoken: bool = False, tentatives: TentativeUtterances | None = None,
                  hold_s: float = 3.0) -> None:
    """``run_microphone`` on a source that ends (a recording heard as a microphone), then hold and end."""
    run_microphone(pipeline, bridge, utterances, spotted_while_spoken, tentatives)
    if not bridge.finished and not bridge.wait_finished(hold_s):
        bridge.bus.emit("session", "recording done: holding and ending", phase="script-done")
        bridge.finish(0)


def _superseded(heard: queue.Queue, pcm: bytes) -> bool:
    """Whether something newer than the guess ``pcm`` waits: another guess, an utterance that is not this
    one (speech went on), or the end of the source."""
    with heard.mutex:
        waiting = list(heard.queue)
    return any(not (isinstance(item, tuple) and item[0] == pcm) for item in waiting)


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


def stays_stopped(wrote: bool, best: bool, p_stop: float | None, spotted: bool, spotted_min: float | None,
                  nearest_min: float | None) -> bool:
    """Whether a motion held while an utterance was decided stays stopped after the decision rejected it: Whisper
    wrote a stop phrase (``wrote``); or ranked one first (``best``: it does for many a short word in noise) and the
    domain ear gives "stop" at least ``nearest_min``; or the stop spotter held it (``spotted``) and the ear gives
    "stop" at least ``spotted_min``. Without an ear (``p_stop`` or a limit None) a stop heard at all stays."""
    if wrote:
        return True
    if best and (p_stop is None or nearest_min is None or p_stop >= nearest_min):
        return True
    return spotted and (p_stop is None or spotted_min is None or p_stop >= spotted_min)


def _ear_stop_limits(recognizer: Any) -> dict[str, float]:
    """The ear's "stop" probabilities that keep a held motion stopped after speech that was not understood
    (``[ear.<engine>]`` spotted_stop, nearest_stop, over_voice_stop); empty when the recogniser has no domain ear."""
    if getattr(recognizer, "ear", None) is None:  # only Whisper in scoring mode has one
        return {}
    return ear_limits(getattr(recognizer, "name", ""))


def _ear_stop(recognizer: Any, pcm: bytes) -> float | None:
    """The domain ear's probability of "stop" for 16 kHz int16 audio heard over the bridge's own voice (None: it
    heard nothing to judge): the over-voice ear, which learnt what the echo canceller leaves of the bridge's cues."""
    import numpy as np

    audio = np.frombuffer(pcm, "<i2").astype(np.float32) / 32768.0
    if audio.size < 1600:
        return None
    return recognizer.hear(audio, over_voice=True).get("ear:stop")
