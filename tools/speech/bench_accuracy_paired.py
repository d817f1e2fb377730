"""Two engines on exactly the same files: for a subsampled engine (whisper-score) vs a full one.

``bench_accuracy.py report`` scores each engine on the files it has cached; when one engine was run
on every 3rd file only, its cells are not comparable with the others'. This prints one markdown table
of the default matcher's decisions on the files BOTH engines have cached (test split + real voices).

    python -m tools.speech.bench_accuracy_paired whisper whisper-score
    python -m tools.speech.bench_accuracy_paired whisper whisper-score --min-confidence 0.5,0.9,0.99

``--min-confidence`` adds the LAST engine once per value of the matcher's min_confidence (a
trade-off curve on the same files, not a tuned result).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

from tools.speech import accuracy_data as bench
from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("engines", nargs="+")
    p.add_argument("--matcher", default=DEFAULT_MATCHER)
    p.add_argument("--corpus", type=Path, default=REPO / "corpus")
    p.add_argument("--min-confidence", default="", help="comma-separated values for the last engine")
    args = p.parse_args(argv)
    items = bench.real_items(bench.SHARED / "speech") + bench.corpus_items(args.corpus)
    caches = {e: bench.fresh_cache(e, items) for e in args.engines}
    both = [it for it in items if it.split in ("test", "real") and all(it.key in c for c in caches.values())]
    dictionaries = {lang: load_language(lang) for lang in ("en", "es")}
    decided = {e: bench.decide_all(e, args.matcher, both, caches[e], dictionaries) for e in args.engines}
    last = args.engines[-1]
    for value in filter(None, args.min_confidence.split(",")):
        label = f"{last} min_confidence {value}"
        decided[label] = bench.decide_all(last, args.matcher, both, caches[last], dictionaries,
                                          min_confidence=float(value))
    cells = sorted({(it.lang, it.noise) for it in both}, key=lambda c: (c[1] == "real", c))
    print("Cells: commands right / wrong class / rejected, non-commands acted on.\n")
    print("| lang | noise | n commands / non-commands | " + " | ".join(
        f"{e} + {args.matcher}" for e in decided) + " |")
    print("|---" * (3 + len(decided)) + "|")
    for lang, noise in cells:
        sel = [it for it in both if it.lang == lang and it.noise == noise]
        row = []
        for e in decided:
            s = bench.score(sel, decided[e])
            row.append(f"**{s.right}** / {s.wrong} / {s.rejected}, {s.false_accept}/{s.n_ood}")
        s = bench.score(sel, decided[args.engines[0]])
        print(f"| {lang} | {noise} | {s.n_cmd} / {s.n_ood} | " + " | ".join(row) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
