"""``gcs-voice [fly]``: connect to a vehicle and fly it by voice (microphone, or recorded ``--say`` files).

    gcs-voice --udp 14550                          # listen like a ground station, speak to fly
    gcs-voice --connect tcp:127.0.0.1:5760 --say takeoff.wav forward.wav --takeoff 1.5 --headless --json
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gcs_voice.link.options import DEFAULT_UDP_PORT


def _seconds(positive: bool):
    """An argparse ``type``: a finite number of seconds (> 0 when ``positive``, else >= 0)."""
    import math

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
        if not math.isfinite(value) or value < 0 or (positive and value == 0):
            raise argparse.ArgumentTypeError(f"{text}: a finite number of seconds {'> 0' if positive else '>= 0'}")
        return value

    return parse


def _echo(text: str) -> tuple[float, float]:
    """An argparse ``type``: DB:MS -> (gain in dB, delay in seconds)."""
    import math

    try:
        db, ms = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: DB:MS, e.g. -6:60 (6 dB down, 60 ms late)") from None
    if not (math.isfinite(db) and math.isfinite(ms)) or db > 20 or not 0 <= ms <= 2000:
        raise argparse.ArgumentTypeError(f"{text!r}: gain at most +20 dB, delay 0 to 2000 ms")
    return db, ms / 1000.0


def _stem(text: str) -> str:
    """An argparse ``type``: a file name stem for the logs (the folder is --log-dir)."""
    if not text.strip() or text.startswith(".") or any(sep in text for sep in ("/", "\\")):
        raise argparse.ArgumentTypeError(f"{text!r}: a file name without folder or leading dot (use --log-dir)")
    return text


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from gcs_voice.link.options import add_setting_arguments, range_help, setting_type

    link = parser.add_argument_group("vehicle link")
    where = link.add_mutually_exclusive_group()
    where.add_argument("--udp", type=int, metavar="PORT",
                       help=f"listen for the vehicle on UDP PORT, like a ground station (default {DEFAULT_UDP_PORT})")
    where.add_argument("--connect", metavar="STRING",
                       help="pymavlink connection string: udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
                            "tcpin:HOST:PORT, /dev/ttyACM0[,BAUD]")
    link.add_argument("--wait", type=_seconds(positive=True), default=30.0, metavar="S",
                      help="seconds to wait for the vehicle's first HEARTBEAT (default 30)")
    from gcs_voice.link.security import add_security_arguments

    add_security_arguments(link)
    voice = parser.add_argument_group("voice")
    voice.add_argument("--lang", default="en", choices=("en", "es", "auto"), help="language spoken (default en)")
    voice.add_argument("--engine", help="recogniser: vosk, whisper or sphinx (default: the best installed one "
                                        "for the language)")
    voice.add_argument("--model", help="model path or name for the engine")
    voice.add_argument("--matcher", help="how heard text is matched to the dictionary (default: the project's "
                                         "default matcher)")
    voice.add_argument("--dictionary", action="append", metavar="TOML",
                       help="use this dictionary file instead of the bundled one (repeatable)")
    mic = voice.add_mutually_exclusive_group()
    mic.add_argument("--push-to-talk", action="store_true",
                     help="listen only while toggled with Enter (default: always listening)")
    voice.add_argument("--no-stop-spotter", action="store_true",
                       help="do not run the stop spotter before the recogniser (a stop then waits for the main "
                            "decision like any word)")
    voice.add_argument("--no-pause", action="store_true",
                       help="keep a moving vehicle moving while an utterance is decided (default: it holds from the "
                            "end of the speech until the decision, and resumes after speech that was not a command)")
    mic.add_argument("--listen-wav", type=Path, metavar="WAV",
                     help="hear this recording as the microphone would (in real time, cut into utterances by the "
                          "segmenter), then end the session")
    mic.add_argument("--say", nargs="+", type=Path, metavar="WAV",
                     help="feed these recorded utterances in order, as if spoken, instead of the microphone")
    voice.add_argument("--gap", type=_seconds(positive=False), default=3.0, metavar="S",
                       help="with --say: seconds each action runs before the next utterance (default 3)")
    voice.add_argument("--hold", type=_seconds(positive=False), default=3.0, metavar="S",
                       help="with --say or --listen-wav: seconds the last action runs before the session ends, stopped "
                            "(default 3)")
    from gcs_voice.session.feedback import DEFAULT_MODE, MODES

    heard = parser.add_argument_group("what the pilot hears")
    heard.add_argument("--feedback", choices=MODES, default=DEFAULT_MODE,
                       help="after each decision and warning: a tone and the words (speech), the tone alone (tones: "
                            "rising = doing it, low = not understood, falling = refused), or nothing (off). While it "
                            f"plays the microphone hears only stop words (default {DEFAULT_MODE})")
    heard.add_argument("--feedback-echo", type=_echo, metavar="DB:MS",
                       help="with --listen-wav: play the feedback into the recording DB decibels down and MS "
                            "milliseconds late, as a speaker beside the microphone would (--feedback-echo=-6:60), instead of "
                            "out of the sound card")
    flight = parser.add_argument_group("flight")
    flight.add_argument("--takeoff", type=setting_type("takeoff_altitude_m"), metavar="M",
                        help="arm and take off to M metres as soon as the vehicle reports it can"
                             + range_help("takeoff_altitude_m"))
    flight.add_argument("--config", type=Path, metavar="FILE",
                        help="settings TOML overriding the defaults (speeds, floor, fence, ceiling, link timing)")
    add_setting_arguments(flight)
    out = parser.add_argument_group("output")
    out.add_argument("--headless", action="store_true", help="one line per event instead of the live view")
    out.add_argument("--json", action="store_true", help="with --headless: each line is the JSON event record")
    out.add_argument("--log-dir", type=Path, default=Path("."), metavar="DIR",
                     help="where the session's .tlog and .jsonl go (default: current directory)")
    out.add_argument("--log-name", type=_stem, metavar="STEM", help="file name stem for the session logs (default: time stamp)")


def run(args: argparse.Namespace) -> int:
    from gcs_voice.errors import GcsVoiceError
    from gcs_voice.link.options import setting_flag_names, setting_overrides
    from gcs_voice.link.security import security_from_args
    from gcs_voice.session.run import SessionConfig, run_session
    from gcs_voice.settings import load_settings

    if args.json and not args.headless:
        args.headless = True
    if args.feedback_echo is not None and args.listen_wav is None:
        raise GcsVoiceError("--feedback-echo plays the feedback into a --listen-wav recording: give --listen-wav")
    overrides, names = setting_overrides(args), setting_flag_names()
    if args.takeoff is not None:  # --takeoff M is the take-off height too
        if overrides.get("takeoff_altitude_m") not in (None, args.takeoff):
            raise GcsVoiceError(f"--takeoff {args.takeoff:g} and --takeoff-alt {overrides['takeoff_altitude_m']:g} "
                                "disagree: give one")
        overrides["takeoff_altitude_m"], names["takeoff_altitude_m"] = args.takeoff, "--takeoff"
    load_settings(args.config, names=names, **overrides)  # values that disagree (floor above ceiling): one line now
    connection = _connection(args)
    config = SessionConfig(
        connection=connection, lang=args.lang, engine=args.engine, model=args.model, matcher=args.matcher,
        dictionaries=args.dictionary or [], settings_path=args.config, say=args.say or [], gap_s=args.gap,
        hold_s=args.hold, takeoff_m=args.takeoff, push_to_talk=args.push_to_talk, headless=args.headless,
        as_json=args.json, log_dir=args.log_dir, log_name=args.log_name, wait_vehicle_s=args.wait,
        setting_overrides=overrides, setting_names=names, link_security=security_from_args(args),
        stop_spotter=not args.no_stop_spotter,
        pause_while_deciding=not args.no_pause, listen_wav=args.listen_wav, feedback=args.feedback,
        feedback_echo=args.feedback_echo,
    )
    return run_session(config).exit_code


def _connection(args: argparse.Namespace) -> str:
    from gcs_voice.errors import GcsVoiceError
    from gcs_voice.link.connection import parse_connection, udp_listen

    if args.connect:
        parse_connection(args.connect)  # one clear line for a malformed string
        return args.connect
    port = DEFAULT_UDP_PORT if args.udp is None else args.udp
    if not 0 < port < 65536:
        raise GcsVoiceError(f"--udp {port}: not a port number (1-65535)")
    return udp_listen(port)
