#!/usr/bin/env python3
"""A stop said over the bridge's own voice: how often the stop spotter still hears it, by how loud that voice is.

While the bridge speaks (``--feedback speech``) the segmenter is deaf and only the stop spotter listens
(gcs_voice/audio/microphone.py). The spotter then hears the pilot's "stop" mixed with the bridge's words
as a speaker beside the microphone returns them. For every real held-out "stop" of ../shared/speech
(``tools.real_speech.load_recordings(split="test")``) that the spotter hears alone, this mixes the
bridge's longest decision cue (the doing tone, then espeak-ng's "going forward, turning right"; the
pilot's stop starting ``--stop-at`` seconds into it) at several levels of its voiced parts relative to
the stop's voiced parts, delayed as ``--delay-ms``, and spots the mix as the spotter's stream would
take it (from the start of the bridge's sound). No noise, no room reverberation: the direct path only.

    python -m tools.bench_echo --out docs/bench/echo.md
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from tools.bench_stream import voiced_level
from tools.real_speech import SHARED, load_recordings

RATE = 16_000


def voiced_dbfs(x: np.ndarray) -> float:
    """Level of the voiced frames (tools.bench_stream.voiced_level), in dBFS, of int16-scaled samples."""
    return float(20 * np.log10(voiced_level(x / 32768.0)[0] + 1e-12))


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.audio.sounds import Speech, tone
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.session.feedback import load_sound_settings

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default="-20,-10,-6,0,6", help="the bridge's voice relative to the pilot's, dB")
    parser.add_argument("--delay-ms", type=float, default=60.0, help="the echo's delay (default 60 ms)")
    parser.add_argument("--stop-at", type=float, default=0.5, help="seconds into the bridge's sound the stop starts")
    parser.add_argument("--speech", type=Path, default=SHARED / "speech")
    parser.add_argument("--out", type=Path, help="write the markdown report here")
    args = parser.parse_args(argv)

    spotter = load_stop_spotter(["en"])
    s = load_sound_settings()
    words = "going forward, turning right"
    voice = np.frombuffer(tone(s.tones["doing"], s.amplitude, s.fade_s) + Speech("en-us", s.speed_wpm).say(words),
                          "<i2").astype(np.float64)
    stops = [(r.path.name, np.frombuffer(read_wav(r.path), "<i2").astype(np.float64))
             for r in load_recordings(args.speech, split="test") if r.action == "stop"]
    alone = [x for _name, x in stops if spotter.spot(x.astype("<i2").tobytes()).fired]
    levels = [float(v) for v in args.levels.split(",")]
    delay = int(args.delay_ms / 1000 * RATE)
    rows = []
    for level in levels:
        hits = 0
        for x in alone:
            gain = 10 ** ((voiced_dbfs(x) - voiced_dbfs(voice) + level) / 20)
            at = int(args.stop_at * RATE)
            n = max(at + x.size, delay + voice.size) + RATE // 2
            mix = np.zeros(n)
            mix[delay:delay + voice.size] += voice * gain
            mix[at:at + x.size] += x
            hits += spotter.spot(np.clip(mix, -32768, 32767).astype("<i2").tobytes()).fired
        rows.append(f"| {level:+g} dB | {hits}/{len(alone)} |")
        print(rows[-1])
    corpus = "../shared/speech" if args.speech == SHARED / "speech" else str(args.speech)
    report = "\n".join([
        "# A stop said over the bridge's own voice",
        "",
        f"Command: `python -m tools.bench_echo --levels {args.levels} --delay-ms {args.delay_ms:g} "
        f"--stop-at {args.stop_at:g}" + (f" --out {args.out}" if args.out else "") + "`",
        "",
        f"Corpus: the real \"stop\" recordings of the held-out test speakers of `{corpus}` that the stop spotter "
        f"hears alone ({len(alone)} of {len(stops)}). Each is mixed with the bridge's cue for a decision (the doing "
        f"tone, then espeak-ng saying \"{words}\", {voice.size / RATE:.1f} s), the stop starting {args.stop_at:g} s "
        f"into it, the cue {args.delay_ms:g} ms late, at a level of its voiced parts relative to the stop's; the "
        "spotter decodes the mix from the start of the cue, as its stream does while the microphone is deaf. "
        "Direct path only: no room, no noise.",
        "",
        "| the bridge's voice vs the pilot's | stops still spotted |",
        "| --- | --- |",
        *rows,
        "",
        "The bridge does not subtract what it plays (no echo canceller yet): the spotter hears the raw microphone.",
        "While the bridge speaks the segmenter is deaf, so a stop the spotter misses then is not heard at all (the",
        "main recogniser does not get it): the pilot says it again after the cue.",
        "",
    ])
    print(report)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
