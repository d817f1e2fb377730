"""The domain ear on real speakers it never heard: accuracy with and without it, its thresholds, unseen noises.

    python -m tools.speech.ear_rows --split test && python -m tools.speech.ear_rows --split dev
    python -m tools.speech.bench_ear tune [--write]   # vouch / veto on the dev speakers (out-of-fold ears)
    python -m tools.speech.bench_ear report           # docs/bench/ear.md

``report`` judges the held-out speakers over the second half of each noise with the shipped ear, and each noise
again with an ear trained without that noise at all (trained here from the cached training features of
``python -m tools.speech.train_ear``, same seed). ``tune`` chooses ``[ear.whisper-score]`` on the dev speakers,
with ears that never heard the speaker judged (5 folds by speaker), so the choice is not made on trained-on audio.
"""

from __future__ import annotations

import argparse
import hashlib
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path


from gcs_voice.asr.ear import NONE, DomainEar
from gcs_voice.domain.dictionary import load_language
from gcs_voice.domain.text import normalize_text
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher
from gcs_voice.understanding.thresholds import THRESHOLDS_PATH, ear_limits
from tools.speech.ear_data import EVAL_CONDITIONS, NOISES, UNSEEN_WORDS, Clip, clip_audio, condition_audio, real_clips
from tools.speech.ear_rows import DEV_CONDITIONS, NOISE_SEED, decode_vector, half_of, load_rows, recognition
from tools.speech.train_ear import SEED, Example, featurise, train, training_clips

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "bench" / "ear.md"
FOLDS = 5
#: the grid ``tune`` searches (vouch: probability of Whisper's first class that waives the score rules; veto:
#: probability of the decided class under which the action is refused; 0 = no veto)
VOUCH = (0.5, 0.7, 0.8, 0.9, 0.95, 0.98, 1.01)
VETO = (0.0, 0.02, 0.05, 0.1)
#: alone: probability of the ear's own class that puts that class first among Whisper's phrases (1.01 = never)
ALONE = (0.95, 0.98, 0.995, 1.01)
#: the fraction of the dev speakers' stops (every condition) a held motion must stay stopped for, of those a hold can
#: keep (decided a stop, or rejected and kept by the hold; one decided as another command is that command): the
#: issue's 95 % for real stops. On the dev speakers a margin above it (98 %) was bought by two stops in 72, heard in
#: noise as "That" and "Spill." and by the ear as "up" and "down", and kept the motion stopped after twice as much
#: other speech (59 of 580 against 31, issue 52)
STOP_KEPT = 0.95
SPOTTED_STOP = (0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5)
#: nearest_stop: the ear's "stop" that keeps a held motion stopped when Whisper's best-scored phrase is a stop
NEAREST_STOP = (0.0, 0.01, 0.02, 0.05, 0.1)
#: limit on dev: other speech acted on (a fraction, overall and clean); and no more wrong actions than without the ear
DEV_OTHER = 0.01


@dataclass
class Tally:
    """Decisions of one condition: commands right / wrong / no action, other speech acted on."""

    commands: int = 0
    right: int = 0
    wrong: int = 0
    other: int = 0
    other_acted: int = 0
    unseen: int = 0
    unseen_acted: int = 0
    sentences: int = 0
    sentences_acted: int = 0
    wrongs: list[str] = field(default_factory=list)

    def add(self, clip: Clip, action: str | None, heard: str) -> None:
        if clip.label != NONE:
            self.commands += 1
            self.right += action == clip.label
            if action is not None and action != clip.label:
                self.wrong += 1
                self.wrongs.append(f"{clip.word}->{action} ('{heard}')")
            return
        self.other += 1
        self.other_acted += action is not None
        if clip.kind == "sentence":
            self.sentences += 1
            self.sentences_acted += action is not None
        elif clip.word in UNSEEN_WORDS:
            self.unseen += 1
            self.unseen_acted += action is not None
        if action is not None:
            self.wrongs.append(f"[{clip.word}]->{action} ('{heard}')")

    def objective(self) -> float:
        return self.right - 3 * self.wrong - 2 * self.other_acted


def thresholds_with(vouch: float | None, veto: float | None, directory: Path, alone: float | None = None) -> Path:
    """A copy of thresholds.toml whose [ear.whisper-score] says these values (None: the key left out)."""
    text = THRESHOLDS_PATH.read_text(encoding="utf-8")
    text = re.sub(r"\n\[ear\.whisper-score\]\n(?:[^\[\n].*\n|\n)*", "\n", text)
    lines = ["[ear.whisper-score]"] + [f"{k} = {v}" for k, v in (("vouch", vouch), ("veto", veto), ("alone", alone))
                                       if v is not None]
    path = directory / f"thresholds-{vouch}-{veto}-{alone}.toml"
    path.write_text(text.rstrip("\n") + "\n\n" + "\n".join(lines) + "\n", encoding="utf-8")
    return path


def judge(rows: dict[str, dict], clips: list[Clip], conditions: list[str], ear_of: Callable[[Clip, str], DomainEar | None],
          thresholds: Path) -> dict[str, Tally]:
    """Each clip's decision under each condition, with the ear ``ear_of(clip, condition)`` (None: no ear)."""
    matcher = get_matcher(DEFAULT_MATCHER, thresholds_path=thresholds)
    dictionary = load_language("en")
    out: dict[str, Tally] = {}
    for cond in conditions:
        tally = out.setdefault(cond, Tally())
        for clip in clips:
            row = rows.get(f"{clip.key}|{cond}")
            if row is None:
                continue
            ear = ear_of(clip, cond)
            evidence = ear.evidence(decode_vector(row["features"])) if ear is not None else None
            decision = matcher.decide(recognition(row, evidence), [dictionary])
            tally.add(clip, decision.action, row["transcript"])
    return out


def fold_of(clip: Clip) -> int:
    return int(hashlib.sha1(f"ear-fold:{clip.speaker}".encode()).hexdigest(), 16) % FOLDS


def out_of_fold_ears(examples: list[Example], seed: int) -> list[DomainEar]:
    """One ear per speaker fold, trained without that fold's real speakers."""
    classes = (NONE,) + tuple(sorted({e.clip.label for e in examples} - {NONE}))
    ears = []
    for k in range(FOLDS):
        kept = [e for e in examples if e.clip.source != "real" or fold_of(e.clip) != k]
        ears.append(train(kept, seed, classes)[0])
    return ears


def without_noise_ears(examples: list[Example], seed: int) -> dict[str, DomainEar]:
    """One ear per noise, trained on everything but that noise: a noise it never heard."""
    classes = (NONE,) + tuple(sorted({e.clip.label for e in examples} - {NONE}))
    return {name: train([e for e in examples if e.noise != name], seed, classes)[0] for name in NOISES}


def training_examples(seed: int) -> list[Example]:
    return featurise(training_clips(seed, False), seed, False)


def tune(seed: int, write: bool) -> int:
    rows = load_rows()
    clips = [c for c in real_clips() if c.split == "dev"]
    ears = out_of_fold_ears(training_examples(seed), seed)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        base = judge(rows, clips, list(DEV_CONDITIONS), lambda c, cond: None, thresholds_with(None, None, Path(tmp)))
        for vouch in VOUCH:
            for veto in VETO:
                for alone in ALONE:
                    path = thresholds_with(vouch, veto, Path(tmp), alone)
                    tallies = judge(rows, clips, list(DEV_CONDITIONS), lambda c, cond: ears[fold_of(c)], path)
                    results.append((vouch, veto, alone, tallies))
    def total(t: dict[str, Tally], attr: str) -> int:
        return sum(getattr(x, attr) for x in t.values())

    def within(t: dict[str, Tally]) -> bool:
        return (total(t, "wrong") <= total(base, "wrong")
                and total(t, "other_acted") <= DEV_OTHER * total(t, "other")
                and t["clean"].other_acted <= DEV_OTHER * t["clean"].other)

    print(f"dev speakers, {', '.join(DEV_CONDITIONS)} (first half of each noise), out-of-fold ears")
    print(f"without the ear: right {total(base, 'right')}/{total(base, 'commands')}, wrong {total(base, 'wrong')}, "
          f"other acted {total(base, 'other_acted')}/{total(base, 'other')}")
    print("vouch\tveto\talone\tright\twrong\tother acted\twithin")
    for vouch, veto, alone, t in results:
        print(f"{vouch}\t{veto}\t{alone}\t{total(t, 'right')}\t{total(t, 'wrong')}\t{total(t, 'other_acted')}"
              f"\t{within(t)}")
    fit = [r for r in results if within(r[3])]
    if not fit:
        print("no setting within the dev limits")
        return 1
    # the best objective; among equals the strictest (a higher vouch and alone, a higher veto)
    vouch, veto, alone, t = max(fit, key=lambda r: (sum(x.objective() for x in r[3].values()), r[0], r[2], r[1]))
    print(f"chosen: vouch {vouch}, veto {veto}, alone {alone}: right {total(t, 'right')}, wrong {total(t, 'wrong')}, "
          f"other acted {total(t, 'other_acted')}")
    with tempfile.TemporaryDirectory() as tmp:
        spotted, nearest = spotted_stop(rows, clips, ears, thresholds_with(vouch, veto, Path(tmp), alone))
    if write:
        write_ear_limits({"vouch": vouch, "veto": veto, "alone": alone, "spotted_stop": spotted,
                          "nearest_stop": nearest})
    return 0


def write_ear_limits(values: dict[str, float]) -> None:
    """Set these keys of ``[ear.whisper-score]`` in thresholds.toml, its comments kept."""
    text = THRESHOLDS_PATH.read_text(encoding="utf-8")
    for key, value in values.items():
        text = re.sub(rf"(\[ear\.whisper-score\](?:\n[^\[].*)*?\n){key} = [^\n]*", rf"\g<1>{key} = {value}", text)
    THRESHOLDS_PATH.write_text(text, encoding="utf-8")
    print(f"wrote {', '.join(f'{k} = {v}' for k, v in values.items())} into {THRESHOLDS_PATH}")


@dataclass
class Holds:
    """The utterances the stop spotter fires on (only those are ever held), and how their holds can settle."""

    stops: int = 0          # real stops among them
    decided_stops: int = 0  # ... that the decision took as a stop
    #: those the decision rejected: (a real stop, Whisper wrote a stop phrase, its best phrase is one, ear p(stop))
    rejected: list[tuple[bool, bool, bool, float]] = field(default_factory=list)

    def kept(self, spotted: float, nearest: float) -> tuple[int, int]:
        """Real stops and other utterances a held motion stays stopped for (VoicePipeline.settle_pause's rule)."""
        from gcs_voice.session.listen import stays_stopped

        def stays(wrote: bool, best: bool, p: float) -> bool:
            return stays_stopped(wrote, best, p, True, spotted, nearest)
        return (sum(stays(*r[1:]) for r in self.rejected if r[0]),
                sum(stays(*r[1:]) for r in self.rejected if not r[0]))

    def line(self, spotted: float, nearest: float) -> str:
        stops, others = self.kept(spotted, nearest)
        rejected_stops = sum(r[0] for r in self.rejected)
        return (f"{stops}/{rejected_stops} | {self.decided_stops + stops}/{self.stops} | "
                f"{others}/{len(self.rejected) - rejected_stops}")


def holds(rows: dict[str, dict], clips: list[Clip], conditions: list[str], ear_of: Callable[[Clip], DomainEar],
          thresholds: Path) -> Holds:
    """What a hold could be settled on, for every clip the shipped stop spotter fires on in each condition."""
    matcher = get_matcher(DEFAULT_MATCHER, thresholds_path=thresholds)
    dictionary = load_language("en")
    stop_words = {p.match_key for p in dictionary.phrases if p.action == "stop"}
    from gcs_voice.asr.stop_spotter import load_stop_spotter

    spotter = load_stop_spotter(["en"])
    out = Holds()
    for cond in conditions:
        for clip in clips:
            row = rows.get(f"{clip.key}|{cond}")
            if row is None:
                continue
            evidence = ear_of(clip).evidence(decode_vector(row["features"]))
            action = matcher.decide(recognition(row, evidence), [dictionary]).action
            if not spotter.spot(_pcm(condition_audio(clip, clip_audio(clip), *EVAL_CONDITIONS[cond], half_of(clip),
                                                     NOISE_SEED))).fired:
                continue
            out.stops += clip.label == "stop"
            out.decided_stops += clip.label == "stop" and action == "stop"
            if action is not None:
                continue
            best = normalize_text(row["hypotheses"][0][0]) if row["hypotheses"] else ""
            out.rejected.append((clip.label == "stop", normalize_text(row["transcript"]) in stop_words,
                                 best in stop_words, evidence["ear:stop"]))
    return out


def spotted_stop(rows: dict[str, dict], clips: list[Clip], ears: list[DomainEar],
                 thresholds: Path) -> tuple[float, float]:
    """``spotted_stop`` and ``nearest_stop`` (gcs_voice.session.listen.VoicePipeline.settle_pause): of the settings
    that keep STOP_KEPT of the dev speakers' real stops stopped that a hold can keep (decided a stop, or rejected and
    kept by the hold), the one that keeps the fewest other utterances stopped (on a tie the lower), among the
    utterances the stop spotter fires on (only those are ever held); printed with what each costs."""
    found = holds(rows, clips, list(DEV_CONDITIONS), lambda c: ears[fold_of(c)], thresholds)
    rejected_stops = sum(r[0] for r in found.rejected)
    print(f"dev utterances the spotter fires on: {found.stops} stops ({found.decided_stops} decided a stop, "
          f"{rejected_stops} rejected), {len(found.rejected) - rejected_stops} others rejected")
    print("spotted_stop | nearest_stop | real stops rejected, kept stopped | all stops stopped | other rejected, kept stopped")
    fit = []
    for t in SPOTTED_STOP:
        for t2 in NEAREST_STOP:
            print(f"{t} | {t2} | {found.line(t, t2)}")
            kept, held = found.kept(t, t2)
            if found.decided_stops + kept >= STOP_KEPT * (found.decided_stops + rejected_stops):
                fit.append((held, t, t2))
    held, t, t2 = min(fit)
    print(f"spotted_stop {t}, nearest_stop {t2}: other utterances kept stopped {held}")
    return t, t2


def _pcm(audio) -> bytes:
    import numpy as np

    return (np.clip(audio, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()


def _cell(t: Tally) -> str:
    return (f"{t.right}/{t.commands} ({100 * t.right / max(1, t.commands):.1f} %) | {t.wrong} | "
            f"{t.other_acted}/{t.other} | {t.unseen_acted}/{t.unseen} | {t.sentences_acted}/{t.sentences}")


def report(seed: int) -> str:
    rows = load_rows()
    clips = [c for c in real_clips() if c.split == "test"]
    shipped = DomainEar.load()
    if shipped is None:
        raise SystemExit("bench_ear: no shipped ear (python -m tools.speech.train_ear)")
    conditions = list(EVAL_CONDITIONS)
    with_ear = judge(rows, clips, conditions, lambda c, cond: shipped, THRESHOLDS_PATH)
    without = judge(rows, clips, conditions, lambda c, cond: None, THRESHOLDS_PATH)
    unheard_ears = without_noise_ears(training_examples(seed), seed)
    unheard = judge(rows, clips, [c for c in conditions if EVAL_CONDITIONS[c][0]],
                    lambda c, cond: unheard_ears[EVAL_CONDITIONS[cond][0]], THRESHOLDS_PATH)
    lines = [
        "# The domain ear on held-out real speakers",
        "",
        f"Held-out speakers of ../shared/speech ({sum(c.label != NONE for c in clips)} commands, "
        f"{sum(c.label == NONE for c in clips)} other utterances: non-command words and sentences), each noise's "
        "second half (the ear trained on the first). Whisper base, scoring mode, phonetic matcher, thresholds.toml "
        f"as shipped; the ear gcs_voice/asr/ear_model.npz ({shipped.meta.get('examples')} examples, seed "
        f"{shipped.meta.get('seed')}). Decisions come from cached recognitions (machine load does not move them). "
        "'unseen words': non-command word types no ear was trained on "
        f"({', '.join(sorted(UNSEEN_WORDS))}).",
        "",
        "| condition | ear | commands right | wrong | other speech acted on | unseen words acted on | sentences acted on |",
        "|---|---|---|---|---|---|---|",
    ]
    for cond in conditions:
        lines.append(f"| {cond} | shipped | {_cell(with_ear[cond])} |")
        if cond in unheard:
            lines.append(f"| {cond} | never heard this noise | {_cell(unheard[cond])} |")
        lines.append(f"| {cond} | none | {_cell(without[cond])} |")
    lines += ["", "Wrong actions and other speech acted on, with the shipped ear:", ""]
    for cond in conditions:
        if with_ear[cond].wrongs:
            lines.append(f"- {cond}: " + "; ".join(with_ear[cond].wrongs))
    limits = ear_limits("whisper-score")
    found = holds(rows, clips, conditions, lambda c: shipped, THRESHOLDS_PATH)
    lines += [
        "", "## A motion held by the stop spotter, after speech that was not understood", "",
        f"Every held-out utterance above that the shipped stop spotter fires on ({found.stops} real stops among them, "
        f"{found.decided_stops} decided a stop). Of those the decision rejected, the held motion stays stopped when "
        "Whisper wrote a stop, or ranked a stop first and the ear gives \"stop\" at least `nearest_stop`, or the ear "
        "gives it at least `spotted_stop` (gcs_voice.session.listen.VoicePipeline.settle_pause).", "",
        "| spotted_stop | nearest_stop | real stops rejected, kept stopped | all real stops stopped | "
        "other speech rejected, kept stopped |", "|---|---|---|---|---|",
        f"| {limits['spotted_stop']:g} | {limits['nearest_stop']:g} (shipped) | "
        f"{found.line(limits['spotted_stop'], limits['nearest_stop'])} |",
        f"| 0.02 | 0 (keeps every dev stop) | {found.line(0.02, 0.0)} |",
    ]
    return "\n".join(lines) + "\n"


def timing(n: int = 40) -> str:
    """What the ear adds to a decision: its own encoder pass and classifier, per held-out command (wall ms)."""
    import time

    from gcs_voice.asr.registry import load_recognizer
    from tools.speech.ear_rows import DEFAULT_MODEL
    from tools.speech.real_speech import load_recordings, read_wav

    recognizer = load_recognizer("whisper", [load_language("en")], model=str(DEFAULT_MODEL), mode="score")
    spent = []
    for rec in [r for r in load_recordings(split="test") if r.kind == "command"][:n]:
        audio = read_wav(rec.path)
        started = time.perf_counter()
        recognizer.hear(audio)
        spent.append((time.perf_counter() - started) * 1000)
    spent.sort()
    return (f"The ear's time per utterance (its encoder pass on the utterance alone, and the classifier), {len(spent)} "
            f"held-out commands: median {spent[len(spent) // 2]:.0f} ms, p95 {spent[int(0.95 * (len(spent) - 1))]:.0f} ms.")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.bench_ear", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="stage", required=True)
    tun = sub.add_parser("tune", help="choose vouch and veto on the dev speakers")
    tun.add_argument("--write", action="store_true", help="write them into thresholds.toml")
    rep = sub.add_parser("report", help="judge the held-out speakers (and time the ear); write docs/bench/ear.md")
    rep.add_argument("--out", type=Path, default=DOC)
    for p in (tun, rep):
        p.add_argument("--seed", type=int, default=SEED)
    args = parser.parse_args(argv)
    if args.stage == "tune":
        return tune(args.seed, args.write)
    from tools.report import header

    text = header("tools.speech.bench_ear", argv) + report(args.seed) + "\n" + timing() + "\n"
    print(text)
    args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
