"""``gcs-voice`` entry point: parses flags and hands over to one command module; no logic here.

``gcs-voice [fly flags]`` flies (the default command); ``gcs-voice recognize|demo|plot|download ...`` run the
other commands. User mistakes (GcsVoiceError, and flags argparse refuses) end in one line on stderr and
exit status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from gcs_voice.errors import GcsVoiceError

#: sub-command -> (module under gcs_voice.cli, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "fly": ("fly", "connect to a vehicle and fly it by voice (the default command)"),
    "recognize": ("recognize", "recognise command words in WAV files (or stdin PCM) and print the decisions"),
    "demo": ("demo", "start the bundled simulator and fly a scripted spoken sequence"),
    "plot": ("plot", "draw a flight from a .tlog as a PNG"),
    "download": ("download", "fetch a speech model once (recognising never downloads)"),
}
DEFAULT_COMMAND = "fly"


class _Parser(argparse.ArgumentParser):
    """argparse, but a refused flag is one line (the usage is one ``--help`` away), like every other mistake."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _load(name: str):
    module_name, _ = COMMANDS[name]
    return importlib.import_module(f"gcs_voice.cli.{module_name}")


def build_parser(command: str) -> argparse.ArgumentParser:
    prog = "gcs-voice" if command == DEFAULT_COMMAND else f"gcs-voice {command}"
    others = ", ".join(c for c in COMMANDS if c != DEFAULT_COMMAND)
    parser = _Parser(
        prog=prog,
        description=COMMANDS[command][1],
        epilog=f"other commands: {others} (gcs-voice COMMAND --help)" if command == DEFAULT_COMMAND else None,
    )
    _load(command).add_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = argv[0] if argv and argv[0] in COMMANDS else DEFAULT_COMMAND
    if argv and argv[0] == command:
        argv = argv[1:]
    parser = build_parser(command)
    args = parser.parse_args(argv)
    try:
        return int(_load(command).run(args) or 0)
    except GcsVoiceError as exc:
        print(f"gcs-voice: error: {exc}", file=sys.stderr)
        return 2  # = gcs_voice.session.run.USER_ERROR_EXIT, what the session log records
    except KeyboardInterrupt as exc:  # (SIGTERM / SIGHUP during a session come as one too, with .signum)
        print("gcs-voice: interrupted", file=sys.stderr)
        return 128 + int(getattr(exc, "signum", 2))


