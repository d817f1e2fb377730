"""``gcs-voice recognize``: recognise command words in WAV files (or stdin PCM) and print the decisions.

One line per file (or per utterance with ``--segment``): what was heard, the matched phrase, the
action class or "none" with the reason, the score and the milliseconds spent; ``--json`` prints one
JSON object per line instead. The model is loaded once per run; all inputs are read first, so a
missing or bad file fails before the (slow) model load.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

__all__ = ["add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("files", nargs="+", metavar="FILE",
                        help="WAV file(s) (any rate/channels); '-' reads raw 16 kHz mono s16le PCM from stdin")
    parser.add_argument("--lang", default="en",
                        help="language code of a bundled dictionary (en, es, ...) or 'auto' to pick it per "
                             "utterance (default: en)")
    parser.add_argument("--engine", default=None,
                        help="recogniser: vosk, whisper or sphinx (default: vosk if a model for the language is found, else sphinx "
                             "for English, whisper if a Whisper model is known)")
    parser.add_argument("--model", default=None, metavar="PATH",
                        help="model folder (Vosk, faster-whisper or PocketSphinx) or a Whisper size name")
    parser.add_argument("--mode", choices=("grammar", "free", "score"), default=None,
                        help="grammar: only dictionary words (plus unknown); free: open vocabulary; score (whisper): "
                             "every dictionary phrase scored by the decoder (default: the engine's best on the "
                             "benchmark: score for whisper, grammar for the others)")
    parser.add_argument("--matcher", default=None, help="matcher name (default: the project default)")
    parser.add_argument("--dictionary", action="append", default=None, metavar="TOML",
                        help="use this dictionary file instead of the bundled one (repeatable)")
    parser.add_argument("--segment", action="store_true",
                        help="split each input into utterances at pauses (one line per utterance)")
    parser.add_argument("--vad", choices=("silero", "energy"), default=None,
                        help="with --segment: the segmenter (default: gcs_voice/audio/vad.toml's, silero)")
    parser.add_argument("--vad-settings", default=None, metavar="TOML",
                        help="with --segment: a segmenter settings file of your own, in the form of "
                             "gcs_voice/audio/vad.toml (for a room that needs other pauses or thresholds)")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")


def _engine_for(args: argparse.Namespace) -> str:
    """--engine, else the kind of folder --model points to, else the language's default."""
    from gcs_voice.asr.registry import default_engine

    if args.engine:
        return args.engine
    if args.model:
        path = Path(args.model).expanduser()
        if (path / "model.bin").is_file():
            return "whisper"
        if (path / "am" / "final.mdl").is_file() or (path / "final.mdl").is_file():
            return "vosk"
        if (path / "en-us").is_dir():
            return "sphinx"
        if not path.exists() and "/" not in args.model:
            return "whisper"  # a size name such as "base"
    return default_engine(args.lang)


def _dictionaries(args: argparse.Namespace):
    from gcs_voice.domain.dictionary import AUTO_LANGUAGES, load_dictionary, load_language

    if args.dictionary:
        return [load_dictionary(p) for p in args.dictionary]
    if args.lang == "auto":
        return [load_language(code) for code in AUTO_LANGUAGES]
    return [load_language(args.lang)]


def _read_inputs(files: list[str]) -> list[tuple[str, bytes]]:
    from gcs_voice.audio.sources import read_pcm, read_wav
    from gcs_voice.errors import AudioError

    if files.count("-") > 1:
        raise AudioError("stdin ('-') can be read only once")
    return [(name, read_pcm() if name == "-" else read_wav(name)) for name in files]


def _format_line(row: dict) -> str:
    action = row["action"] or "none"
    phrase = f"'{row['phrase']}'" if row["phrase"] else "-"
    where = f" [{row['start_s']:.2f}-{row['end_s']:.2f} s]" if "start_s" in row else ""
    if row.get("snr_db") is not None:
        where += f" (voice {row['snr_db']:.0f} dB over the room)"
    reason = f" ({row['reason']})" if row["reason"] and not row["action"] else ""
    heard = row.get("transcript") or row["text"]  # what the engine wrote, not the phrase it scored best
    return (f"{row['file']}{where}: heard '{heard}' -> {phrase} -> {action}{reason} "
            f"score {row['score']:.2f} lang {row['lang'] or '-'} {row['ms']:.0f} ms")


def _vad_settings(args: argparse.Namespace):
    """The segmenter's settings: vad.toml, or --vad-settings; a missing or malformed file is one line."""
    import tomllib

    from gcs_voice.audio.vad import VAD_SETTINGS_PATH, load_vad_settings
    from gcs_voice.errors import AudioError

    path = Path(args.vad_settings) if args.vad_settings else VAD_SETTINGS_PATH
    try:
        return load_vad_settings(path, method=args.vad)
    except OSError as exc:
        raise AudioError(f"cannot read the segmenter settings {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, TypeError, ValueError) as exc:
        raise AudioError(f"the segmenter settings {path} are not valid: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.audio.sources import pcm_to_chunks
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
    from gcs_voice.audio.vad import load_vad_settings, segment_utterances

    inputs = _read_inputs(args.files)
    vad = _vad_settings(args) if args.segment else None
    dictionaries = _dictionaries(args)
    matcher = get_matcher(args.matcher or DEFAULT_MATCHER)
    engine = _engine_for(args)
    recognizer = load_recognizer(engine, dictionaries, model=args.model, mode=args.mode)
    stream_lang = None if args.lang == "auto" or args.dictionary else args.lang

    for name, pcm in inputs:
        pieces = ([(u.pcm, u.start_s, u.end_s, u.snr_db) for u in segment_utterances(pcm_to_chunks(pcm), vad)]
                  if args.segment else [(pcm, None, None, None)])
        for piece, start_s, end_s, snr_db in pieces:
            started = time.perf_counter()
            stream = recognizer.start_stream(stream_lang)
            stream.accept(piece)
            recognition = stream.finish()
            decision = matcher.decide(recognition, dictionaries)
            ms = (time.perf_counter() - started) * 1000.0
            row = {
                "file": name, "lang": decision.lang or recognition.lang, "text": recognition.text,
                "phrase": decision.phrase, "action": decision.action, "score": round(decision.score, 4),
                "amount": decision.amount.label if decision.amount else None,
                "reason": decision.reason, "went_on": decision.went_on, "ms": round(ms, 1), "engine": recognition.engine,
                "matcher": decision.matcher,
                "alternatives": [h.text for h in recognition.hypotheses],
                "extra": {k: round(v, 4) for k, v in recognition.extra.items()},
            }
            if recognition.transcript:
                row["transcript"] = recognition.transcript
            if start_s is not None:
                row.update(start_s=round(start_s, 3), end_s=round(end_s, 3), snr_db=snr_db)
            print(json.dumps(row, ensure_ascii=False) if args.json else _format_line(row), flush=True)
    return 0
