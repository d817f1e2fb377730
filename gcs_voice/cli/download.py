"""``gcs-voice download vosk --lang LANG [--dir DIR] [--url URL]`` / ``gcs-voice download whisper --size S``.

Recognising never downloads (a session must not stall on a network fetch); this does, once: a Vosk
model from the same server and into the same folder the vosk package uses, a Whisper model through
faster-whisper into the Hugging Face cache, so either is then found by language or size.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("engine", choices=["vosk", "whisper"], help="whose model to fetch")
    parser.add_argument("--lang", help="vosk: language code of the model, e.g. en, es")
    parser.add_argument("--size", default="base", help="whisper: model size (default: base; e.g. small)")
    parser.add_argument("--dir", metavar="DIR",
                        help="vosk: where to put it (default: $VOSK_MODEL_PATH, else ~/.cache/vosk, where it is "
                             "looked for)")
    parser.add_argument("--url", metavar="URL",
                        help="vosk: server with model-list.json and the zips (default: $GCS_VOICE_VOSK_URL, else "
                             "https://alphacephei.com/vosk/models)")


def run(args: argparse.Namespace) -> int:
    from gcs_voice.asr.download import download_vosk_model, download_whisper_model
    from gcs_voice.errors import ModelError

    if args.engine == "whisper":
        print(download_whisper_model(args.size))
        return 0
    if not args.lang:
        raise ModelError("gcs-voice download vosk needs --lang (e.g. --lang es)")
    print(download_vosk_model(args.lang, args.dir, args.url))
    return 0
