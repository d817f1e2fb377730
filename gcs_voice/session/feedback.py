"""The pilot hears the decision: a cue per decision and per warning, out of a speaker, never in the way.

A pilot looks at the drone, not at a screen. After each decision the bridge plays one of three tones a
pilot tells apart without looking (rising: doing it; one low: not understood; falling: refused), and with
``--feedback speech`` (the default of ``gcs-voice``) says what in the session's language: "going left",
"refused, not armed". Warnings (link lost and restored, the vehicle's mode changed, whoever changed it:
a failsafe, another station; floor / ceiling / fence reached; waiting to arm and for what; the vehicle's
low-battery warning; a failed take-off) are three quick beeps and their words. What is said is data: ``gcs_voice/data/feedback/<lang>.toml``; the tones: ``sounds.toml``.

Cues are made from the session's events (``gcs_voice.session.events``), the same records the console
prints, so the feedback says nothing the log does not. ``Feedback`` only queues in the emitter's thread;
rendering and playing run in its own thread (``feedback``), so a cue never delays a command. Before a
sound starts it is held on the ``EchoGate`` (``gcs_voice.audio.speaker``): the microphone's segmenter is
deaf to it, the stop spotter is not. A newer decision's cue replaces one still waiting: what the pilot
needs is the latest decision, not a backlog.
"""

from __future__ import annotations

import re
import threading
import time
import tomllib
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.events import Event, EventBus

if TYPE_CHECKING:  # the sound side loads when a session plays something (``gcs-voice --help`` stays light)
    from gcs_voice.audio.speaker import EchoGate, Player

__all__ = ["MODES", "DEFAULT_MODE", "Cue", "Phrases", "SoundSettings", "Feedback", "cue_for", "load_phrases",
           "load_sound_settings", "FEEDBACK_DIR"]

FEEDBACK_DIR = Path(__file__).resolve().parent.parent / "data" / "feedback"
#: ``--feedback``: tones and words, tones alone, or nothing
MODES = ("speech", "tones", "off")
#: a pilot on a field looks at the drone: "going left" and "going right" sound the same as tones, and a
#: wrong action is the one thing the pilot must catch at once, so the words are on by default
DEFAULT_MODE = "speech"
TONES = ("doing", "not_understood", "refused", "warning")
#: a wait-to-arm reason said again only after this long (the readiness check repeats it every few seconds)
WAITING_REPEAT_S = 15.0
#: a stop the spotter fired is not said when the same cue was queued less than this before (see __call__)
SPOTTER_REPEAT_S = 5.0
#: a decision or a wait-to-arm said later than this after it happened is no longer news
STALE_S = 2.5
#: the events' shapes this module reads (gcs_voice.session.bridge): "vehicle is in BRAKE, not GUIDED: ..."
_OTHER_MODE = re.compile(r"vehicle is in (\S+), not ")


@dataclass(frozen=True)
class Cue:
    """One thing to play: a tone (one of TONES), then words (may be empty)."""

    tone: str
    words: str = ""
    #: a decision's cue (replaced by a newer decision's while it waits), not a warning
    decision: bool = False
    #: dropped when it has waited longer than STALE_S (the moment passed: the log still has it); link and
    #: mode warnings never go stale
    stale_s: float | None = None
    queued_t: float = 0.0

    @property
    def stale(self) -> bool:
        """Queued longer ago than ``stale_s``: the moment to say it has passed."""
        return self.stale_s is not None and time.time() - self.queued_t > self.stale_s


@dataclass(frozen=True)
class Phrases:
    """What is said in one language (``<lang>.toml``)."""

    language: str
    voice: str
    actions: dict[str, str]
    said: dict[str, str]
    reasons: dict[str, str]
    waiting: dict[str, str]
    #: mode names said otherwise (a mode called like a stop word: PX4's HOLD)
    modes: dict[str, str]
    #: how an amount said with a motion is said back ("{n} metres", "{n} degrees", "to {n} metres")
    amounts: dict[str, str] = field(default_factory=dict)

    def mode(self, name: str) -> str:
        return self.said["mode"].format(mode=self.modes.get(name.upper(), name))

    def amount(self, said: dict[str, Any] | None) -> str:
        """An amount said with a motion, as said back (issue 33: the pilot hears "going forward, 3 metres", and a
        misheard amount is caught at once); "" when none was said or the language has no words for it."""
        if not said:
            return ""
        key = "height" if said.get("height") else {"m": "metres", "deg": "degrees"}.get(str(said.get("unit")), "")
        if said.get("value") == 1 and f"{key}_one" in self.amounts:  # "1 metre", "a 1 metro"
            key = f"{key}_one"
        return self.amounts.get(key, "").format(n=said.get("value"))

    def reason(self, text: str) -> str:
        """The words for a refusal's or a limit's reason: the vehicle's other mode, else the first match."""
        other = _OTHER_MODE.search(text)
        if other:
            return self.mode(other.group(1))
        low = text.lower()
        return next((words for key, words in self.reasons.items() if key.lower() in low), "")


@dataclass(frozen=True)
class SoundSettings:
    amplitude: float
    fade_s: float
    tones: dict[str, list[list[float]]]
    tail_s: float
    speed_wpm: int
    #: the echo canceller's settings (``gcs_voice.audio.echo_cancel.EchoCanceller``'s keywords); None: off
    echo_cancel: dict[str, float] | None = None
    #: how long a cue waits for the pilot to finish a word before it is played over it
    wait_for_pilot_s: float = 2.0


def _load(path: Path) -> dict[str, Any]:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise GcsVoiceError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as exc:
        raise GcsVoiceError(f"{path}: not valid TOML: {exc}") from None


def load_phrases(language: str, folder: Path = FEEDBACK_DIR) -> Phrases:
    """The phrases of one language; a missing file, table or action is one line naming the file."""
    from gcs_voice.domain.dictionary import ACTIONS

    path = folder / f"{language}.toml"
    data = _load(path)
    tables = {}
    for name in ("actions", "said", "reasons", "waiting", "modes", "amounts"):
        table = data.get(name, {} if name in ("modes", "amounts") else None)
        if not isinstance(table, dict) or not all(isinstance(v, str) for v in table.values()):
            raise GcsVoiceError(f"{path}: [{name}] must be a table of strings")
        tables[name] = dict(table)
    missing = [a for a in ACTIONS if a not in tables["actions"]]
    if missing:
        raise GcsVoiceError(f"{path}: [actions] has no phrase for {', '.join(missing)}")
    needed = ("not_understood", "refused", "link_lost", "link_restored", "mode", "waiting", "battery",
              "take_off_failed", "error", "collision", "takeover", "loud_room")
    missing = [k for k in needed if k not in tables["said"]]
    if missing:
        raise GcsVoiceError(f"{path}: [said] has no phrase for {', '.join(missing)}")
    return Phrases(str(data.get("language", language)), str(data.get("voice", language)), **tables)


#: the echo canceller's settings in sounds.toml [echo] (``EchoCanceller``'s keywords)
ECHO_KEYS = ("length_s", "step", "min_step", "regularization", "suppress", "comfort_noise_dbfs", "residual_gate_db",
             "window_s", "loud_db", "learn_s")


def load_sound_settings(path: Path = FEEDBACK_DIR / "sounds.toml") -> SoundSettings:
    data = _load(path)
    tones = data.get("tones", {})
    missing = [t for t in TONES if t not in tones]
    if missing:
        raise GcsVoiceError(f"{path}: [tones] has no {', '.join(missing)}")
    echo = data.get("echo", {})
    cancel = None
    if echo.get("cancel", False):
        try:
            cancel = {key: float(echo[key]) for key in ECHO_KEYS if key in echo}
        except (TypeError, ValueError):
            raise GcsVoiceError(f"{path}: [echo] {', '.join(ECHO_KEYS)} must be numbers") from None
    try:
        wait_s = float(echo.get("wait_for_pilot_s", 2.0))
    except (TypeError, ValueError):
        raise GcsVoiceError(f"{path}: [echo] wait_for_pilot_s must be a number of seconds") from None
    return SoundSettings(float(data.get("amplitude", 0.3)), float(data.get("fade_s", 0.005)), tones,
                         float(echo.get("tail_s", 0.4)), int(data.get("speech", {}).get("speed_wpm", 175)), cancel,
                         wait_s)


def cue_for(event: Event, phrases: Phrases) -> Cue | None:
    """What the pilot hears for one event (None: nothing)."""
    d, said = event.data, phrases.said
    if event.kind == "command":
        if d.get("origin") == "shutdown":
            return None  # the session's own end: the pilot ended it
        words = phrases.actions.get(str(d.get("action")), "")
        amount = phrases.amount(d.get("said_amount"))
        return Cue("doing", f"{words}, {amount}" if words and amount else words, decision=True, stale_s=STALE_S)
    if event.kind == "rejected":
        if d.get("say_loud_room"):  # the voice was barely above the room: the pilot can help it
            return Cue("not_understood", said["loud_room"], decision=True, stale_s=STALE_S)
        return Cue("not_understood", said["not_understood"], decision=True, stale_s=STALE_S)
    if event.kind == "refused":
        reason = phrases.reason(str(d.get("reason", "")))
        if "origin" not in d:  # a limit on the motion in progress (floor, ceiling, fence): a warning
            return Cue("warning", reason) if reason else None
        return Cue("refused", f"{said['refused']}, {reason}" if reason else said["refused"], decision=True,
                   stale_s=STALE_S)
    if event.kind == "link" and d.get("state") in ("lost", "restored"):
        return Cue("warning", said["link_lost" if d["state"] == "lost" else "link_restored"])
    if event.kind == "warning" and d.get("source") == "link" and event.msg.startswith("battery low: "):
        return Cue("warning", said["battery"])  # the bridge's own threshold (battery_low_pct), link.channel
    if event.kind == "warning" and d.get("source") == "link" and event.msg.startswith("vehicle now "):
        # "vehicle now RTL, armed" (gcs_voice.link.channel: a mode or arming change, whoever made it)
        return Cue("warning", phrases.mode(event.msg.removeprefix("vehicle now ").split(",")[0]))
    if event.kind == "warning" and d.get("source") == "mapper":  # "go_left -> stop: floor 0.5 m reached"
        reason = phrases.reason(event.msg.split(": ", 1)[-1])
        if not reason or "link lost" in event.msg:  # a lost link is said by its own event
            return None
        return Cue("warning", reason)
    if event.kind == "ready" and d.get("waiting_for"):
        low = str(d["waiting_for"]).lower()
        what = [words for key, words in phrases.waiting.items() if key.lower() in low]
        # a wait the table does not name (the arming mode settling: a second) is not said
        return Cue("warning", said["waiting"].format(what=what[0]), stale_s=STALE_S) if what else None
    if event.kind == "takeover" and d.get("by") == "station":
        # the mode itself is said by the link's mode line; this says who: another ground station took over
        return Cue("warning", said["takeover"])
    if event.kind == "flight":
        if d.get("what") == "mode" and d.get("mode"):  # the vehicle's mode changed, not by us
            return Cue("warning", phrases.mode(str(d["mode"])))
        if d.get("what") == "take_off" and d.get("ok") is False:
            return Cue("refused", said["take_off_failed"])
        return None
    if event.kind == "vehicle" and "battery" in str(d.get("text", "")).lower():
        # the autopilot's own low-battery warning (ArduPilot "Battery 1 is low ...", PX4 "Low battery level! ...")
        return Cue("warning", said["battery"])
    if event.kind == "error":
        return Cue("warning", said["error"])
    if event.kind == "collision":
        return Cue("warning", said["collision"])
    return None


def _mode_line(event: Event) -> bool:
    """Whether the event is the link's "vehicle now MODE, armed|disarmed"."""
    return event.data.get("source") == "link" and event.msg.startswith("vehicle now ")


class Feedback:
    """A bus subscriber that plays each event's cue in its own thread; ``close()`` at the end."""

    def __init__(self, mode: str, languages: dict[str, Phrases], default_language: str, player: Player,
                 gate: EchoGate, bus: EventBus, sounds: SoundSettings | None = None) -> None:
        from gcs_voice.audio.sounds import Speech, tone
        from gcs_voice.audio.speaker import pcm_seconds

        self._seconds = pcm_seconds

        if mode not in MODES or mode == "off":
            raise ValueError(f"not a feedback mode to play: {mode!r}")
        self.mode = mode
        self.languages = languages
        self.language = default_language
        self.player = player
        self.gate = gate
        self.bus = bus
        s = sounds or load_sound_settings()
        self.wait_for_pilot_s = s.wait_for_pilot_s
        self.tones = {name: tone(notes, s.amplitude, s.fade_s) for name, notes in s.tones.items()}
        self.speech: dict[str, Speech] = {}
        if mode == "speech":
            from gcs_voice.errors import AudioError

            try:
                self.speech = {lang: Speech(p.voice, s.speed_wpm) for lang, p in languages.items()}
            except AudioError as exc:
                bus.emit("warning", f"feedback: {exc}", source="feedback")
        self._queue: deque[Cue] = deque()
        self._ready = threading.Condition()
        self._closed = False
        self._last_waiting: tuple[str, float] = ("", 0.0)
        self._last_mode = ""
        self._last_said: tuple[str, str, float] = ("", "", 0.0)  # tone, words, when queued
        self._said_over_t = 0.0  # when a cue was last said over the pilot (after wait_for_pilot_s)
        #: cues played, as (UNIX time started, cue, seconds): for the log and the tests
        self.played: list[tuple[float, Cue, float]] = []
        self._warm()  # before the session flies: the first cue is as quick as any
        self._thread = threading.Thread(target=self._run, name="feedback", daemon=True)
        self._thread.start()

    def __call__(self, event: Event) -> None:
        """Queue the event's cue (the emitter's thread: nothing slow here)."""
        if event.kind == "heard" and event.data.get("lang") in self.languages:
            self.language = event.data["lang"]  # --lang auto: answer in the language just spoken
        cue = cue_for(event, self.languages[self.language])
        if cue is None:
            return
        if event.kind == "warning" and _mode_line(event):  # said when the mode changes, not when only arming does
            if cue.words == self._last_mode:
                return
            self._last_mode = cue.words
        if event.data.get("origin") == "spotter":
            # a stop the spotter fired is not said again if it says what was just said: the spotter hears the
            # bridge's own voice, and a cue it took for a stop must not start a loop of stops and cues
            if (cue.tone, cue.words) == self._last_said[:2] and event.t - self._last_said[2] < SPOTTER_REPEAT_S:
                return
        if event.kind == "ready":
            last, at = self._last_waiting
            if cue.words == last and event.t - at < WAITING_REPEAT_S:
                return
            self._last_waiting = (cue.words, event.t)
        cue = replace(cue, queued_t=time.time())
        self._last_said = (cue.tone, cue.words, event.t)
        with self._ready:
            if cue.decision:
                self._queue = deque(c for c in self._queue if not c.decision)
            self._queue.append(cue)
            self._ready.notify()

    def close(self, timeout_s: float = 5.0) -> None:
        """Play what is queued (up to ``timeout_s``), then end the thread."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        self._thread.join(timeout_s)

    def _warm(self) -> None:
        """Render every decision's and fixed warning's words now (espeak-ng, ~30 ms a phrase), so none waits for
        it in flight (a mode's name or a wait's reason is rendered once, when first said)."""
        from gcs_voice.errors import AudioError

        for lang, speech in list(self.speech.items()):
            p = self.languages[lang]
            try:
                refusals = [f"{p.said['refused']}, {why}" for why in p.reasons.values()]
                for words in (*p.actions.values(), *refusals, *p.reasons.values(), p.said["link_lost"],
                              p.said["link_restored"], p.said["battery"], p.said["loud_room"]):
                    speech.say(words)
            except AudioError as exc:
                self.bus.emit("warning", f"feedback: {exc}; tones only", source="feedback")
                self.speech = {}
                return

    def _run(self) -> None:
        from gcs_voice.errors import AudioError

        while True:
            with self._ready:
                while not self._queue and not self._closed:
                    self._ready.wait()
                if not self._queue:
                    return
                cue = self._queue.popleft()
            if cue.stale:
                continue
            # The pilot's turn first: a sound begun over a word cuts it in two (the microphone goes deaf), and a
            # stop cut so may be heard by neither half. A cue that has waited long enough is played over it.
            if not self.gate.wait_pilot_done(self.wait_for_pilot_s) and time.time() - self._said_over_t > 60.0:
                self._said_over_t = time.time()  # said once a minute at most: in babble it could be every cue
                self.bus.emit("warning", f"feedback: the pilot was still speaking after {self.wait_for_pilot_s:g} s; "
                              "said over it", source="feedback")
            with self._ready:
                newer = cue.decision and any(c.decision for c in self._queue)
            if newer or cue.stale:
                continue  # a newer decision came while the pilot spoke, or the moment passed
            pcm = self.tones[cue.tone]
            speech = self.speech.get(self.language)
            if speech is not None and cue.words:
                try:
                    pcm += bytes(int(0.05 * 16_000) * 2) + speech.say(cue.words)
                except AudioError as exc:
                    self.bus.emit("warning", f"feedback: {exc}; tones only", source="feedback")
                    self.speech = {}
            seconds = self._seconds(pcm)
            start = time.time()
            self.gate.hold(start, seconds)  # deaf before the sound starts
            self.bus.emit("feedback", f"said: {cue.tone.replace('_', ' ')}{': ' + cue.words if cue.words and speech else ''}",
                          tone=cue.tone, words=cue.words if speech is not None else "", played_t=start,
                          seconds=round(seconds, 3), player=self.player.name)
            try:
                self.player.play(pcm, started=lambda t, sound=pcm: self.gate.record(t, sound))  # the canceller's reference
            except Exception as exc:  # noqa: BLE001 - a broken speaker must not end the session
                self.bus.emit("warning", f"feedback: the speaker failed ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
                              "feedback is shown, not heard", source="feedback")
                return
            self.played.append((start, cue, seconds))
