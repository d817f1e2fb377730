"""The stop spotter in Spanish: which stop words it listens for, on synthetic Spanish (no real Spanish is here).

The stop spotter (PocketSphinx keyword search, gcs_voice/asr/stop_spotter.py) is the fast stop path: it stops the
vehicle before Whisper has decided. It hears only the words in ``stop_spotter.toml`` ``[es] words``, each spelt in
the English model's phones. This tool says, word by word, what each candidate word catches and what it fires on
that is no stop, over the synthetic Spanish of ``python -m tools.speech.bench_spanish`` (every phrase of
dictionaries/es.toml and the Spanish sentences of tools/speech/corpus_sentences.toml, six espeak-ng voices, clean and over
the real noises at 12 dB; three voices dev, three test):

- a *hit*: a stop phrase ("pare", "detener", "quédate quieto", ...) on which any word of the set fired;
- a *false alarm*: any other utterance (another command, or a sentence) on which a word of the set fired: a
  pause, since a false stop only holds the vehicle (the main decision follows).

As for English (``python -m tools.listen.bench_stop_spotter``), the spotter trades precision for never waiting; ``--sweep``
adds more lenient thresholds. Test voices are reported beside dev; nothing is chosen here on them.

    python -m tools.listen.bench_spotter_spanish --sweep 1e-20,1e-25,1e-30 --every 4 --out docs/bench/spotter_spanish.md
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

import numpy as np

from tools.speech import bench_spanish as bs
from tools.speech.real_cache import pct

REPO = Path(__file__).resolve().parents[2]
SETTINGS = REPO / "gcs_voice" / "asr" / "stop_spotter.toml"
CACHE = REPO / "out" / "bench" / "spotter_spanish.json"


def pcm(item: bs.Item) -> bytes:
    return (np.clip(bs.audio(item), -1, 32767 / 32768) * 32768).astype("<i2").tobytes()


def fires(words: list[str], items: list[bs.Item], threshold: float) -> dict[str, set[str]]:
    """For each word alone, the keys of the items it fires on at ``threshold`` (not over the bridge's voice).
    Cached in out/bench/spotter_spanish.json by threshold, word (with its phones) and item."""
    from gcs_voice.asr.stop_spotter import load_stop_spotter

    phones = tomllib.loads(SETTINGS.read_text(encoding="utf-8"))["es"]["phones"]
    cache = json.loads(CACHE.read_text(encoding="utf-8")) if CACHE.is_file() else {}
    slots = {w: cache.setdefault(f"{threshold:g}|{w}|{phones[w]}", {}) for w in words}
    todo = [i for i in items if any(i.key not in slots[w] for w in words)]
    spotters = {w: load_stop_spotter(["es"], words=[w], thresholds={"es": threshold}) for w in words} if todo else {}
    for n, item in enumerate(todo):
        audio = pcm(item)
        for w, spotter in spotters.items():
            slots[w][item.key] = spotter.spot(audio).word is not None
        if n % 200 == 0:
            print(f"  {threshold:g}: {n}/{len(todo)}", file=sys.stderr, flush=True)
            CACHE.parent.mkdir(parents=True, exist_ok=True)
            CACHE.write_text(json.dumps(cache), encoding="utf-8")
    if todo:
        CACHE.write_text(json.dumps(cache), encoding="utf-8")
    return {w: {i.key for i in items if slots[w].get(i.key)} for w in words}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.listen.bench_spotter_spanish", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the tables here (markdown) as well as to stdout")
    parser.add_argument("--sweep", default="", help="also these kws thresholds (comma-separated), on the stop phrases "
                        "and every --every'th other utterance")
    parser.add_argument("--every", type=int, default=4)
    args = parser.parse_args(argv)
    settings = tomllib.loads(SETTINGS.read_text(encoding="utf-8"))["es"]
    shipped = list(settings["words"])
    candidates = list(settings["phones"])  # every Spanish word with phones: the shipped ones and the candidates
    items = bs.items()
    heard = fires(candidates, items, float(settings["threshold"]))
    stops = {s: [i for i in items if i.split == s and i.action == "stop"] for s in ("dev", "test")}
    other = {s: [i for i in items if i.split == s and i.action != "stop"] for s in ("dev", "test")}

    def caught(words: list[str], selected: list[bs.Item]) -> set[str]:
        keys = {i.key for i in selected}
        return set().union(*(heard[w] & keys for w in words)) if words else set()

    def cells(fired: set[str], groups: tuple[list[bs.Item], ...]) -> str:
        """Hits and false alarms, dev then test: how many of each group's items fired, as table cells."""
        return " | ".join(pct(len(fired & {i.key for i in group}), len(group)) for group in groups)

    groups = (stops["dev"], other["dev"], stops["test"], other["test"])

    # the words worth listening for at this threshold: those that catch at least one dev stop phrase (a word that
    # catches none only adds false alarms)
    chosen = [w for w in candidates if caught([w], stops["dev"])]
    lines = ["# The stop spotter in Spanish (synthetic speech)", "",
             f"Command: `python -m tools.listen.bench_spotter_spanish"
             + (f" --sweep {args.sweep} --every {args.every}` (first table: the shipped threshold)" if args.sweep else "`")
             + ". The utterances of `python -m tools.speech.bench_spanish` "
             f"(espeak-ng, {len(bs.VOICES)} voices, clean and 12 dB); dev and test voices as there. Threshold as "
             f"shipped ({settings['threshold']:g}), not over the bridge's voice. **Synthetic speech: real Spanish "
             "stops have not been measured here.**", "",
             f"Each word alone: stop phrases it catches (hits), and other utterances it fires on (false alarms: "
             f"other commands, sentences). Dev stop phrases {len(stops['dev'])}, other dev utterances "
             f"{len(other['dev'])}; test {len(stops['test'])} and {len(other['test'])}.", "",
             "| word | phones | shipped | dev hits | dev false alarms | test hits | test false alarms |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for w in candidates:
        lines.append(f"| {w} | {settings['phones'][w]} | {'yes' if w in shipped else 'no'} | {cells(heard[w], groups)} |")
    lines += ["", "Sets: the shipped words, and the words that catch at least one dev stop phrase at this threshold.", "",
              "| set | dev hits | dev false alarms | test hits | test false alarms |", "| --- | --- | --- | --- | --- |"]
    for name, words in (("shipped: " + ", ".join(shipped), shipped), ("catching a dev stop: " + ", ".join(chosen), chosen)):
        lines.append(f"| {name} | {cells(set().union(*(heard[w] for w in words)), groups)} |")
    missed = {}
    for i in stops["test"]:
        if i.key not in caught(chosen, stops["test"]):
            missed[i.text] = missed.get(i.text, 0) + 1
    false_test = sorted({i.text for i in other["test"] if i.key in caught(chosen, other["test"])})
    lines += ["", "Test stop phrases the second set misses (times, of 6): "
              + (", ".join(f"{t} ({n})" for t, n in sorted(missed.items(), key=lambda kv: -kv[1])) or "none"),
              "", "Test utterances it fires on that are no stop (first 30): " + ("; ".join(false_test[:30]) or "none"), ""]
    if args.sweep:
        lines += ["## Other thresholds", "",
                  f"Command: `python -m tools.listen.bench_spotter_spanish --sweep {args.sweep} --every {args.every}`: every "
                  f"stop phrase, and every {args.every}th other utterance (false alarms of that sample).", "",
                  "| threshold | word | dev hits | dev false alarms | test hits | test false alarms |",
                  "| --- | --- | --- | --- | --- | --- |"]
        sampled = (stops["dev"], other["dev"][::args.every], stops["test"], other["test"][::args.every])
        for threshold in (float(t) for t in args.sweep.split(",")):
            swept = fires(candidates, [i for group in sampled for i in group], threshold)
            for w in candidates:
                lines.append(f"| {threshold:g} | {w} | {cells(swept[w], sampled)} |")
            lines.append(f"| {threshold:g} | all of them | {cells(set().union(*swept.values()), sampled)} |")
            print(lines[-1], file=sys.stderr, flush=True)
        lines.append("")
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
