"""``gcs-voice demo``: start the bundled simulator, fly the shipped spoken sequence, plot the flight.

Needs nothing beyond ``pip install .``: English runs on PocketSphinx's bundled model (``--model`` does
not change that; ``--engine`` does). Spanish flies too when an engine with a Spanish model is present (a
Vosk Spanish model, or Whisper via ``--model`` or a faster-whisper-base folder found in
$GCS_VOICE_SHARED, ../shared or beside the checkout); which engine and model each language uses, and
what is skipped, is said with why.
Outputs go to the current directory (or ``--out``): ``demo-LANG.tlog``, ``.jsonl`` and ``.png``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

DEFAULT_SPEEDUP = 1.0
DEFAULT_ROOM = "living_room"


def _speedup(text: str) -> float:
    """A positive number, or 'max' (infinity: the simulator is not paced), as ``gcs-sim --speedup`` takes."""
    import math

    if text.strip().lower() == "max":
        return math.inf
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: a positive number or 'max'")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lang", choices=("en", "es", "all"), default="all",
                        help="which sequence(s) to fly (default all: every language an engine is available for)")
    parser.add_argument("--engine", help="recogniser for every language (default: the best available per language)")
    parser.add_argument("--model", help="model path for Spanish (e.g. a faster-whisper model folder), or for every "
                                        "language with --engine; English otherwise stays on PocketSphinx")
    parser.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot",
                        help="personality of the bundled simulator (default ardupilot)")
    parser.add_argument("--room", default=DEFAULT_ROOM, help=f"simulator room (default {DEFAULT_ROOM})")
    parser.add_argument("--speedup", type=_speedup, default=DEFAULT_SPEEDUP, metavar="N|max",
                        help=f"simulated seconds per wall second (default {DEFAULT_SPEEDUP:g}); 'max' runs the "
                             "simulator as fast as the CPU allows, as gcs-sim --speedup max (speech and setpoints "
                             "keep wall time, so each action then lasts far longer in the simulator)")
    parser.add_argument("--out", type=Path, default=Path("."), metavar="DIR",
                        help="where the .tlog, .jsonl and .png go (default: current directory)")
    parser.add_argument("--json", action="store_true", help="print every event as a JSON line")


def run(args: argparse.Namespace) -> int:
    from gcs_voice.session.demo import run_demo

    return run_demo(langs=("en", "es") if args.lang == "all" else (args.lang,), engine=args.engine,
                    model=args.model, autopilot=args.autopilot, room=args.room, speedup=args.speedup,
                    out_dir=args.out, as_json=args.json)
