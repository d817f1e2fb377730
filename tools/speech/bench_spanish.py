"""Spanish on synthetic speech, and the Spanish thresholds chosen on it (no real Spanish recordings are here).

Every phrase of dictionaries/es.toml and every ``[es] passing``, ``ood`` and ``near`` sentence of
tools/speech/corpus_sentences.toml is spoken by espeak-ng in six voices (Spain and Latin America, seseo included, male and
female variants, 120 to 200 words per minute, pitch 35 to 70: :data:`VOICES`), clean and with one of the real noises
of ../shared/noise at 12 dB (the noise fixed per utterance), and decided by the default pipeline for Spanish (Whisper
base in scoring mode + the phonetic matcher). Three voices are ``dev`` (the thresholds are chosen on them), three
``test`` (reported, never chosen on), as speakers are split for the real English recordings.

    python -m tools.speech.bench_spanish recognise         # cache the recognitions: out/bench/spanish/whisper-score.jsonl
    python -m tools.speech.bench_spanish tune [--write]    # choose [evidence.whisper-score.lang.es] on dev
    python -m tools.speech.bench_spanish report            # docs/bench/spanish.md from the cache
    python -m tools.speech.bench_spanish                   # recognise (what is missing), then report

``tune`` sweeps the Spanish margin, class gap and how near each heard word must sound to a word of the winning
class (``word_max_distance``: "bebe a casa" for "vete a casa" is near enough "baje" at 0.5): on dev Spanish (clean and 12 dB) other speech acted on must stay
within half its 1 % target and wrong actions at 0, there and one grid step looser in either threshold; the same
values, applied to the real English dev speakers (tools.speech.bench_real's cache: the decision's shape on real speech,
which synthetic speech lacks), must keep the English clean limits too. Among those, the best "right - 3 x wrong -
2 x other speech acted on" on dev Spanish wins. Synthetic speech is a regression check and a choice of thresholds,
not a measure of real speakers: real Spanish commands have not been measured here.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
import tempfile
import tomllib
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import Recognition
from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
from gcs_voice.understanding.thresholds import THRESHOLDS_PATH, load_thresholds
from tools.speech import real_cache, real_tune
from tools.speech.real_cache import Counts, _recognition, pct, recognise_one
from tools.speech.real_tune import _with_thresholds
from tools.speech.make_corpus import SENTENCES_PATH, synthesise
from tools.speech.real_speech import SHARED, load_recordings, mix, read_wav

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "bench" / "spanish.md"
CACHE = REPO / "out" / "bench" / "spanish" / "whisper-score.jsonl"
#: (espeak-ng voice, words per minute, pitch, split): Spain (distinción) and Latin America (seseo), three each
VOICES = (("es", 130, 50, "dev"), ("es-419", 170, 50, "dev"), ("es+f3", 150, 70, "dev"),
          ("es", 185, 35, "test"), ("es-419+m3", 120, 40, "test"), ("es-419+f2", 200, 60, "test"))
NOISES = ("doing_the_dishes", "running_tap", "exercise_bike", "dude_miaowing")
SNR_DB = 12.0
CONDITIONS = ("clean", "noise12")
SENTENCE_KINDS = ("passing", "ood", "near")
#: the Spanish thresholds chosen here: the key's table in thresholds.toml, and its candidate values
TABLES = {"min_margin": "evidence.whisper-score.lang.es", "min_class_gap": "evidence.whisper-score.lang.es",
          "word_max_distance": "transcript.whisper-score.lang.es"}
GRID = {"min_margin": [round(x / 10, 1) for x in range(-20, 1, 2)],
        "min_class_gap": [0.0, 0.4, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0],
        "word_max_distance": [0.4, 0.45, 0.5]}
#: Spanish targets (issue 31): other speech acted on <= 1 %, no wrong action; dev holds half the first
ACTED_LIMIT, DEV_SAFETY = 0.01, 0.5


@dataclass(frozen=True)
class Item:
    """One synthetic utterance: what was said, what it means (None: other speech), and how it was spoken."""

    text: str
    action: str | None
    kind: str
    voice: str
    wpm: int
    pitch: int
    split: str
    condition: str

    @property
    def key(self) -> str:
        return f"{self.kind}|{self.text}|{self.voice}|{self.wpm}|{self.pitch}|{self.condition}"


def items() -> list[Item]:
    es = load_language("es")
    sentences = tomllib.loads(SENTENCES_PATH.read_text(encoding="utf-8"))["es"]
    said = [(p.text, p.action, "command") for p in es.phrases]
    said += [(text, None, kind) for kind in SENTENCE_KINDS for text in sentences.get(kind, [])]
    return [Item(text, action, kind, voice, wpm, pitch, split, cond)
            for voice, wpm, pitch, split in VOICES for cond in CONDITIONS for text, action, kind in said]


_NOISE: dict[str, np.ndarray] = {}


def audio(item: Item) -> np.ndarray:
    """The utterance, with 0.3 s of silence either side; under noise, one of :data:`NOISES` fixed by its key."""
    speech = synthesise(item.text, item.voice, item.wpm, item.pitch)
    pad = np.zeros(4800, np.float32)
    speech = np.concatenate([pad, speech, pad])
    if item.condition == "clean":
        return speech
    noise = NOISES[zlib.crc32(item.key.encode()) % len(NOISES)]
    if noise not in _NOISE:
        _NOISE[noise] = read_wav(SHARED / "noise" / f"{noise}.wav")
    return mix(speech, _NOISE[noise], SNR_DB, item.key)


def _config(model: str) -> str:
    """The model and the dictionary it scores: a cached recognition of another one is made again."""
    return hashlib.sha1((real_cache.model_identity(model) + load_language("es").path.read_text(encoding="utf-8"))
                        .encode()).hexdigest()[:12]


def load_cache() -> dict[str, dict]:
    out: dict[str, dict] = {}
    if CACHE.is_file():
        for line in CACHE.read_text(encoding="utf-8").splitlines():
            if line.strip():
                row = json.loads(line)
                out[row["key"]] = row
    return out


def recognise(model: str) -> None:
    from gcs_voice.asr.registry import load_recognizer

    config = _config(model)
    cache = {k: r for k, r in load_cache().items() if r.get("config") == config}
    todo = [item for item in items() if item.key not in cache]
    print(f"bench_spanish: {len(todo)} recognitions to do", file=sys.stderr)
    if not todo:
        return
    recognizer = load_recognizer("whisper", [load_language("es")], model=model, mode="score")
    CACHE.parent.mkdir(parents=True, exist_ok=True)
    with open(CACHE, "a", encoding="utf-8") as out:
        for i, item in enumerate(todo):
            result, dt = recognise_one(recognizer, audio(item), "es")
            row = {"key": item.key, "config": config, "engine": result.engine, "lang": result.lang,
                   "hypotheses": [[h.text, h.confidence, h.score] for h in result.hypotheses],
                   "extra": dict(result.extra), "transcript": result.transcript, "audio_s": result.audio_s,
                   "decision_s": dt}
            out.write(json.dumps(row) + "\n")
            out.flush()
            if i % 100 == 0:
                print(f"  {i}/{len(todo)} {item.key}", file=sys.stderr)


def count(selected: list[Item], cache: dict[str, dict], matcher, missed: list | None = None) -> Counts:
    """Decisions on the items: commands right / wrong / none; sentences (all kinds) acted on."""
    es = [load_language("es")]
    c = Counts()
    for item in selected:
        row = cache.get(item.key)
        if row is None:
            continue
        recognition: Recognition = _recognition(row)
        decision = matcher.decide(recognition, es)
        c.add("command" if item.action else "sentence", item.action, decision.action)
        if missed is not None and decision.action != item.action:
            missed.append((item, recognition, decision))
    return c


def _objective(c: Counts) -> int:
    return c.right - real_tune.WRONG_COST * c.wrong - real_tune.ACTED_COST * c.sentences_acted


def _fits(c: Counts) -> bool:
    return c.wrong == 0 and c.sentences_acted <= ACTED_LIMIT * DEV_SAFETY * c.sentences


def with_values(values: dict[str, float], directory: Path, name: str) -> Path:
    """A copy of thresholds.toml with each value of :data:`GRID`'s keys in its table (:data:`TABLES`)."""
    path = None
    for table in dict.fromkeys(TABLES.values()):
        mine = {k: v for k, v in values.items() if TABLES[k] == table}
        path = _with_thresholds(table, mine, directory, name, source=path)
    assert path is not None
    return path


def tune(write: bool) -> int:
    cache = load_cache()
    dev = [i for i in items() if i.split == "dev"]
    english = real_cache.load_cache("whisper-score")
    en_dev = load_recordings(split="dev")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n, combo in enumerate(itertools.product(*GRID.values())):
            values = dict(zip(GRID, combo))
            matcher = get_matcher(DEFAULT_MATCHER, thresholds_path=with_values(values, Path(tmp), str(n)))
            c = count(dev, cache, matcher)
            rows.append((values, _fits(c), _objective(c), c))
        ok_at = {tuple(r[0].values()): r[1] for r in rows}

        def looser(values: dict[str, float]) -> list[tuple]:
            out = []
            for k, key in enumerate(GRID):
                i = GRID[key].index(values[key])
                step = i + 1 if key == "word_max_distance" else i - 1  # a larger word distance is looser
                if 0 <= step < len(GRID[key]):
                    combo = list(values.values())
                    combo[k] = GRID[key][step]
                    out.append(tuple(combo))
            return out

        feasible = sorted((r for r in rows if r[1] and all(ok_at[x] for x in looser(r[0]))),
                          key=lambda r: (r[2], r[0]["min_margin"], r[0]["min_class_gap"], -r[0]["word_max_distance"]),
                          reverse=True)
        print(f"dev voices, clean and {SNR_DB:g} dB; limits: no wrong action, other speech acted on <= "
              f"{100 * ACTED_LIMIT * DEV_SAFETY:g} %, also one grid step looser in any key; objective = right - "
              f"{real_tune.WRONG_COST} x wrong - {real_tune.ACTED_COST} x other speech acted on")
        chosen = None
        for values, _, score, c in feasible:
            # the margin and the class gap on real English speakers: the decision's shape on real speech
            en_values = {k: v for k, v in values.items() if k != "word_max_distance"}
            path = _with_thresholds("evidence.whisper-score", en_values, Path(tmp), "en")
            matcher = get_matcher(DEFAULT_MATCHER, thresholds_path=path)
            en_ok = all(real_tune.within_targets(real_cache.count(en_dev, cond, english, matcher), "clean",
                                                 real_tune.DEV_SAFETY) for cond in ("clean", "kitchen20"))
            print(f"  {values}  objective {score}: {c.right}/{c.commands} right, {c.wrong} wrong, "
                  f"{c.sentences_acted}/{c.sentences} other speech acted on; real English dev within its limits: "
                  f"{'yes' if en_ok else 'no'}")
            if en_ok:
                chosen = values
                break
    shipped = load_thresholds()
    now_values = {}
    for key, table in TABLES.items():
        level = shipped
        for part in table.split("."):
            level = level.get(part, {})
        now_values[key] = level.get(key)
    now = next((r for r in rows if r[0] == now_values), None)
    if now is not None:
        c = now[3]
        print(f"shipped now: {now[0]}  objective {now[2]}: {c.right}/{c.commands} right, {c.wrong} wrong, "
              f"{c.sentences_acted}/{c.sentences} other speech acted on")
    if chosen is None:
        print("no setting meets the limits on dev", file=sys.stderr)
        return 1
    print("chosen: " + ", ".join(f"[{TABLES[k]}] {k} = {v}" for k, v in chosen.items()))
    if write:
        out = with_values(chosen, CACHE.parent, "chosen")
        THRESHOLDS_PATH.write_text(out.read_text(encoding="utf-8"), encoding="utf-8")
        print(f"written to {THRESHOLDS_PATH.relative_to(REPO)}")
    return 0


def report() -> str:
    cache = load_cache()
    matcher = get_matcher(DEFAULT_MATCHER)
    every = items()
    lines = ["# Spanish on synthetic speech", "",
             "Generated by `python -m tools.speech.bench_spanish report` from the cache of `python -m tools.speech.bench_spanish "
             "recognise`. espeak-ng voices (voice, words per minute, pitch): "
             + "; ".join(f"{v} {w} {p} ({s})" for v, w, p, s in VOICES)
             + f". Noise: one of {', '.join(NOISES)} (../shared/noise) at {SNR_DB:g} dB, fixed per utterance. Whisper "
             "base, scoring mode, phonetic matcher, thresholds.toml as shipped (Spanish: chosen on the dev voices by "
             "`python -m tools.speech.bench_spanish tune`).", "",
             "**There are no real Spanish recordings here: these figures are synthetic speech, a regression check "
             "and what the Spanish thresholds were chosen on. Real Spanish commands have not been measured here**; "
             "the check on real Spanish speakers comes from outside.", "",
             "| split | condition | commands right | wrong | no action | other speech acted on |",
             "| --- | --- | --- | --- | --- | --- |"]
    missed: list = []
    for split in ("dev", "test"):
        for cond in CONDITIONS:
            chosen = [i for i in every if i.split == split and i.condition == cond]
            c = count(chosen, cache, matcher, missed if split == "test" else None)
            lines.append(f"| {split} | {cond} | {pct(c.right, c.commands)} | {pct(c.wrong, c.commands)} | "
                         f"{pct(c.commands - c.right - c.wrong, c.commands)} | "
                         f"{pct(c.sentences_acted, c.sentences)} |")
    lines += ["", "Other speech: the `passing` (a command word in passing), `ood` and `near` sentences of "
              "tools/speech/corpus_sentences.toml.", ""]
    # what the weak-match guard costs here: the same decisions without it (min_shared 0)
    with tempfile.TemporaryDirectory() as tmp:
        unguarded = get_matcher(DEFAULT_MATCHER, thresholds_path=_with_thresholds(
            "transcript.whisper-score", {"min_shared": 0.0}, Path(tmp), "unguarded"))
        lines += ["Without the weak-match guard (`min_shared` 0 instead of as shipped), the same utterances:", "",
                  "| split | condition | commands right | wrong | other speech acted on |", "| --- | --- | --- | --- | --- |"]
        for split in ("dev", "test"):
            for cond in CONDITIONS:
                c = count([i for i in every if i.split == split and i.condition == cond], cache, unguarded)
                lines.append(f"| {split} | {cond} | {pct(c.right, c.commands)} | {pct(c.wrong, c.commands)} | "
                             f"{pct(c.sentences_acted, c.sentences)} |")
    lines.append("")
    acted = [(i, d) for i, _, d in missed if i.action is None]
    wrong = [(i, r, d) for i, r, d in missed if i.action and d.action]
    if wrong or acted:
        lines += ["Acted on wrongly (test): " + "; ".join(
            f"'{i.text}' ({i.voice} {i.wpm} wpm, {i.condition}) heard '{r.transcript}' -> {d.action}"
            for i, r, d in wrong) + "; ".join(f"'{i.text}' ({i.voice}, {i.condition}) -> {d.action}" for i, d in acted),
            ""]
    # What Whisper writes for each command word it did not act on (test): the hard sounds
    heard: dict[str, Counter] = {}
    for item, recognition, decision in missed:
        if item.action and decision.action is None:
            heard.setdefault(item.text, Counter())[recognition.transcript or "(nothing)"] += 1
    if heard:
        lines += ["Commands not acted on (test split), with what Whisper wrote for them (times):", "",
                  "| said | not acted on | Whisper wrote |", "| --- | --- | --- |"]
        for text, seen in sorted(heard.items(), key=lambda kv: -sum(kv[1].values())):
            lines.append(f"| {text} | {sum(seen.values())} | "
                         + ", ".join(f"{t!r} ({n})" for t, n in seen.most_common(4)) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.bench_spanish", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="stage")
    rec = sub.add_parser("recognise", help="recognise every synthetic utterance (cached)")
    rec.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    tun = sub.add_parser("tune", help="choose the Spanish thresholds on the dev voices")
    tun.add_argument("--write", action="store_true", help="write them into thresholds.toml")
    rep = sub.add_parser("report", help="write docs/bench/spanish.md from the cache")
    rep.add_argument("--out", type=Path, default=DOC)
    args = parser.parse_args(argv)
    if args.stage in ("recognise", None):  # with no stage: recognise what is missing, then report
        recognise(getattr(args, "model", str(SHARED / "models" / "faster-whisper-base")))
        if args.stage == "recognise":
            return 0
    if not CACHE.is_file():
        print(f"bench_spanish: error: no recognitions in {CACHE.relative_to(REPO)} "
              "(run `python -m tools.speech.bench_spanish recognise` first)", file=sys.stderr)
        return 2
    if args.stage == "tune":
        return tune(args.write)
    from tools.report import header

    text = header("tools.speech.bench_spanish", argv) + report()
    out = getattr(args, "out", DOC)
    out.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
