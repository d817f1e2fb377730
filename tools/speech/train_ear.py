"""Train the domain ear from scratch: one command, a fixed seed, two CPU cores, minutes.

    python -m tools.speech.train_ear                 # writes gcs_voice/asr/ear_model.npz and ear_over_voice.npz
    python -m tools.speech.train_ear --tiny --out /tmp/ear.npz   # what CI runs: a few clips, checks it learns

What it learns from (tools/speech/ear_data.py): the dev speakers of ../shared/speech, clean and over the FIRST
half of each real noise at 20, 12 and 6 dB; every phrase of the English and Spanish dictionaries (with fillers
before some and amounts after some) and other speech, said by espeak-ng and Piper voices that no held-out
benchmark uses, clean and over the same noise halves; and stretches of those noise halves alone (as "none": the
room is no command). The over-voice ear (which settles a stop spotted while the bridge speaks) learns all that and
half of the bridge's own cues as the echo canceller leaves them, alone ("none") and with a dev speaker's word said
over them (that word; tools/speech/ear_cues.py). Never the held-out speakers, the second halves, or the
non-command word types kept unseen. Features are cached in out/ear/ (delete it to start from nothing).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.asr.ear import EAR_OVER_VOICE_PATH, EAR_PATH, NONE, DomainEar
from tools.speech.real_speech import SHARED
from tools.speech.ear_data import (NOISES, TRAIN_SNRS, Clip, clip_audio, condition_audio, cue_plan, features,
                                   noise_plan, over_cue_plan, real_clips, synthetic_plan, trainable)
from tools.speech.ear_rows import decode_vector, encode_vector

REPO = Path(__file__).resolve().parents[2]
CACHE_DIR = REPO / "out" / "ear"
DEFAULT_MODEL = SHARED / "models" / "faster-whisper-base"
SEED = 1
#: L2 penalty on the standardised weights, and the optimiser's steps (chosen on the dev speakers, out of fold: fewest
#: confident mistakes; more steps overfit)
L2 = 0.03
STEPS = 300
#: a real utterance counts this many times a synthetic one (real voices are what the ear must hear)
REAL_WEIGHT = 2.0
#: scenes of each trained cue heard alone, and of each real dev "stop" said over a cue (the others: one)
CUE_TAKES = 4
STOP_OVER_CUE_TAKES = 6
#: in the over-voice ear, a cue alone weighs this many times another "none" example: its remains are a small part of
#: all "none", and the stops said over cues teach "this sound is a stop" unless they weigh in. Chosen on dev scenes by
#: ``python -m tools.listen.bench_settle --split dev --cue-weights 5,20,50,100,200,500``: every dev stop over a cue
#: keeps its hold at each weight; 100 lets go of most cues (9 of the 23 the spotter fired on kept; 200, 500 the same)
CUE_WEIGHT = 100.0


@dataclass(frozen=True)
class Example:
    """One training vector: the clip it came from, the noise it was mixed with (None: clean)."""

    clip: Clip
    noise: str | None
    snr: float | None
    vector: np.ndarray


def versions(clip: Clip, rng: np.random.Generator, tiny: bool) -> list[tuple[str | None, float | None]]:
    """The conditions a training clip is heard in: clean, and over the first half of the noises."""
    if tiny or clip.source == "noise" or clip.over is not None:  # over the bridge's voice: its scene has the room
        return [(None, None)]
    if clip.source == "real":
        return [(None, None)] + [(n, snr) for n in NOISES for snr in TRAIN_SNRS]
    names = list(NOISES)
    return [(None, None)] + [(names[int(rng.integers(len(names)))], float(rng.choice(TRAIN_SNRS))) for _ in range(2)]


def training_clips(seed: int, tiny: bool) -> list[Clip]:
    """The clips the ear learns from (see the module's docstring); ``tiny``: a handful, for CI."""
    real = [c for c in real_clips() if trainable(c)]
    if tiny:
        wanted = ("up", "stop", "go_left", NONE)
        real = [next(c for c in real if c.label == label and c.kind != "sentence") for label in wanted]
        synthetic = [c for c in synthetic_plan(seed, takes=1, langs=("en",), natural=False)
                     if c.word in ("up", "stop", "left", "go left", "hello", "water")]
        return real + synthetic
    return real + synthetic_plan(seed) + noise_plan(seed)


def over_voice_clips(clips: list[Clip], seed: int, tiny: bool) -> list[Clip]:
    """What the over-voice ear learns besides ``clips`` (tools.speech.ear_cues): the bridge's cues alone as the echo
    canceller leaves them ("none"), and words of ``clips`` said over them (that word; every dev stop several times)."""
    real = [c for c in clips if c.source == "real"]
    if tiny:
        first_stop = [c for c in real if c.label == "stop"][:1]
        return cue_plan(seed, takes=1, langs=("en",))[:1] + over_cue_plan(first_stop, seed)
    stops = [c for c in real if c.label == "stop"]
    words = [c for c in real if c.label != "stop" and c.kind != "sentence"]
    said_stops = [c for c in clips if c.source == "synthetic" and c.label == "stop" and c.kind == "command"]
    return (cue_plan(seed, takes=CUE_TAKES) + over_cue_plan(stops, seed, takes=STOP_OVER_CUE_TAKES)
            + over_cue_plan(words + said_stops, seed))


def featurise(clips: list[Clip], seed: int, tiny: bool, model: Path = DEFAULT_MODEL,
              cache: Path | None = None) -> list[Example]:
    """Every clip in each of its versions, as the ear's feature vector (cached by clip and version)."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.domain.dictionary import load_language

    cache = cache or CACHE_DIR / f"train-seed{seed}{'-tiny' if tiny else ''}.jsonl"
    known: dict[str, np.ndarray] = {}
    if cache.is_file():
        for line in cache.read_text(encoding="utf-8").splitlines():
            row = json.loads(line)
            known[row["key"]] = decode_vector(row["features"])
    recognizer = load_recognizer("whisper", [load_language("en")], model=str(model), mode="score")
    rng = np.random.default_rng(seed)
    out: list[Example] = []
    cache.parent.mkdir(parents=True, exist_ok=True)
    t0, made = time.time(), 0
    with open(cache, "a", encoding="utf-8") as fh:
        for i, clip in enumerate(clips):
            plan = versions(clip, rng, tiny)
            keys = [f"{clip.key}|{n}|{s}" for n, s in plan]
            audio = None if all(k in known for k in keys) else clip_audio(clip, seed)
            for key, (noise, snr) in zip(keys, plan):
                if key not in known:
                    heard = condition_audio(clip, audio, noise, snr, "train", seed)
                    known[key] = features(recognizer.model.encode, recognizer.log_mel, heard)
                    fh.write(json.dumps({"key": key, "features": encode_vector(known[key])}) + "\n")
                    made += 1
                # a stretch of noise alone counts as that noise (an ear that never heard it never heard it alone)
                out.append(Example(clip, clip.speaker if clip.source == "noise" else noise, snr, known[key]))
            if i % 200 == 0:
                print(f"  featurised {i}/{len(clips)} clips ({made} new, {time.time() - t0:.0f} s)", file=sys.stderr)
    return out


def fit(x: np.ndarray, labels: list[str], weights: np.ndarray, classes: tuple[str, ...], seed: int,
        l2: float = L2, steps: int = STEPS) -> tuple[DomainEar, list[float]]:
    """A multinomial logistic regression on standardised features (full-batch Adam, fixed seed).

    Returns the ear and the training loss at each step (CI checks that it falls)."""
    rng = np.random.default_rng(seed)
    mean = x.mean(axis=0)
    scale = x.std(axis=0) + 1e-3
    z = (x - mean) / scale
    index = {c: i for i, c in enumerate(classes)}
    y = np.array([index[label] for label in labels])
    onehot = np.eye(len(classes), dtype=np.float32)[y]
    w = (rng.standard_normal((z.shape[1], len(classes))) * 1e-3).astype(np.float32)
    b = np.zeros(len(classes), np.float32)
    sw = (weights / weights.sum()).astype(np.float32)[:, None]
    m = [np.zeros_like(w), np.zeros_like(b)]
    v = [np.zeros_like(w), np.zeros_like(b)]
    lr, beta1, beta2 = 0.01, 0.9, 0.999
    losses = []
    for step in range(1, steps + 1):
        logits = z @ w + b
        logits -= logits.max(axis=1, keepdims=True)
        p = np.exp(logits)
        p /= p.sum(axis=1, keepdims=True)
        losses.append(float(-(sw[:, 0] * np.log(p[np.arange(len(y)), y] + 1e-12)).sum() + 0.5 * l2 * (w * w).sum()))
        grad_logits = (p - onehot) * sw
        grads = [z.T @ grad_logits + l2 * w, grad_logits.sum(axis=0)]
        for k, (param, g) in enumerate(zip((w, b), grads)):
            m[k] = beta1 * m[k] + (1 - beta1) * g
            v[k] = beta2 * v[k] + (1 - beta2) * g * g
            param -= lr * (m[k] / (1 - beta1 ** step)) / (np.sqrt(v[k] / (1 - beta2 ** step)) + 1e-8)
    return DomainEar(classes, mean.astype(np.float32), scale.astype(np.float32), w, b, {}), losses


def sample_weights(examples: list[Example]) -> np.ndarray:
    """Each class weighs the same in all, a real utterance REAL_WEIGHT times a synthetic one, and the bridge's cue
    alone CUE_WEIGHT times another "none"."""
    labels = [e.clip.label for e in examples]
    raw = np.array([REAL_WEIGHT if e.clip.source == "real" else CUE_WEIGHT if e.clip.source == "cue" else 1.0
                    for e in examples])
    total = {c: raw[[i for i, l in enumerate(labels) if l == c]].sum() for c in set(labels)}
    return np.array([raw[i] / total[labels[i]] for i in range(len(labels))])


def classes_of(examples: list[Example]) -> tuple[str, ...]:
    return (NONE,) + tuple(sorted({e.clip.label for e in examples} - {NONE}))


def train(examples: list[Example], seed: int, classes: tuple[str, ...] | None = None) -> tuple[DomainEar, list[float]]:
    """The ear fitted on ``examples``."""
    x = np.stack([e.vector for e in examples])
    return fit(x, [e.clip.label for e in examples], sample_weights(examples), classes or classes_of(examples), seed)


def model_bin_size(model: Path = DEFAULT_MODEL) -> int | None:
    path = Path(model) / "model.bin"
    return path.stat().st_size if path.is_file() else None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.speech.train_ear", description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--tiny", action="store_true", help="a few clips, clean only: CI's check that the recipe learns")
    parser.add_argument("--out", type=Path, default=EAR_PATH, help=f"where the ear is written (default {EAR_PATH})")
    parser.add_argument("--out-over-voice", type=Path,
                        help=f"where the over-voice ear is written (default: {EAR_OVER_VOICE_PATH.name} beside --out)")
    parser.add_argument("--model", type=Path, default=DEFAULT_MODEL, help="the Whisper base folder (faster-whisper)")
    args = parser.parse_args(argv)
    if not (args.model / "model.bin").is_file():
        parser.error(f"no Whisper model at {args.model} (give --model PATH/faster-whisper-base)")
    t0 = time.time()
    clips = training_clips(args.seed, args.tiny)
    examples = featurise(clips, args.seed, args.tiny, args.model)
    over = featurise(over_voice_clips(clips, args.seed, args.tiny), args.seed, args.tiny, args.model)
    over_out = args.out_over_voice or args.out.with_name(EAR_OVER_VOICE_PATH.name)
    for what, trained_on, out in (("ear", examples, args.out), ("over-voice ear", examples + over, over_out)):
        ear, losses = train(trained_on, args.seed)
        x = np.stack([e.vector for e in trained_on])
        predicted = [ear.classes[i] for i in ear.posteriors(x).argmax(axis=1)]
        fitted = np.mean([p == e.clip.label for p, e in zip(predicted, trained_on)])
        meta = {"seed": args.seed, "tiny": args.tiny, "clips": len({e.clip.key for e in trained_on}),
                "examples": len(trained_on), "real_examples": sum(e.clip.source == "real" for e in trained_on),
                "l2": L2, "steps": STEPS, "model_bin_size": model_bin_size(args.model),
                "train_accuracy": round(float(fitted), 4), "loss_first": round(losses[0], 4),
                "loss_last": round(losses[-1], 4)}
        if trained_on is not examples:
            meta["over_voice_examples"] = len(over)
        ear = DomainEar(ear.classes, ear.mean, ear.scale, ear.weights, ear.bias, meta)
        out.parent.mkdir(parents=True, exist_ok=True)
        ear.save(out)
        print(f"train_ear: {what}: {meta['clips']} clips, {len(trained_on)} examples ({meta['real_examples']} real), "
              f"{len(ear.classes)} classes; loss {losses[0]:.3f} -> {losses[-1]:.3f}; fits {fitted:.1%} of its "
              f"training set; {time.time() - t0:.0f} s; wrote {out} ({out.stat().st_size // 1024} KB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
