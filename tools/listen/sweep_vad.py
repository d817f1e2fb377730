"""Choose the Silero segmenter's start/end thresholds on streams built from the dev part of the real speech.

Builds the same kind of stream as tools/listen/bench_stream.py (60 utterances at random pauses, real noise at a
measured SNR) from the dev part of ``../shared/speech``: ``tools.speech.real_speech.load_recordings(split="dev")``,
the one speaker split of every real-speech tool (this file has no split of its own), never the test
speakers that bench_stream reports on. It segments it with each start/end threshold pair and counts:
segments, utterances found as exactly one segment, utterances missed (no segment), and segments on noise
alone. No recogniser runs: this is the segmenter only. The chosen pair goes in ``gcs_voice/audio/vad.toml``;
the pairs not taken are in docs/bench/stream.md (Tried and not taken; this sweep's last full report:
git history: docs/bench/vad_sweep.md).

    python -m tools.listen.sweep_vad --out docs/bench/vad_sweep.md
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path

import numpy as np

from tools.listen.streams import NOISE_FILES, build_stream, choose, read_wav
from tools.speech.real_speech import SHARED, load_recordings

PAIRS = ((0.5, 0.35), (0.4, 0.25), (0.3, 0.2), (0.2, 0.12))


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.audio.sources import pcm_to_chunks
    from gcs_voice.audio.vad import load_vad_settings, segment_utterances

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--conditions", default="clean,kitchen12,kitchen6,tap6,machine6,cat6")
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    clips = choose(load_recordings(split="dev"), 60, np.random.default_rng(args.seed))
    base = load_vad_settings(method="silero")
    lines = []
    for cond in args.conditions.split(","):
        name = cond.rstrip("0123456789")
        snr = float(cond[len(name):]) if cond != "clean" else None
        noise = read_wav(SHARED / "noise" / NOISE_FILES[name]) if snr is not None else None
        x, placed = build_stream(clips, noise, snr, args.seed)
        pcm = (np.clip(x, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
        for start, end in PAIRS:
            s = dataclasses.replace(base, silero=dataclasses.replace(base.silero, start_threshold=start,
                                                                     end_threshold=end))
            segs = list(segment_utterances(pcm_to_chunks(pcm), s))
            overlaps = [sum(1 for u in segs if min(u.end_s, q.end_s) - max(u.start_s, q.start_s) > 0) for q in placed]
            noise_only = sum(1 for u in segs if not any(min(u.end_s, q.end_s) - max(u.start_s, q.start_s) > 0
                                                        for q in placed))
            lines.append(f"| {cond} | {start:g} / {end:g} | {len(segs)} | {overlaps.count(1)} / {len(placed)} | "
                         f"{overlaps.count(0)} | {noise_only} |")
            print(lines[-1], flush=True)
    report = "\n".join([
        "# Silero segmenter thresholds on dev-part streams",
        "",
        "Command: `" + " ".join(["python -m tools.listen.sweep_vad", *(shlex.quote(a) for a in
                                                               (argv if argv is not None else sys.argv[1:]))]) + "`",
        "",
        f"One stream of 60 utterances from the dev split of `../shared/speech` (`python -m tools.speech.real_speech`; "
        f"seed {args.seed}; the other "
        "settings as in `gcs_voice/audio/vad.toml`), per noise condition (name + SNR dB over the voiced frames).",
        "",
        "| condition | start / end threshold | segments | utterances as one segment | utterances missed | "
        "segments on noise alone |",
        "|---|---|---|---|---|---|",
        *lines, "",
    ])
    if args.out:
        Path(args.out).write_text(report, encoding="utf-8")
    else:
        print(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
