"""--lang auto in Whisper's scoring mode: pick the language by Whisper's detection or by the best phrase?

For each utterance of a corpus split (both languages), the phrases of every dictionary are scored on
the short encoder window (the engine's own code); the language is chosen (a) by Whisper's language
detection among the loaded languages and (b) by the highest prior-corrected phrase score. Prints how
often each picks the right language, and the closed-set class accuracy that follows (no rejection).

    python -m tools.make_corpus
    nice -n 10 python -m tools.bench_auto_language --split dev --noises raw --limit 90
"""

from __future__ import annotations

import argparse
import sys
import zlib
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

from tools import bench_accuracy
from tools import bench_accuracy_engines as bench_engines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--corpus", type=Path, default=REPO / "corpus")
    parser.add_argument("--split", default="dev")
    parser.add_argument("--noises", default="raw")
    parser.add_argument("--limit", type=int, default=0, help="at most this many files (CRC order)")
    args = parser.parse_args(argv)
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.asr.whisper_score import score_phrases
    from gcs_voice.domain.dictionary import load_language

    recognizer = load_recognizer("whisper", [load_language("en"), load_language("es")],
                                 model=str(bench_engines.WHISPER_MODEL), mode="score")
    weight = float(recognizer.settings.get("score_prior_weight", 0.6))
    items = [it for it in bench_accuracy.corpus_items(args.corpus)
             if it.split == args.split and it.noise in args.noises.split(",")]
    items.sort(key=lambda it: zlib.crc32(it.key.encode()))
    items = items[: args.limit or None]
    counts = Counter()
    for it in items:
        audio = bench_accuracy.make_corpus.read_wav(it.path)
        encoded, frames = recognizer.encode_short(audio)
        detected, _, _ = recognizer.detect(encoded, None)
        best = {lang: score_phrases(recognizer.model.model, encoded, recognizer.tokenizer(lang),
                                    recognizer.dictionaries[lang], frames, recognizer.phrase_priors(lang), weight)[0]
                for lang in recognizer.languages}
        by_score = max(best, key=lambda lang: best[lang].logprob)
        counts["utterances"] += 1
        counts["language right, detection"] += detected == it.lang
        counts["language right, best phrase"] += by_score == it.lang
        if it.truth != "none":
            counts["commands"] += 1
            counts["class right, detection"] += best[detected].phrase.action == it.truth
            counts["class right, best phrase"] += best[by_score].phrase.action == it.truth
    print(f"{args.split} split, noises {args.noises}, {counts['utterances']} utterances (en + es)")
    for key, value in counts.items():
        print(f"  {key}: {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
