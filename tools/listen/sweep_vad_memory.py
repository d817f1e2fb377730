"""Choose how long the Silero segmenter's state may remember (``memory_s``) on streams of the dev speakers.

Silero is a recurrent network; carried across minutes of noise its state drifts until speech no longer
crosses the start threshold (``gcs_voice.audio.vad.SileroVad``). ``memory_s`` bounds what it remembers.
Too long and the drift comes back; too short and the network has too little of the room to tell a clatter
or a miaow from a voice. This builds streams like ``tools.listen.bench_stream`` (real noise under all of it at
12 dB) from the dev part of ``../shared/speech`` (``tools.speech.real_speech.load_recordings(split="dev")``: never
the test speakers the benchmarks report on), two ways: a talkative room (pauses 1.5-4 s, levels ±6 dB) and
a pilot who speaks now and then (pauses 5-40 s: long noise without speech, where the drift shows), and
segments each with every ``memory_s``. No recogniser runs: this counts utterances the segmenter cut
(commands, and all) and segments on noise alone. The recogniser's side of the choice is
``python -m tools.listen.bench_stream --split dev --vad-settings ...``. Both, and the values not taken:
docs/bench/stream.md (Tried and not taken; their last full reports: git history: docs/bench/vad_memory.md,
vad_memory_sweep.md).

    python -m tools.listen.sweep_vad_memory --out docs/bench/vad_memory_sweep.md
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path

import numpy as np

from tools.listen.stream_score import overlaps
from tools.listen.streams import NOISE_FILES, choose, lay_clips, noise_track, read_wav
from tools.speech.real_speech import SHARED, load_recordings

#: (name, pauses s, level spread dB, utterances)
ROOMS = (("talkative", (1.5, 4.0), 6.0, 120), ("sparse", (5.0, 40.0), 0.0, 60))


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.audio.sources import pcm_to_chunks
    from gcs_voice.audio.vad import load_vad_settings, segment_utterances

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--memories", default="0,3,5,8,12", help="memory_s values (0: the state carried forever)")
    p.add_argument("--noises", default=",".join(NOISE_FILES))
    p.add_argument("--snr", type=float, default=12.0)
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    memories = [float(m) for m in args.memories.split(",")]
    base = load_vad_settings(method="silero")
    recordings = load_recordings(split="dev")
    lines = []
    for room, pauses, spread, n in ROOMS:
        clips = choose(recordings, n, np.random.default_rng(args.seed))
        for name in args.noises.split(","):
            speech, placed, rng = lay_clips(clips, args.seed, pauses, spread)
            x = np.clip(speech + noise_track(read_wav(SHARED / "noise" / NOISE_FILES[name]), speech.size, args.snr, rng),
                        -1, 1)
            pcm = (x * 32767).astype("<i2").tobytes()
            commands = [q for q in placed if q.clip.action]
            cells = []
            for m in memories:
                s = dataclasses.replace(base, silero=dataclasses.replace(base.silero, memory_s=m))
                segs = list(segment_utterances(pcm_to_chunks(pcm), s))
                cut = sum(any(overlaps(u.start_s, u.end_s, q.voiced_start_s, q.voiced_end_s) for u in segs)
                          for q in commands)
                on_noise = sum(not any(overlaps(u.start_s, u.end_s, q.start_s, q.end_s) for q in placed) for u in segs)
                cells.append(f"{cut} / {len(commands)}, {on_noise}")
            lines.append(f"| {room} | {NOISE_FILES[name]} | {x.size / 16000 / 60:.0f} | " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
    report = "\n".join([
        "# How long the Silero segmenter may remember: segmenter alone, dev-part streams",
        "",
        "Command: `" + " ".join(["python -m tools.listen.sweep_vad_memory", *(shlex.quote(a) for a in
                                                                      (argv if argv is not None else sys.argv[1:]))]) + "`",
        "",
        f"Streams of real utterances of the dev split of `../shared/speech` (seed {args.seed}; 70 % commands), the real "
        f"noise under all of it {args.snr:g} dB below the speech level: *talkative* (120 utterances, pauses 1.5-4 s, "
        "each utterance up to ±6 dB from the level) and *sparse* (60 utterances, pauses 5-40 s: minutes of noise "
        "with little speech). Each cell: commands cut (a segment overlaps their speech) / commands, and segments "
        "on noise alone. Other settings as in `gcs_voice/audio/vad.toml`; memory 0 carries the state forever.",
        "",
        "| room | noise | minutes | " + " | ".join(f"memory {m:g} s" for m in memories) + " |",
        "|---|---|---|" + "---|" * len(memories),
        *lines, "",
    ])
    if args.out:
        Path(args.out).write_text(report, encoding="utf-8")
    print(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
