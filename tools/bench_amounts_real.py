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
numbers, beside the synthetic table of ``tools.bench_amounts``.

    python -m tools.bench_amounts_real --out docs/bench/amounts_real.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
from tools.bench_amounts import outcome
from tools.bench_real import pct, recognise_one
from tools.make_corpus import mix_at_snr, read_wav
from tools.real_speech import SHARED, load_recordings

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "bench" / "amounts_real.md"
RATE = 16_000
DIGITS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9}
MOTIONS = ("up", "down", "go_forward", "go_back", "go_left", "go_right")
GAP_S = 0.15
NOISE = "doing_the_dishes"


def voiced(x: np.ndarray, pad_s: float = 0.05) -> np.ndarray:
    """The part of a 1 s clip where the speech is: 20 ms frames within 30 dB of the loudest, padded."""
    frame = RATE // 50
    n = x.size // frame
    if n == 0:
        return x
    energy = 10 * np.log10(np.mean(x[:n * frame].reshape(n, frame) ** 2, axis=1) + 1e-12)
    loud = np.flatnonzero(energy > energy.max() - 30.0)
    start = max(0, loud[0] * frame - int(pad_s * RATE))
    end = min(x.size, (loud[-1] + 1) * frame + int(pad_s * RATE))
    return x[start:end]


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
    parser = argparse.ArgumentParser(prog="python -m tools.bench_amounts_real", description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    parser.add_argument("--split", choices=("dev", "test"), default="test")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=DOC)
    args = parser.parse_args(argv)
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
            pad = np.zeros(int(0.3 * RATE), np.float32)
            speech = np.concatenate([pad, voiced(read_wav(command)), np.zeros(int(GAP_S * RATE), np.float32),
                                     voiced(read_wav(digit)), pad])
            audio = speech
            if condition != "clean":
                start = (i * 7919) % max(1, noise.size - speech.size)
                audio = mix_at_snr(speech, slice(pad.size, speech.size - pad.size), noise[start:start + speech.size],
                                   12.0)
            result, _seconds = recognise_one(recognizer, audio, "en")
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
             f"Generated by `python -m tools.bench_amounts_real --split {args.split} --seed {args.seed}`. Corpus: the "
             f"real recordings of ../shared/speech, {args.split} speakers (`python -m tools.real_speech`): every "
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


if __name__ == "__main__":
    sys.exit(main())
