"""How much of the silence prior to subtract in Whisper's scoring mode (``score_prior_weight``).

For each utterance of a corpus split, every dictionary phrase's mean token log-probability is
computed once on the short encoder window (the engine's own code), together with the same on
silence (the prior). Then, for each weight w, the class of the phrase maximising
``logprob - w * prior`` is compared with the truth: closed-set accuracy, no rejection. The weight
in gcs_voice/asr/engines.toml was chosen with this on the dev split (docs/bench/accuracy.md).

    python -m tools.make_corpus
    nice -n 10 python -m tools.sweep_score_prior --split dev --noises raw,u0.15,babble10
"""

from __future__ import annotations

import argparse
import json
import sys
import zlib
from collections import defaultdict
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent

from tools import bench_accuracy
from tools import bench_accuracy_engines as bench_engines
from gcs_voice.asr.whisper_score import phrase_logprobs

CACHE = REPO / "out" / "bench" / "score-raw-logprobs.json"


def raw_scores(recognizer, item) -> list[float]:
    """Mean token log-probability of every phrase of the item's language (no prior subtracted)."""
    samples = bench_accuracy.make_corpus.read_wav(item.path).astype(np.float32)
    encoded, frames = recognizer.encode_short(samples)
    return phrase_logprobs(recognizer.model.model, encoded, recognizer.tokenizer(item.lang),
                           recognizer.dictionaries[item.lang], frames)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--corpus", type=Path, default=REPO / "corpus")
    parser.add_argument("--split", default="dev")
    parser.add_argument("--noises", default="raw,u0.15,babble10")
    parser.add_argument("--weights", default="0,0.25,0.5,0.6,0.75,1.0")
    parser.add_argument("--limit", type=int, default=0, help="at most this many files (CRC order)")
    args = parser.parse_args(argv)
    noises = set(args.noises.split(","))
    items = [it for it in bench_accuracy.corpus_items(args.corpus)
             if it.split == args.split and it.noise in noises and it.truth != "none"]
    items.sort(key=lambda it: zlib.crc32(it.key.encode()))
    if args.limit:
        items = items[: args.limit]
    cache = json.loads(CACHE.read_text()) if CACHE.is_file() else {}
    recognizers = {}
    from gcs_voice.domain.dictionary import load_language

    # a changed WAV or dictionary is scored again: both are in the cache keys
    tag = {lang: f"{lang}@{bench_accuracy.file_digest(load_language(lang).path)}" for lang in {it.lang for it in items}}
    keys = {it.key: f"{it.key}@{bench_accuracy.file_digest(it.path)}@{tag[it.lang]}" for it in items}
    for n, it in enumerate(items, 1):
        if keys[it.key] in cache:
            continue
        if it.lang not in recognizers:
            recognizers[it.lang] = bench_engines.load("whisper-score", it.lang)
            cache[f"prior/{tag[it.lang]}"] = recognizers[it.lang].phrase_priors(it.lang)
        cache[keys[it.key]] = raw_scores(recognizers[it.lang], it)
        if n % 25 == 0:
            CACHE.parent.mkdir(parents=True, exist_ok=True)
            CACHE.write_text(json.dumps(cache))
            print(f"{n}/{len(items)}", flush=True)
    CACHE.parent.mkdir(parents=True, exist_ok=True)
    CACHE.write_text(json.dumps(cache))
    actions = {lang: [p.action for p in load_language(lang).phrases] for lang in {it.lang for it in items}}
    cells = sorted({(it.lang, it.noise) for it in items})
    print(f"Closed-set accuracy (%, no rejection), {args.split} split, n per cell in the header\n")
    counts = defaultdict(int)
    for it in items:
        counts[(it.lang, it.noise)] += 1
    print("| weight | " + " | ".join(f"{lang} {noise} (n={counts[(lang, noise)]})" for lang, noise in cells) + " |")
    print("|---" * (len(cells) + 1) + "|")
    for w in (float(x) for x in args.weights.split(",")):
        right = defaultdict(int)
        for it in items:
            prior = np.asarray(cache[f"prior/{tag[it.lang]}"])
            best = int(np.argmax(np.asarray(cache[keys[it.key]]) - w * prior))
            right[(it.lang, it.noise)] += actions[it.lang][best] == it.truth
        print(f"| {w:g} | " + " | ".join(f"{100 * right[c] / counts[c]:.1f}" for c in cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
