"""Amounts on real voices, roughly (issue 33): a real command word followed by a real spoken digit.

There are no real recordings of "go forward three metres" here. ../shared/speech has real single command
words ("forward", "left", "up", ...) and real digits ("one" ... "nine") from hundreds of speakers, so this
splices them: each real command recording of a motion with a word of its own (up, down, go_*: the turns and
stop have none, and a stop takes no amount) is cut to its voiced part and followed, 0.15 s later, by a real
digit said by another speaker of the same split (seeded), as "forward three": with no unit word an amount
is metres. Each is decided by Whisper base in scoring mode and the shipped matcher, clean and over the real
kitchen noise at 12 dB, and counted as right (class and amount), wrong class, wrong amount (the class right
but another amount, or none: an open-ended motion for a bounded one) or no action.

Two speakers in one utterance, with a cut between them, is not how people speak: a rough real check of the
numbers, beside the synthetic table of ``tools.speech.bench_amounts``.

    python -m tools.speech.bench_amounts_real --out docs/bench/amounts_real.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
from tools.speech.bench_amounts import outcome
from tools.speech.real_cache import pct, recognise_one
from tools.speech.make_corpus import mix_at_snr, read_wav
from tools.speech.real_speech import SHARED, load_recordings

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "bench" / "amounts_real.md"
RATE = 16_000
DIGITS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9}
MOTIONS = ("up", "down", "go_forward", "go_back", "go_left", "go_right")
GAP_S = 0.15
NOISE = "doing_the_dishes"


def voiced(x: np.ndarray, pad_s: float = 0.05) -> np.ndarray:
    """The part of a 1 s clip where the speech is: 20 ms frames within 30 dB of the loudest, padded."""
    return x[voiced_slice(x, pad_s)]


def voiced_slice(x: np.ndarray, pad_s: float = 0.05) -> slice:
    """Where :func:`voiced` cuts ``x``."""
    frame = RATE // 50
    n = x.size // frame
    if n == 0:
        return slice(0, x.size)
    energy = 10 * np.log10(np.mean(x[:n * frame].reshape(n, frame) ** 2, axis=1) + 1e-12)
    loud = np.flatnonzero(energy > energy.max() - 30.0)
    return slice(max(0, loud[0] * frame - int(pad_s * RATE)), min(x.size, (loud[-1] + 1) * frame + int(pad_s * RATE)))


def spliced(command: Path, digit: Path, noise: np.ndarray, i: int, condition: str) -> np.ndarray:
    """The command's voiced part, ``GAP_S`` of silence, the digit's voiced part, 0.3 s of silence around them;
    over the kitchen recording at 12 dB (from a place set by ``i``) unless ``condition`` is clean."""
    pad = np.zeros(int(0.3 * RATE), np.float32)
    speech = np.concatenate([pad, voiced(read_wav(command)), np.zeros(int(GAP_S * RATE), np.float32),
                             voiced(read_wav(digit)), pad])
    if condition == "clean":
        return speech
    start = (i * 7919) % max(1, noise.size - speech.size)
    return mix_at_snr(speech, slice(pad.size, speech.size - pad.size), noise[start:start + speech.size], 12.0)


def plan(split: str, seed: int) -> list[tuple[Path, Path, str, int]]:
    """(command file, digit file, action, value): every real motion command of the split, one digit each."""
    recordings = load_recordings(split=split)
    digits = [r for r in recordings if r.kind == "word" and r.word in DIGITS]
    rng = np.random.default_rng(seed)
    items = []
    for rec in recordings:
        if rec.kind != "command" or rec.action not in MOTIONS:
            continue
        others = [d for d in digits if d.speaker != rec.speaker]
        digit = others[int(rng.integers(len(others)))]
        items.append((rec.path, digit.path, rec.action, DIGITS[digit.word]))
    return items


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.bench_amounts_real", description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    parser.add_argument("--split", choices=("dev", "test"), default="test")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=DOC)
    parser.add_argument("--after", default="",
                        help="values of max_speech_after_s to compare (comma-separated, 'none' for no limit): each "
                             "spliced item and each plain command of the split decided again under each (a sweep, "
                             "to choose the limit on --split dev; the report then has that table only)")
    args = parser.parse_args(argv)
    if args.after:
        return sweep_after(args)
    from gcs_voice.asr.registry import load_recognizer

    dictionary = load_language("en")
    recognizer = load_recognizer("whisper", [dictionary], model=args.model, mode="score")
    matcher = get_matcher(DEFAULT_MATCHER)
    noise = read_wav(SHARED / "noise" / f"{NOISE}.wav")
    items = plan(args.split, args.seed)
    rows, wrongs = [], []
    for condition in ("clean", "kitchen 12 dB"):
        counts = {"right": 0, "wrong class": 0, "wrong amount": 0, "no action": 0}
        for i, (command, digit, action, value) in enumerate(items):
            result, _seconds = recognise_one(recognizer, spliced(command, digit, noise, i, condition), "en")
            d = matcher.decide(result, [dictionary])
            kind = outcome(d, action, value, "m", False)
            counts[kind] += 1
            said = f"{command.name} + {digit.name} ({action} {value} m)"
            if kind in ("wrong class", "wrong amount"):
                wrongs.append(f"| {said} | {condition} | {d.label} | {result.transcript} |")
            print(f"{condition}: {said} -> {d.label or 'no action'} ({kind}; heard {result.transcript!r})", flush=True)
        n = len(items)
        rows.append(f"| {condition} | {n} | {pct(counts['right'], n)} | {pct(counts['wrong class'], n)} "
                    f"| {pct(counts['wrong amount'], n)} | {pct(counts['no action'], n)} |")
    lines = ["# Amounts on real voices, spliced", "",
             f"Generated by `python -m tools.speech.bench_amounts_real --split {args.split} --seed {args.seed}`. Corpus: the "
             f"real recordings of ../shared/speech, {args.split} speakers (`python -m tools.speech.real_speech`): every "
             "command of a motion said as one word (up, down, forward, back/backward, left, right), cut to its voiced "
             f"part and followed {GAP_S:g} s later by a real digit (one to nine) said by another speaker of the same "
             "split, as \"forward three\" (no unit word: metres). Clean, and over the real kitchen recording of "
             "../shared/noise at 12 dB. Whisper base, scoring mode, the shipped matcher and thresholds. Wrong amount "
             "= the class right but another amount or none. Two speakers spliced is not how people speak: a rough "
             "real check of the numbers beside the synthetic table (amounts.md).", "",
             "| condition | n | right | wrong class | wrong amount | no action |",
             "| --- | --- | --- | --- | --- | --- |", *rows, ""]
    if wrongs:
        lines += ["Acted on wrongly:", "", "| said (files) | condition | done | Whisper heard |", "| --- | --- | --- | --- |",
                  *wrongs, ""]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))
    return 0


def sweep_after(args: argparse.Namespace) -> int:
    """Each spliced amount and each plain real command of the split, clean and at kitchen 12 dB, recognised
    once and decided under each ``max_speech_after_s``: what the limit saves (digits lost, flown open-ended) and
    what it costs (plain commands no longer acted on)."""
    import tempfile

    from gcs_voice.asr.registry import load_recognizer
    from tools.speech.real_tune import _with_thresholds

    dictionary = load_language("en")
    recognizer = load_recognizer("whisper", [dictionary], model=args.model, mode="score")
    noise = read_wav(SHARED / "noise" / f"{NOISE}.wav")
    items = plan(args.split, args.seed)
    plain = [r for r in load_recordings(split=args.split) if r.kind == "command"]
    heard: dict[tuple[str, str], list] = {}
    for condition in ("clean", "kitchen 12 dB"):
        for i, (command, digit, action, value) in enumerate(items):
            result, _ = recognise_one(recognizer, spliced(command, digit, noise, i, condition), "en")
            heard.setdefault(("amount", condition), []).append((result, action, value))
        for i, rec in enumerate(plain):
            audio = read_wav(rec.path)
            if condition != "clean":  # over its voiced part, as the spliced ones
                part = voiced_slice(audio)
                start = (i * 7919) % max(1, noise.size - audio.size)
                audio = mix_at_snr(audio, part, noise[start:start + audio.size], 12.0)
            result, _ = recognise_one(recognizer, audio, "en")
            heard.setdefault(("plain", condition), []).append((result, rec.action, None))
        print(f"{condition}: recognised", flush=True)
    values = [None if v.strip() == "none" else float(v) for v in args.after.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n, limit in enumerate(values):
            path = _with_thresholds("transcript.whisper-score", {"max_speech_after_s": 1e9 if limit is None else limit},
                                    Path(tmp), str(n))
            matcher = get_matcher(DEFAULT_MATCHER, thresholds_path=path)
            cells = []
            for condition in ("clean", "kitchen 12 dB"):
                counts = {"right": 0, "wrong class": 0, "wrong amount": 0, "no action": 0}
                for result, action, value in heard[("amount", condition)]:
                    counts[outcome(matcher.decide(result, [dictionary]), action, value, "m", False)] += 1
                decided = [(matcher.decide(result, [dictionary]), action) for result, action, _ in heard[("plain", condition)]]
                right = sum(1 for d, action in decided if d.action == action)
                wrong = sum(1 for d, action in decided if d.action is not None and d.action != action)
                cells.append(f"{counts['right']} / {counts['wrong amount']} / {counts['wrong class']} | "
                             f"{right}/{len(decided)}, {wrong} wrong")
            rows.append(f"| {'none' if limit is None else f'{limit:g}'} | " + " | ".join(cells) + " |")
            print(rows[-1], flush=True)
    lines = ["# Speech after the words Whisper wrote: the limit on it", "",
             f"Generated by `python -m tools.speech.bench_amounts_real --split {args.split} --seed {args.seed} --after "
             f"{args.after}`. The {len(items)} spliced real \"command digit\" items of the {args.split} speakers (as in "
             f"amounts_real.md) and the split's {len(plain)} plain real commands (one word, no amount), clean and over "
             "the real kitchen recording at 12 dB, recognised once (Whisper base, scoring mode) and decided under each "
             "value of `[transcript.whisper-score] max_speech_after_s`: a motion that could take an amount is not "
             "flown when more than that much speech follows the words Whisper wrote. Spliced: right / wrong amount "
             "(nearly always the digit lost: flown open-ended) / wrong class. Plain: acted on right, and wrongly.", "",
             "| max_speech_after_s | clean: spliced right / wrong amount / wrong class | clean: plain commands right "
             "| kitchen 12 dB: spliced | kitchen 12 dB: plain |",
             "| --- | --- | --- | --- | --- |", *rows, ""]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
