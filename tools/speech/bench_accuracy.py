"""Accuracy benchmark of the voice front-end: recogniser (voice-asr registry) + matcher, per noise.

Two stages. ``recognise`` streams every WAV of the synthetic corpus (tools/speech/make_corpus.py) and of the
real recordings (../shared/speech) through each engine once and caches the hypotheses, evidence and
timings per file in ``out/bench/recognitions-<engine>.json`` (resumable; Whisper is slow here).
``report`` runs every matcher over the cached recognitions and writes the paper's table layout
(matcher x language x noise), babble/hum at 20/10/5 dB, out-of-domain false accepts, the real
voices, latency and real-time factor, and confusion matrices, into docs/bench/accuracy.md.
``tune`` sweeps the rejection thresholds on the dev split + real voices.

    nice -n 10 python -m tools.speech.bench_accuracy recognise --engines sphinx,whisper
    python -m tools.speech.bench_accuracy report
    python -m tools.speech.bench_accuracy tune --engine whisper --matcher phonetic
"""

from __future__ import annotations

import argparse
import sys
import time
import zlib
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import Recognition
from gcs_voice.understanding import MATCHERS

from tools.speech import accuracy_data
from tools.speech import bench_accuracy_report as bench_report
from tools.speech import make_corpus
from tools.speech.accuracy_data import REPO, SHARED, Item, corpus_items, file_digest, fresh_cache, real_items, save_cache

CHUNK_S = 0.1


def recognise_one(recognizer, item: Item) -> dict:
    """Stream one WAV in 100 ms chunks; latency counts from the end of the audio, as if live."""
    samples = make_corpus.read_wav(item.path)
    pcm = (np.clip(samples, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
    chunk = int(CHUNK_S * 16_000) * 2
    stream = recognizer.start_stream(item.lang)
    clock = 0.0  # simulated time at which the engine is free again (s since audio start)
    busy = 0.0
    n_chunks = max(1, -(-len(pcm) // chunk))
    for i in range(n_chunks):
        available = (i + 1) * CHUNK_S
        t0 = time.perf_counter()
        stream.accept(pcm[i * chunk:(i + 1) * chunk])
        dt = time.perf_counter() - t0
        clock = max(clock, available) + dt
        busy += dt
    t0 = time.perf_counter()
    rec: Recognition = stream.finish()
    dt = time.perf_counter() - t0
    busy += dt
    clock = max(clock, n_chunks * CHUNK_S) + dt
    audio_s = len(pcm) / 2 / 16_000
    return {
        "hypotheses": [[h.text, h.confidence, h.score] for h in rec.hypotheses],
        "engine": rec.engine, "lang": rec.lang, "extra": dict(rec.extra), "transcript": rec.transcript,
        "audio_s": audio_s,
        "latency_s": clock - n_chunks * CHUNK_S, "busy_s": busy, "sha1": file_digest(item.path),
    }


def recognise(engines: Iterable[str], items: list[Item], limit_s: float | None, every: int) -> None:
    for engine in engines:
        cache = fresh_cache(engine, items)
        todo = [it for it in items[::every] if it.key not in cache]
        todo = [it for it in todo if accuracy_data.supports(engine, it.lang)]
        # A fixed pseudo-random order: a run stopped early (--limit-s) still samples every cell evenly.
        todo.sort(key=lambda it: (it.split != "real", zlib.crc32(it.key.encode())))
        print(f"{engine}: {len(cache)} cached, {len(todo)} to recognise", flush=True)
        if not todo:
            continue
        recognizers: dict[str, object] = {}
        config = accuracy_data.config(engine)
        t_start, last_save = time.monotonic(), time.monotonic()
        for n, it in enumerate(todo, 1):
            if it.lang not in recognizers:
                recognizers[it.lang] = accuracy_data.load(engine, it.lang)
            cache[it.key] = recognise_one(recognizers[it.lang], it)
            if time.monotonic() - last_save > 20 or n == len(todo):
                save_cache(engine, cache, config)
                last_save = time.monotonic()
                print(f"  {engine}: {n}/{len(todo)} ({time.monotonic() - t_start:.0f} s)", flush=True)
            if limit_s and time.monotonic() - t_start > limit_s:
                save_cache(engine, cache, config)
                print(f"  {engine}: stopped after --limit-s {limit_s:.0f} s", flush=True)
                break


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="stage", required=True)
    r = sub.add_parser("recognise", help="run engines over the corpus and real voices, cache hypotheses")
    r.add_argument("--engines", default="sphinx,whisper")
    r.add_argument("--corpus", type=Path, default=REPO / "corpus")
    r.add_argument("--noises", default="", help="only these noise labels (default: all)")
    r.add_argument("--split", default="", help="only this split (dev/test)")
    r.add_argument("--every", type=int, default=1, help="take every Nth file (subsample)")
    r.add_argument("--limit-s", type=float, default=None, help="stop an engine after this many seconds")
    r.add_argument("--no-real", action="store_true", help="skip ../shared/speech")
    for name in ("report", "tune"):
        q = sub.add_parser(name)
        q.add_argument("--engines", default="sphinx,whisper")
        q.add_argument("--matchers", default=",".join(MATCHERS))
        q.add_argument("--corpus", type=Path, default=REPO / "corpus")
    args = p.parse_args(argv)

    items = corpus_items(args.corpus)
    if args.stage == "recognise":
        if args.noises:
            items = [it for it in items if it.noise in args.noises.split(",")]
        if args.split:
            items = [it for it in items if it.split == args.split]
        if not args.no_real:
            items = real_items(SHARED / "speech") + items
        recognise(args.engines.split(","), items, args.limit_s, args.every)
        return 0
    items = real_items(SHARED / "speech") + items
    if args.stage == "tune":
        bench_report.tune(args.engines.split(","), args.matchers.split(","), items)
    else:
        bench_report.report(args.engines.split(","), args.matchers.split(","), items)
    return 0


if __name__ == "__main__":
    sys.exit(main())
