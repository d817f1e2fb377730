"""Wire one session together: models, link, mapper, bridge, voice thread, keys, view and logs.

``gcs-voice fly`` and ``gcs-voice demo`` both call ``run_session``. Everything that can be wrong in
the user's input (a model, a WAV, a dictionary, a connection string, a settings file) is loaded or
checked *before* the link opens, so a mistake costs one line and no flight.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.bridge import STOP_SIGNALS, Bridge, Request
from gcs_voice.session.collisions import CollisionWatch
from gcs_voice.session.events import Event, EventBus
from gcs_voice.session.listen import (ScriptStep, TentativeUtterances, VoicePipeline, read_utterance, run_microphone,
                                      run_recording, run_script, start_voice_thread)
from gcs_voice.session.session_log import SessionLog, session_paths

if TYPE_CHECKING:  # annotations only: the engines and matchers load when a session picks them
    from gcs_voice.audio.speaker import EchoGate, EchoRoom, Player
    from gcs_voice.session.feedback import Feedback
    from gcs_voice.asr.base import Recognizer
    from gcs_voice.asr.stop_spotter import StopSpotter
    from gcs_voice.domain.dictionary import Dictionary
    from gcs_voice.link.security import LinkSecurity
    from gcs_voice.understanding.matcher import Matcher

__all__ = ["SessionConfig", "SessionResult", "Voice", "run_session", "load_voice", "USER_ERROR_EXIT"]

#: what hears a session: (recogniser, matcher, dictionaries, stream language; None = let the engine choose)
Voice: TypeAlias = tuple["Recognizer", "Matcher", "list[Dictionary]", "str | None"]

#: exit status of a session ended by a user mistake or a missing vehicle (GcsVoiceError), as the CLI exits
USER_ERROR_EXIT = 2
#: exit status of a session in which the vehicle hit something (and nothing worse happened)
COLLISION_EXIT = 1


@dataclass
class SessionConfig:
    connection: str
    lang: str = "en"
    engine: str | None = None
    model: str | None = None
    matcher: str | None = None
    dictionaries: Sequence[str | Path] = ()
    settings_path: Path | None = None
    say: Sequence[Path] = ()
    #: a recording heard as the microphone would hear it (real time, through the segmenter), then the end
    listen_wav: Path | None = None
    gap_s: float = 3.0
    hold_s: float = 3.0
    takeoff_m: float | None = None
    push_to_talk: bool = False
    headless: bool = True
    as_json: bool = False
    #: headless without the console printer (benchmarks); the session log is still written
    quiet: bool = False
    log_dir: Path = Path(".")
    log_name: str | None = None
    wait_vehicle_s: float = 30.0
    #: explicit script (demo: per-step holds); overrides say/gap/hold when given
    script: Sequence[ScriptStep] | None = None
    #: extra bus subscribers (the demo's summary)
    subscribers: Sequence[Callable[[Event], None]] = ()
    #: single settings given as flags (``--speed``...), over ``settings_path``; None = not given
    setting_overrides: dict[str, float | None] = field(default_factory=dict)
    #: --signing-key, --require-signed, --lock-vehicle (a gcs_voice.link.security.LinkSecurity; None = none)
    link_security: LinkSecurity | None = None
    #: how the user wrote each override (its flag), for error messages
    setting_names: dict[str, str] = field(default_factory=dict)
    #: run the stop spotter before the main recogniser (a stop word stops at once)
    stop_spotter: bool = True
    #: hold a moving vehicle from the end of each utterance to its decision; resume after speech not understood
    pause_while_deciding: bool = True
    #: what the pilot hears after each decision and warning: speech | tones | off (gcs_voice.session.feedback;
    #: off here, so a library caller or a test hears nothing unasked; ``gcs-voice`` defaults to speech)
    feedback: str = "off"
    #: with ``listen_wav``: the feedback is played into the recording (gain in dB, delay in s), as a speaker
    #: beside the microphone would put it there, instead of out of the sound card
    feedback_echo: tuple[float, float] | None = None
    #: where the feedback plays instead of the sound card (a gcs_voice.audio.speaker.Player: a benchmark's
    #: TimedSink); the microphone is not gated for it
    feedback_player: Player | None = None


@dataclass
class SessionResult:
    exit_code: int
    tlog: Path
    jsonl: Path
    events: list = field(default_factory=list)


def load_voice(lang: str, engine: str | None, model: str | None, matcher_name: str | None,
               dictionary_files: Sequence[str | Path] = ()) -> Voice:
    """(recognizer, matcher, dictionaries, stream language) for a language choice; errors are one line."""
    from gcs_voice.asr.registry import default_engine, load_recognizer
    from gcs_voice.domain.dictionary import AUTO_LANGUAGES, load_dictionary, load_language
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    if dictionary_files:
        dictionaries = [load_dictionary(p) for p in dictionary_files]
    else:
        dictionaries = [load_language(code) for code in (AUTO_LANGUAGES if lang == "auto" else (lang,))]
    stream_lang = None if lang == "auto" else lang
    engine_name = engine or default_engine(lang)
    recognizer = load_recognizer(engine_name, dictionaries, model=model)
    matcher = get_matcher(matcher_name or DEFAULT_MATCHER)
    return recognizer, matcher, dictionaries, stream_lang


def _stop_spotter(config: SessionConfig, dictionaries: Sequence[Dictionary], bus: EventBus) -> StopSpotter | None:
    """The stop spotter for the session's languages, or None (said once) when off or unavailable."""
    if not config.stop_spotter:
        return None
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.errors import GcsVoiceError

    try:
        return load_stop_spotter(sorted({d.language for d in dictionaries}))
    except (GcsVoiceError, ImportError) as exc:
        bus.emit("warning", f"no stop spotter ({exc}): a stop waits for the main recogniser like any word")
        return None


def _script(config: SessionConfig) -> list[ScriptStep]:
    if config.script is not None:
        return list(config.script)
    paths = list(config.say)
    return [ScriptStep(p, config.gap_s if i < len(paths) - 1 else config.hold_s) for i, p in enumerate(paths)]


def _feedback(config: SessionConfig, dictionaries: Sequence[Dictionary], bus: EventBus
              ) -> tuple[Feedback | None, EchoGate | None, EchoRoom | None, Callable[[float, bytes], bytes] | None]:
    """The session's feedback (subscribed to the bus), the gate that keeps the microphone deaf to it, the
    echo room it plays into (``feedback_echo``), and what takes its echo out of the stop spotter's audio while
    deaf; Nones when off, or (said once) when there is no speaker."""
    if config.feedback == "off":
        return None, None, None, None
    from gcs_voice.audio.speaker import EchoGate, EchoRoom, open_speaker
    from gcs_voice.session.feedback import FEEDBACK_DIR, Feedback, load_phrases, load_sound_settings

    sounds = load_sound_settings()
    spoken = sorted({d.language for d in dictionaries})
    languages = {lang: load_phrases(lang) for lang in spoken if (FEEDBACK_DIR / f"{lang}.toml").is_file()}
    if len(languages) < len(spoken):
        bus.emit("warning", f"feedback: no phrases for {', '.join(l for l in spoken if l not in languages)} "
                 f"(gcs_voice/data/feedback/): {'English' if not languages else ', '.join(languages)} instead",
                 source="feedback")
        languages = languages or {"en": load_phrases("en")}
    room = None
    if config.feedback_player is not None:
        player = config.feedback_player
    elif config.feedback_echo is not None and config.listen_wav is not None:
        gain_db, delay_s = config.feedback_echo
        room = EchoRoom(10 ** (gain_db / 20), delay_s)
        player: Player = room
    else:
        try:
            player = open_speaker()
        except GcsVoiceError as exc:
            bus.emit("warning", f"feedback off: {exc}; decisions are shown, not heard", source="feedback")
            return None, None, None, None
    # the microphone is deaf while the speaker plays; a recording (--listen-wav) hears the speaker only through
    # the echo room: played out of the sound card, the feedback cannot reach it, so there is nothing to gate
    gate = (EchoGate(sounds.tail_s) if room is not None or (config.listen_wav is None and config.feedback_player is None)
            else None)
    default = config.lang if config.lang in languages else next(iter(languages))
    feedback = Feedback(config.feedback, languages, default, player, gate or EchoGate(0.0), bus, sounds)
    bus.subscribe(feedback)
    clean = None
    if gate is not None and sounds.echo_cancel is not None:
        from gcs_voice.audio.echo_cancel import EchoCanceller, PlayedEcho

        clean = PlayedEcho(gate, EchoCanceller(**sounds.echo_cancel))
    return feedback, gate, room, clean


class _Terminated(KeyboardInterrupt):
    """SIGTERM / SIGHUP before the flight loop: unwinds like Ctrl-C (logs closed, link closed)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, _frame: Any) -> None:
    raise _Terminated(signum)


def run_session(config: SessionConfig, voice: Voice | None = None) -> SessionResult:
    """Fly one session to its end; the vehicle is stopped before this returns, whatever happened."""
    import signal

    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        # Before the flight loop (which stops the vehicle on these itself), kill / a closed terminal must
        # still close the logs; the default action would end the process on the spot.
        for signum in (s for s in STOP_SIGNALS if s != signal.SIGINT):
            previous[signum] = signal.signal(signum, _raise_terminated)
    try:
        return _run_session(config, voice)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _run_session(config: SessionConfig, voice: Voice | None) -> SessionResult:
    from gcs_voice.actions.mapper import ActionMapper
    from gcs_voice.link import VehicleLink
    from gcs_voice.settings import load_settings

    overrides = dict(config.setting_overrides)
    if config.takeoff_m is not None:  # take off at once, to this height: checked like the setting
        overrides["takeoff_altitude_m"] = config.takeoff_m
    settings = load_settings(config.settings_path, names={"takeoff_altitude_m": "--takeoff", **config.setting_names},
                             **overrides)
    recognizer, matcher, dictionaries, stream_lang = voice or load_voice(
        config.lang, config.engine, config.model, config.matcher, config.dictionaries)
    steps = _script(config)
    for step in steps:
        read_utterance(step.path)  # a missing or unusable WAV fails here, before any flight
    listen_pcm = read_utterance(config.listen_wav) if config.listen_wav is not None else None
    if not steps and listen_pcm is None:
        from gcs_voice.audio.microphone import check_microphone

        check_microphone()
    tlog, jsonl = session_paths(config.log_dir, config.log_name)

    bus = EventBus()
    link = None
    view = None
    feedback = None
    watch = CollisionWatch(bus, settings.hard_landing_m_s, mode=lambda: link.state.mode if link else None)
    exit_code = 1
    error: str | None = None

    def link_said(line: str) -> None:
        if line.startswith(("waiting for: ", "set mode: ", "arm: ready")):  # link.readiness, while arming
            waiting = line.removeprefix("waiting for: ").split(" (vehicle: ")[0] if line.startswith("waiting") else ""
            bus.emit("ready", line, waiting_for=waiting)
        elif line.startswith("vehicle: "):
            bus.emit("vehicle", line, text=line.removeprefix("vehicle: "))
        elif not line.startswith("link "):  # link transitions are said by the bridge, once
            bus.emit("warning", line, source="link")

    log = SessionLog(jsonl)
    try:  # from the moment a log file exists: whatever happens, the finally below closes (or removes) it
        bus.subscribe(log)
        for subscriber in config.subscribers:
            bus.subscribe(subscriber)
        if config.headless and not config.quiet:
            from gcs_voice.session.headless import HeadlessPrinter

            bus.subscribe(HeadlessPrinter(as_json=config.as_json))
        bus.subscribe(watch)  # after the printers: a hit is printed after the vehicle's text that says it
        bus.emit("session", f"session start: {config.connection}, logs {tlog.name} + {jsonl.name}", phase="start",
                 argv=sys.argv[1:], connection=config.connection, tlog=str(tlog), jsonl=str(jsonl),
                 engine=getattr(recognizer, "name", None), lang=config.lang, matcher=getattr(matcher, "name", None))
        feedback, gate, echo_room, clean = _feedback(config, dictionaries, bus)  # (its notices follow the start)
        link = VehicleLink(config.connection, settings, tlog_path=tlog, on_event=link_said,
                           security=config.link_security)
        link.open()
        mapper = ActionMapper(settings)
        bridge = Bridge(link, mapper, bus, settings.takeoff_altitude_m)
        if not config.headless:
            from gcs_voice.session.view import LiveView

            view = LiveView(bridge.status, lambda: "")
            bus.subscribe(view.state)
            view.start()
        state = link.wait_vehicle(config.wait_vehicle_s)
        bus.emit("link", f"vehicle heard: {state.autopilot}, mode {state.mode}", state="heard",
                 autopilot=state.autopilot)
        telemetry = link.request_telemetry()
        if not telemetry.ok:
            bus.emit("warning", f"telemetry request: {telemetry}")
        pipeline = VoicePipeline(recognizer, matcher, dictionaries, stream_lang, bus,
                                 stop_spotter=_stop_spotter(config, dictionaries, bus),
                                 pause_while_deciding=config.pause_while_deciding)
        ready: threading.Event | None = None
        if config.takeoff_m is not None:
            bridge.submit(Request("take_off", "script"))
            ready = bridge.flying_ready
        if steps:
            start_voice_thread(bridge, run_script, pipeline, bridge, steps, 0.0, ready,
                               link.ready_timeout_s + settings.takeoff_timeout_s + 30.0)
        else:
            from gcs_voice.audio.microphone import microphone_utterances
            from gcs_voice.session.keys import talk

            stop_path = pipeline.stop_path
            if stop_path is not None and clean is not None:
                stop_path.own_echo = clean.only_remains
            on_speech = (lambda pcm: stop_path.feed(bridge, pcm)) if stop_path is not None else None
            over_voice = (lambda pcm: stop_path.feed(bridge, pcm, over_voice=True)) if stop_path is not None else None
            tentatives = TentativeUtterances()  # decided while the closing silence runs out
            if listen_pcm is None:
                start_voice_thread(bridge, run_microphone, pipeline, bridge,
                                   microphone_utterances(talk if config.push_to_talk else None, on_speech=on_speech,
                                                         on_tentative=tentatives,
                                                         deaf=gate.deaf if gate is not None else None, clean=clean,
                                                         on_speech_over_voice=over_voice,
                                                         speaking=gate.pilot_speaking if gate is not None else None),
                                   stop_path is not None, tentatives)
            else:
                from gcs_voice.audio.sources import AudioChunk, paced_chunks

                def recording() -> Iterator[AudioChunk]:
                    """The recording from when the vehicle is ready, at the pace it was spoken."""
                    if ready is not None and not ready.wait(link.ready_timeout_s + settings.takeoff_timeout_s + 30.0):
                        raise GcsVoiceError("the vehicle did not become ready in time to hear the recording")
                    def started(t0: float) -> None:
                        if echo_room is not None:
                            echo_room.start(t0)
                        bus.emit("session", f"listening to {config.listen_wav.name} as a microphone",
                                 phase="listening", source=config.listen_wav.name, audio_t0=t0)

                    played = paced_chunks(listen_pcm, on_start=started)
                    yield from (echo_room.hear(played) if echo_room is not None else played)

                start_voice_thread(bridge, run_recording, pipeline, bridge,
                                   microphone_utterances(on_speech=on_speech, on_tentative=tentatives,
                                                         chunks=recording(),
                                                         deaf=gate.deaf if gate is not None else None, clean=clean,
                                                         on_speech_over_voice=over_voice,
                                                         speaking=gate.pilot_speaking if gate is not None else None),
                                   stop_path is not None, tentatives, config.hold_s)
        if not config.headless and sys.stdin.isatty():
            from gcs_voice.session.keys import start_key_thread

            start_key_thread(bridge)
        exit_code = bridge.run()
        if watch.count:  # a flight that hit something did not go well, whatever else went right
            exit_code = exit_code or COLLISION_EXIT
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, _Terminated) else 2
        bus.emit("session", f"{'interrupted (Ctrl-C)' if signum == 2 else f'signal {signum}'} before the flight loop",
                 phase="interrupt")
        exit_code = 128 + signum
    except GcsVoiceError as exc:  # the CLI prints it in one line and exits 2: the log says the same
        exit_code, error = USER_ERROR_EXIT, str(exc)
        raise
    finally:
        if view is not None:
            view.stop()
        if feedback is not None:
            feedback.close()
        if link is not None:
            link.close()
        heard = link is not None and link.state.heartbeats > 0
        collided = f"; {watch.count} collision{'s' if watch.count > 1 else ''}" if watch.count else ""
        bus.emit("session", f"session end (exit {exit_code}{collided})", phase="end", exit_code=exit_code,
                 collisions=watch.count, **({"error": error} if error else {}))
        log.close()
        if not heard:  # nothing flew and nothing was heard: no logs (the one-line error says why)
            for path in (tlog, jsonl):
                path.unlink(missing_ok=True)
    return SessionResult(exit_code, tlog, jsonl, [e.to_dict() for e in bus.history])
