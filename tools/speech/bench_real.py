"""Real people: the voice front-end on ../shared/speech, clean and under real noise, split by speaker.

Three stages, all on the real recordings of ``tools.speech.real_speech`` (split by speaker: thresholds are
chosen on ``dev`` and reported on ``test``, which tuning never sees):

    python -m tools.speech.bench_real recognise --engine whisper-score      # cache recognitions, every condition
    python -m tools.speech.bench_real tune --engine whisper-score --write   # choose thresholds on dev
    python -m tools.speech.bench_real report                                # docs/bench/real.md from the caches

``recognise`` streams every file (under every condition: clean; kitchen at 20/12/6 dB; tap, machine and
voices-with-cat at 12 dB) through the engine exactly as ``gcs-voice recognize`` does, and caches the
recognition and the time from the end of the audio to the result in
``out/bench/real/<engine>.jsonl`` (resumable; a changed file or changed engine settings are recognised again).
``tune`` replays the cache through the real matcher with candidate thresholds (temporary copies of
``gcs_voice/understanding/thresholds.toml``): on clean dev speech, non-command words and sentences acted on
must stay within HALF their 2 % target (a setting that only just fits dev would not hold on test) and wrong
actions within 1 %, there and one grid step looser in any threshold; among those, the best
"right - 3 x wrong - 2 x acted on non-commands" over clean, kitchen 20 dB and each real noise at 12 dB wins (at
12 dB no setting meets the targets on dev). ``gate`` shows what a floor on Whisper's confidence in its own
transcript would cost and save, on dev and test.
``report`` writes the tables with the count behind every percentage, and ``frontier`` (also a section of the
report) the most any threshold of the rule could keep within the targets, chosen on the test split itself: an upper
bound that tells whether better thresholds or a better model is what is missing.

Every noisy file gets one segment of its noise (``tools.speech.real_speech.NOISE_SEED``); ``spread`` draws others and
says how far each figure moves with the draw, so that a difference smaller than that is not read as a change:

    python -m tools.speech.bench_real spread --seeds 1,2,3,4 --out docs/bench/real_spread.md

Another model (a stronger Whisper, say) is a variant, kept in its own cache and never mixed with the shipped one:

    python -m tools.speech.bench_real recognise --model PATH/faster-whisper-small --tag small
    python -m tools.speech.bench_real tune --tag small          # its own thresholds, on dev
    python -m tools.speech.bench_real frontier --tag small      # what it could reach on test

This is the command line; the stages live beside it: tools/speech/real_cache.py (recognise, the cache, the
counts), real_tune.py (tune, frontier, stays, guard, gate, second-ear), real_report.py (report, variants, spread)
and real_timing.py (timing).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tools.speech import real_cache
from tools.speech.real_cache import CACHE_DIR, DEFAULT_MODEL, ENGINES, REPO, cache_path, load_cache, model_identity, recognise
from tools.speech.real_report import DOC, SPREAD_CONDITIONS, VARIANTS_DOC, report, spread, variants_report
from tools.speech.real_speech import CONDITIONS
from tools.speech.real_timing import live_timing, timing
from tools.speech.real_tune import TUNED, frontier, gate, guard, second_ear, stays, tune


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.bench_real", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="stage", required=True)
    rec = sub.add_parser("recognise", help="recognise every real file under every condition (cached)")
    rec.add_argument("--engine", choices=sorted(ENGINES), default="whisper-score")
    rec.add_argument("--model", default=str(DEFAULT_MODEL),
                     help="a faster-whisper model folder (default: ../shared's Whisper base); another model is a "
                          "variant and needs --tag")
    rec.add_argument("--conditions", default=",".join(CONDITIONS))
    rec.add_argument("--split", choices=("dev", "test"))
    rec.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override an engine setting of asr/engines.toml for this run (use with --tag)")
    tun = sub.add_parser("tune", help="choose the engine's rejection threshold on the dev split")
    fro = sub.add_parser("frontier", help="the most commands right any threshold could keep within the targets on "
                                          "test (chosen on test itself: an upper bound; also a section of `report`)")
    for stage in (rec, tun, fro):
        stage.add_argument("--tag", default="", help="a variant's cache, kept apart: out/bench/real/<engine>-<tag>.jsonl "
                                                     "(tune: choose on it; --write is refused)")
    tun.add_argument("--engine", choices=sorted(TUNED), default="whisper-score")
    tun.add_argument("--write", action="store_true", help="write the chosen value into thresholds.toml")
    rep = sub.add_parser("report", help="write docs/bench/real.md from the caches")
    rep.add_argument("--engines", default=",".join(ENGINES))
    sub.add_parser("gate", help="what a floor on Whisper's confidence in its own transcript would cost and save")
    grd = sub.add_parser("guard", help="what the weak-match guard costs on real English, and its value")
    grd.add_argument("--write", action="store_true", help="write the chosen min_shared into thresholds.toml")
    sub.add_parser("second-ear", help="what PocketSphinx vetoing Whisper's actions would cost and save (not shipped)")
    sub.add_parser("stays", help="rejected utterances nearest a stop, by what was said (the pause's STAY rule)")
    spr = sub.add_parser("spread", help="how far the noisy figures move with the noise segment drawn (other seeds)")
    spr.add_argument("--seeds", default="1,2,3,4", help="noise seeds besides the shipped one")
    spr.add_argument("--conditions", default=",".join(SPREAD_CONDITIONS))
    spr.add_argument("--split", choices=("dev", "test"), default="test")
    spr.add_argument("--out", type=Path, help="also write the section to this file (docs/bench/real_spread.md)")
    tim = sub.add_parser("timing", help="decision time on clean test files (run on an idle machine)")
    tim.add_argument("--engine", choices=sorted(ENGINES), default="whisper-score")
    tim.add_argument("--model", default=str(DEFAULT_MODEL))
    tim.add_argument("--n", type=int, default=60)
    tim.add_argument("--hogs", type=int, default=0,
                     help="busy-loop processes beside the file timing (2: both cores of this machine busy)")
    tim.add_argument("--out", type=Path, help="also write the section to this file (docs/bench/real_timing.md)")
    tim.add_argument("--live", action="store_true", help="the microphone path in real time (segmenter + voice thread)")
    tim.add_argument("--no-speculate", action="store_true", help="with --live: decide only once the utterance closed")
    tim.add_argument("--vad-settings", type=Path, help="with --live: a segmenter settings file (to compare settings)")
    args = parser.parse_args(argv)
    real_cache._TAG = f"-{args.tag}" if getattr(args, "tag", "") else ""
    if args.stage == "recognise":
        if (args.engine.startswith("whisper") and not real_cache._TAG
                and model_identity(args.model) != model_identity(str(DEFAULT_MODEL))):
            parser.error("another model than the shipped figures' is a variant: give it --tag NAME, so that its "
                         "recognitions are kept apart (then tune --tag NAME, frontier --tag NAME)")
        unknown = set(args.conditions.split(",")) - set(CONDITIONS)
        if unknown:
            parser.error(f"unknown conditions {sorted(unknown)} (known: {', '.join(CONDITIONS)})")
        overrides = {}
        for item in args.set:
            key, _, value = item.partition("=")
            if not key or not value:
                parser.error(f"--set {item!r}: expected KEY=VALUE")
            try:
                overrides[key] = float(value)
            except ValueError:
                overrides[key] = value  # a word setting, such as score_rank_by=mean
        recognise(args.engine, args.model if args.engine.startswith("whisper") else None,
                  args.conditions.split(","), args.split, overrides)
        return 0
    if args.stage == "tune":
        if args.write and real_cache._TAG:
            parser.error("--write chooses the shipped thresholds: tune a variant (--tag) without it")
        return tune(args.engine, args.write)
    if args.stage == "timing":
        if args.live and args.hogs:
            parser.error("--hogs loads the file timing; the microphone path under load is tools.listen.bench_stop_latency")
        model = args.model if args.engine.startswith("whisper") else None
        text = (live_timing(args.engine, model, args.n, not args.no_speculate, args.vad_settings) if args.live
                else timing(args.engine, model, args.n, args.hogs))
        print(text)
        if args.out:
            appended = args.live or args.hogs  # the idle file timing starts the file; the others follow it
            with open(args.out, "a" if appended else "w", encoding="utf-8") as out:
                out.write(("\n" if appended else "") + text)
        return 0
    if args.stage == "guard":
        print(guard(args.write))
    if args.stage == "gate":
        print(gate())
        return 0
    if args.stage == "second-ear":
        print(second_ear())
        return 0
    if args.stage == "spread":
        try:
            seeds = [int(x) for x in args.seeds.split(",") if x.strip()]
        except ValueError:
            parser.error(f"--seeds {args.seeds!r}: expected whole numbers, such as 1,2,3")
        conditions = args.conditions.split(",")
        unknown = set(conditions) - set(CONDITIONS)
        if unknown:
            parser.error(f"unknown conditions {sorted(unknown)} (known: {', '.join(CONDITIONS)})")
        bad = [c for c in conditions if CONDITIONS[c][0] is None]
        if bad:
            parser.error(f"--conditions: {', '.join(bad)} draws no noise (noisy ones: "
                         f"{', '.join(c for c, (stem, _) in CONDITIONS.items() if stem)})")
        text = spread(seeds, conditions, args.split)
        print(text)
        if args.out:
            args.out.write_text("# Real people: how far the noisy figures move with the noise segment drawn\n\n" + text,
                                encoding="utf-8")
        return 0
    if args.stage == "stays":
        print(stays())
        return 0
    if args.stage == "frontier":
        if not load_cache("whisper-score"):
            print(f"bench_real: error: no recognitions in {cache_path('whisper-score').relative_to(REPO)} "
                  f"(run `python -m tools.speech.bench_real recognise{' --tag ' + args.tag if args.tag else ''}` first)",
                  file=sys.stderr)
            return 2
        print(frontier())
        return 0
    from tools.report import header

    DOC.parent.mkdir(parents=True, exist_ok=True)
    DOC.write_text(header("tools.speech.bench_real", argv) + report(args.engines.split(",")), encoding="utf-8")
    print(f"wrote {DOC.relative_to(REPO)}")
    variants = variants_report()
    if variants is None:
        print(f"no variant caches ({CACHE_DIR.relative_to(REPO)}/whisper-score-TAG.jsonl): "
              f"{VARIANTS_DOC.relative_to(REPO)} left as it is")
    else:
        VARIANTS_DOC.write_text(variants, encoding="utf-8")
        print(f"wrote {VARIANTS_DOC.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
