"""A stop spotted over the bridge's own voice, settled by the domain ear: real stops kept, the bridge's words let go.

While the bridge speaks, only the stop spotter listens; a stop it spots holds a moving vehicle, and the over-voice
ear settles the hold on the audio the spotter heard (gcs_voice.session.listen.StopPath): stopped if the ear gives
"stop" at least ``[ear.whisper-score] over_voice_stop`` (thresholds.toml), else the motion resumes. Two things count:

- what the echo canceller leaves of the bridge's cues, the pilot silent: a hold the ear keeps here is a stop for
  nothing. Held out (``--split test``): the half of the cues the ear never trained on (tools.speech.ear_cues), English
  and Spanish, each in ``--takes`` scenes (room, loudness, alignment, floor from the second half of a real noise).
- a real speaker's "stop" said over those cues, at each of ``--levels`` (the bridge's voiced level relative to the
  pilot's): a hold the ear lets go here is a real stop lost. Held out: the test speakers of ../shared/speech.

The spotter is the shipped one at its threshold over the bridge's voice, on the canceller's output.

    python -m tools.listen.bench_settle --out docs/bench/settle.md          # the shipped ears, held out
    python -m tools.listen.bench_settle --split dev --cue-weights 5,20,50,100,200,500   # choose CUE_WEIGHT
    python -m tools.listen.bench_settle --split dev --choose [--write]   # choose over_voice_stop

``--split dev`` judges over-voice ears trained (from train_ear's cached features) with each ``--cue-weights`` on new
scenes of the trained cues and the dev speakers' stops, over the first halves: train_ear.CUE_WEIGHT is the one that
keeps every dev stop's hold and lets go of most cues (the smallest among equals). ``--choose`` judges each dev stop
with an over-voice ear trained without its speaker (5 folds, as tools.speech.bench_ear tune): ``over_voice_stop`` is
the largest that keeps OVER_VOICE_KEPT of the dev stops the spotter fires on.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tools.speech.real_speech import SHARED

DEFAULT_MODEL = SHARED / "models" / "faster-whisper-base"
#: the scenes' seed (the ears train on seed 1's: these are others, even of the same cues)
SEED = 7
#: the over_voice_stop values ``--choose`` tries
OVER_VOICE_STOP = (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5)
#: the fraction of the dev stops said over the bridge's voice whose hold must be kept: more than the 95 % of stops a
#: decision follows (tools.speech.bench_ear.STOP_KEPT), since none follows here and the pilot who shouts "stop" over
#: the bridge is the one the bridge cannot hear again at once; at 95 % (0.15) one of 7 real stops over the bridge was
#: let go in a live room at 12 dB (tools.listen.bench_room_stops)
OVER_VOICE_KEPT = 0.98


def scenes(split: str, takes: int, levels: list[float], judge) -> tuple[list, dict[float, list]]:
    """``judge(audio)`` of each cue of ``split`` alone in ``takes`` scenes ((cue id, judged)), and of each real
    "stop" of ``split``'s speakers said over one of those cues at each level ({level: [judged]})."""
    from tools.speech.ear_cues import bridge_cues, cue_split, heard_over_cue, scene
    from tools.speech.ear_data import clip_audio, cue_plan, real_clips

    t0 = time.time()
    alone = [(clip.over, judge(clip_audio(clip, SEED), clip)) for clip in cue_plan(SEED, split=split, takes=takes)]
    print(f"  {len(alone)} cues alone ({time.time() - t0:.0f} s)", file=sys.stderr)
    cues = [c for c in bridge_cues() if cue_split(c) == split]
    stops = [c for c in real_clips() if c.split == split and c.label == "stop"]
    half = "train" if split == "dev" else "test"
    rng = np.random.default_rng(SEED)
    over: dict[float, list] = {}
    for level in levels:
        for clip in stops:
            cue = cues[int(rng.integers(len(cues)))]
            where = replace(scene(f"bench/{level}/{clip.key}", SEED), level_db=level)
            earlier = [cues[int(i)] for i in rng.choice(len(cues), size=3, replace=False)]
            over.setdefault(level, []).append(judge(heard_over_cue(cue, where, clip_audio(clip), half, earlier), clip))
        print(f"  stops over cues at {level:+g} dB ({time.time() - t0:.0f} s)", file=sys.stderr)
    return alone, over


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.asr.ear import EAR_OVER_VOICE_PATH, EAR_PATH, DomainEar
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.understanding.thresholds import ear_limits
    from tools.report import header
    from tools.speech import train_ear
    from tools.speech.ear_data import features

    parser = argparse.ArgumentParser(prog="python -m tools.listen.bench_settle", description=__doc__.splitlines()[0])
    parser.add_argument("--ear", type=Path, action="append",
                        help=f"an ear to judge, repeatable (default: {EAR_OVER_VOICE_PATH.name} and {EAR_PATH.name})")
    parser.add_argument("--split", choices=("test", "dev"), default="test")
    parser.add_argument("--cue-weights", default="", help="with --split dev: CUE_WEIGHT values to train and compare")
    parser.add_argument("--choose", action="store_true", help="with --split dev: choose over_voice_stop (out-of-fold)")
    parser.add_argument("--write", action="store_true", help="with --choose: write it into thresholds.toml")
    parser.add_argument("--takes", type=int, default=6, help="scenes per cue alone")
    parser.add_argument("--levels", default="-10,-6,0,6", help="the bridge's voice relative to the pilot's, dB")
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL)
    parser.add_argument("--out", type=Path, help="write the markdown report here")
    args = parser.parse_args(argv)
    if not (args.model / "model.bin").is_file():
        parser.error(f"no Whisper model at {args.model} (give --model PATH/faster-whisper-base)")
    if args.split == "dev" and not (args.cue_weights or args.choose):
        parser.error("--split dev compares --cue-weights or does --choose (the held-out split judges the shipped ears)")
    if args.choose and (args.split != "dev" or args.cue_weights):
        parser.error("--choose is on --split dev, without --cue-weights")
    fold_ears: list = []
    if args.choose or args.cue_weights:
        clips = train_ear.training_clips(train_ear.SEED, False)
        examples = (train_ear.featurise(clips, train_ear.SEED, False, args.model)
                    + train_ear.featurise(train_ear.over_voice_clips(clips, train_ear.SEED, False), train_ear.SEED,
                                          False, args.model))
    if args.choose:
        from tools.speech.bench_ear import fold_of, out_of_fold_ears

        fold_ears = out_of_fold_ears(examples, train_ear.SEED)
        ears = {"over-voice ear, out of fold": fold_ears[0]}
    elif args.cue_weights:
        if args.split != "dev":
            parser.error("--cue-weights are chosen on --split dev only")
        ears = {}
        for weight in (float(w) for w in args.cue_weights.split(",")):
            train_ear.CUE_WEIGHT = weight
            ears[f"CUE_WEIGHT {weight:g}"] = train_ear.train(examples, train_ear.SEED)[0]
    else:
        paths = args.ear or [EAR_OVER_VOICE_PATH, EAR_PATH]
        ears = {str(p): DomainEar.load(p) for p in paths}
        missing = [p for p, e in ears.items() if e is None]
        if missing:
            parser.error(f"no ear at {missing[0]}")
    recognizer = load_recognizer("whisper", [load_language("en")], model=str(args.model), mode="score")
    spotter = load_stop_spotter(["en", "es"])
    keep_at = ear_limits("whisper-score")["over_voice_stop"]
    levels = [float(v) for v in args.levels.split(",")]

    def judge(audio: np.ndarray, clip) -> tuple[bool, dict[str, float]]:
        """(whether the spotter fires over the bridge's voice, each ear's p(stop)); --choose: the ear of the
        speaker's fold."""
        pcm = np.clip(np.round(audio * 32768.0), -32768, 32767).astype("<i2").tobytes()
        fired = spotter.spot(pcm, over_voice=True).fired
        x = features(recognizer.model.encode, recognizer.log_mel, audio)
        judges = ({name: fold_ears[fold_of(clip)] if clip.source == "real" else fold_ears[0] for name in ears}
                  if fold_ears else ears)
        return fired, {name: float(ear.evidence(x)["ear:stop"]) for name, ear in judges.items()}

    alone, over = scenes(args.split, args.takes, levels, judge)
    if args.choose:
        return choose(alone, over, next(iter(ears)), args.write)
    named = {str(EAR_OVER_VOICE_PATH): "over-voice ear (shipped)", str(EAR_PATH): "the commands' ear (shipped)"}
    rows = []
    for name in ears:
        fired_alone = [p for _c, (f, p) in alone if f]
        cells = [f"{sum(p[name] >= keep_at for p in fired_alone)}/{len(fired_alone)}",
                 f"{sum(p[name] >= keep_at for _c, (_f, p) in alone)}/{len(alone)}"]
        for level in levels:
            fired = [p for f, p in over[level] if f]
            cells.append(f"{sum(p[name] >= keep_at for p in fired)}/{len(fired)} (of {len(over[level])})")
        rows.append(f"| {named.get(name, name)} | " + " | ".join(cells) + " |")
        print(rows[-1])
    first = next(iter(ears))
    worst = sorted(((p[first], c) for c, (_f, p) in alone), reverse=True)[:5]
    who = "held-out" if args.split == "test" else "dev"
    report = "\n".join([
        "# A stop spotted over the bridge's voice, settled by the domain ear",
        "",
        header("tools.listen.bench_settle", argv) + f"Corpus: the bridge's cues of the {who} half "
        f"(tools.speech.ear_cues.cue_split: {len({c for c, _ in alone})} English and Spanish cues"
        f"{' the ear never trained on' if args.split == 'test' else ', new scenes'}), each in {args.takes} scenes "
        "(room RT60 0.15-0.6 s, the cue -10 to +6 dB from the pilot's level, its first sample anywhere in a "
        "microphone block, the canceller having heard 0-3 cues, the floor from the "
        f"{'second' if args.split == 'test' else 'first'} half of a real noise at -65 to -45 dBFS), through the "
        f"shipped echo canceller; and the {len(over[levels[0]])} real \"stop\" recordings of the {who} speakers of "
        "../shared/speech said over one of those cues at each level. The spotter at its threshold over the bridge's "
        f"voice; a hold is kept when the ear gives \"stop\" at least {keep_at:g} (thresholds.toml `over_voice_stop`).",
        "",
        "| ear | the bridge alone: holds kept, of the spotter's stops | the bridge alone: kept, of all | "
        + " | ".join(f"real stop over the bridge at {lv:+g} dB: kept, of the spotter's" for lv in levels) + " |",
        "| --- | --- | --- | " + " | ".join("---" for _ in levels) + " |",
        *rows,
        "",
        f"Cues alone given most \"stop\" by the first ear: " + "; ".join(f"{c} ({p:.3f})" for p, c in worst) + ".",
        "",
    ])
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report, encoding="utf-8")
        print(f"wrote {args.out}")
    return 0


def choose(alone: list, over: dict[float, list], name: str, write: bool) -> int:
    """The largest OVER_VOICE_STOP that keeps OVER_VOICE_KEPT of the dev stops the spotter fired on over the bridge."""
    from tools.speech.bench_ear import write_ear_limits

    stops = [p[name] for level in over for fired, p in over[level] if fired]
    cues = [p[name] for _c, (fired, p) in alone if fired]
    print("over_voice_stop | dev stops over the bridge kept (of the spotter's) | cues alone kept (of the spotter's)")
    chosen = OVER_VOICE_STOP[0]
    for t in OVER_VOICE_STOP:
        kept = sum(p >= t for p in stops)
        print(f"{t} | {kept}/{len(stops)} | {sum(p >= t for p in cues)}/{len(cues)}")
        if kept >= OVER_VOICE_KEPT * len(stops):
            chosen = t
    print(f"over_voice_stop {chosen}")
    if write:
        write_ear_limits({"over_voice_stop": chosen})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
