"""Live listening in noise: continuous streams of real speech over real noise, fed to ``gcs-voice recognize --segment``.

A microphone in a room hears commands and other talk at random pauses, over noise that never stops.
This builds such streams from the held-out test part of the real recordings: ``../shared/speech`` as
``tools.real_speech.load_recordings(split="test")`` splits it, the one speaker split of every
real-speech tool (this file has no split of its own), so no speaker heard here was heard by any tuning.
It mixes them over the real noises of ``../shared/noise`` at 20/12/6 dB SNR (speech level measured over
its voiced frames, noise over the whole track), writes the stream WAV
and a truth TSV, and feeds the stream to ``gcs-voice recognize --segment --json`` AS ONE FILE in a real
subprocess. Then it counts, per noise and SNR:

- commands right, wrong (another action), missed (no action);
- false actions: any action during non-command speech, or during noise alone.

    python -m tools.bench_stream                    # clean + kitchen 20/12/6 dB, 60 utterances each
    python -m tools.bench_stream --noises all       # the four real noises
    python -m tools.bench_stream --quick            # 12 utterances, clean + kitchen 12 dB
    python -m tools.bench_stream --vad energy       # the fallback segmenter, for comparison

Results are cached in ``out/bench/stream/`` keyed by the stream's bytes, the command and the digest of
the ``gcs_voice`` sources, so a rerun after no change costs nothing. Writes ``docs/bench/stream.md``
(``--out``) with the counts and the exact command.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shlex
import subprocess
import sys
import time
import wave
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tools.real_speech import SHARED, Recording, load_recordings

ROOT = Path(__file__).resolve().parent.parent
RATE = 16_000
NOISE_FILES = {"kitchen": "doing_the_dishes.wav", "tap": "running_tap.wav", "machine": "exercise_bike.wav",
               "cat": "dude_miaowing.wav"}
SNRS = (20.0, 12.0, 6.0)
SPEECH_DBFS = -26.0  # every utterance is brought to this voiced level: a person at a steady distance


@dataclass(frozen=True)
class Placed:
    """A clip placed in a stream: where its audio and its voiced part are, in seconds."""

    clip: Recording
    start_s: float
    end_s: float
    voiced_start_s: float
    voiced_end_s: float


def read_wav(path: Path) -> np.ndarray:
    with wave.open(str(path), "rb") as w:
        if w.getframerate() != RATE or w.getnchannels() != 1 or w.getsampwidth() != 2:
            raise SystemExit(f"bench_stream: {path} is not 16 kHz mono 16-bit")
        return np.frombuffer(w.readframes(w.getnframes()), "<i2").astype(np.float64) / 32768.0


def write_wav(path: Path, x: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(RATE)
        w.writeframes((np.clip(x, -1.0, 32767 / 32768) * 32768).astype("<i2").tobytes())


def voiced_frames(x: np.ndarray, frame: int = 320, below_peak_db: float = 25.0) -> np.ndarray:
    """Mask of 20 ms frames within ``below_peak_db`` of the loudest: the voiced part of a clip."""
    n = max(1, x.size // frame)
    rms = np.sqrt(np.mean(x[: n * frame].reshape(n, frame) ** 2, axis=1) + 1e-12)
    db = 20 * np.log10(rms)
    return db > db.max() - below_peak_db


def voiced_level(x: np.ndarray, frame: int = 320) -> tuple[float, int, int]:
    """RMS over the voiced frames, and the first and last voiced sample."""
    mask = voiced_frames(x, frame)
    idx = np.flatnonzero(mask)
    n = idx.size
    sel = np.concatenate([x[i * frame:(i + 1) * frame] for i in idx]) if n else x
    return float(np.sqrt(np.mean(sel**2))), int(idx[0] * frame) if n else 0, int((idx[-1] + 1) * frame) if n else x.size


def choose(clips: list[Recording], count: int, rng: np.random.Generator) -> list[Recording]:
    """70 % commands (every class represented), 15 % non-command words, 15 % sentences, shuffled."""
    by_kind = {k: [c for c in clips if c.kind == k] for k in ("command", "word", "sentence")}
    n_cmd = round(count * 0.7)
    n_word = (count - n_cmd) // 2
    n_sent = count - n_cmd - n_word
    picked = []
    for kind, n in (("command", n_cmd), ("word", n_word), ("sentence", n_sent)):
        pool = by_kind[kind]
        order = rng.permutation(len(pool))
        picked += [pool[i] for i in order[:n]] if n <= len(pool) else [pool[i % len(pool)] for i in rng.integers(0, len(pool), n)]
    return [picked[i] for i in rng.permutation(len(picked))]


def build_stream(clips: list[Recording], noise: np.ndarray | None, snr_db: float | None, seed: int,
                 pause_s: tuple[float, float] = (1.5, 6.0)) -> tuple[np.ndarray, list[Placed]]:
    """Clips at random pauses (seeded) over a noise track; each clip at SPEECH_DBFS over its voiced part."""
    rng = np.random.default_rng(seed)
    pieces, placed, t = [], [], 0
    lead = int(rng.uniform(*pause_s) * RATE)
    pieces.append(np.zeros(lead))
    t = lead
    for clip in clips:
        x = read_wav(clip.path)
        _, v0, v1 = voiced_level(x)
        x = at_speech_level(x)
        placed.append(Placed(clip, t / RATE, (t + x.size) / RATE, (t + v0) / RATE, (t + v1) / RATE))
        pause = int(rng.uniform(*pause_s) * RATE)
        pieces += [x, np.zeros(pause)]
        t += x.size + pause
    return under_noise(np.concatenate(pieces), noise, snr_db, rng), placed


def at_speech_level(x: np.ndarray) -> np.ndarray:
    """A clip brought to SPEECH_DBFS over its voiced frames: a person at a steady distance."""
    level, _, _ = voiced_level(x)
    return x * (10 ** (SPEECH_DBFS / 20) / max(level, 1e-6))


def under_noise(speech: np.ndarray, noise: np.ndarray | None, snr_db: float | None,
                rng: np.random.Generator) -> np.ndarray:
    """A stream of speech at SPEECH_DBFS with the noise (from a random point, looped) under all of it,
    ``snr_db`` below the speech's level; clean when either is None."""
    if noise is None or snr_db is None:
        return np.clip(speech, -1, 1)
    target = 10 ** (SPEECH_DBFS / 20)
    start = int(rng.integers(0, noise.size))
    track = np.resize(np.roll(noise, -start), speech.size)
    track = track * (target / 10 ** (snr_db / 20)) / max(float(np.sqrt(np.mean(track**2))), 1e-9)
    return np.clip(speech + track, -1, 1)


def write_truth(path: Path, placed: list[Placed]) -> None:
    rows = ["index\tstart_s\tend_s\tvoiced_start_s\tvoiced_end_s\ttruth\tkind\tpath"]
    rows += [f"{i}\t{p.start_s:.3f}\t{p.end_s:.3f}\t{p.voiced_start_s:.3f}\t{p.voiced_end_s:.3f}\t{p.clip.action or 'none'}\t"
             f"{p.clip.kind}\t{p.clip.path}" for i, p in enumerate(placed)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")


def source_digest() -> str:
    """Digest of the bridge's sources and data (the dictionaries too): a change in them invalidates the cached runs."""
    h = hashlib.sha256()
    import tomllib

    for p in sorted([*(ROOT / "gcs_voice").rglob("*"), *(ROOT / "dictionaries").glob("*.toml")]):
        if p.suffix in (".py", ".toml") and p.is_file():
            h.update(str(p.relative_to(ROOT)).encode())
            # TOML by its values: a comment edited in a settings file does not invalidate the runs
            h.update(json.dumps(tomllib.loads(p.read_text(encoding="utf-8")), sort_keys=True, default=str).encode()
                     if p.suffix == ".toml" else p.read_bytes())
    return h.hexdigest()[:16]


def recognize(wav: Path, args_extra: list[str], cache_dir: Path) -> tuple[list[dict], str, float]:
    """Run ``gcs-voice recognize --segment --json`` on the stream (cached); rows, command, seconds."""
    cmd = ["gcs-voice", "recognize", "--segment", "--json", *args_extra, str(wav)]
    shown = " ".join(shlex.quote(c) for c in cmd)
    # a settings file named in the command counts by its contents, not its path
    files = b"".join(Path(a).read_bytes() for a in args_extra if a.endswith(".toml") and Path(a).is_file())
    key = hashlib.sha256(wav.read_bytes() + shown.encode() + files + source_digest().encode()).hexdigest()[:20]
    cached = cache_dir / f"{key}.json"
    if cached.is_file():
        data = json.loads(cached.read_text(encoding="utf-8"))
        return data["rows"], shown, data["seconds"]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    started = time.monotonic()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    seconds = time.monotonic() - started
    if done.returncode != 0:
        raise SystemExit(f"bench_stream: {shown} failed ({done.returncode}): {done.stderr.strip()[-400:]}")
    rows = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    cache_dir.mkdir(parents=True, exist_ok=True)
    cached.write_text(json.dumps({"rows": rows, "seconds": seconds}), encoding="utf-8")
    return rows, shown, seconds


@dataclass
class Counts:
    segments: int = 0
    commands: int = 0
    right: int = 0
    wrong: int = 0
    missed: int = 0
    others: int = 0  # non-command utterances
    false_speech: int = 0  # actions during non-command speech
    false_noise: int = 0  # actions during noise alone
    minutes: float = 0.0


def score(rows: list[dict], placed: list[Placed], total_s: float) -> Counts:
    """Give each segment to the utterance it overlaps most (none: noise alone) and count the outcomes."""
    c = Counts(segments=len(rows), minutes=total_s / 60)
    actions: dict[int, list[str]] = {i: [] for i in range(len(placed))}
    for row in rows:
        best, overlap = None, 0.0
        for i, p in enumerate(placed):
            o = min(row["end_s"], p.end_s) - max(row["start_s"], p.start_s)
            if o > overlap:
                best, overlap = i, o
        if row.get("action"):
            if best is None:
                c.false_noise += 1
            else:
                actions[best].append(row["action"])
    for i, p in enumerate(placed):
        got = actions[i]
        if p.clip.action is None:
            c.others += 1
            c.false_speech += len(got)
        else:
            c.commands += 1
            if any(a != p.clip.action for a in got):
                c.wrong += 1
            elif got:
                c.right += 1
            else:
                c.missed += 1
    return c


def pct(n: int, d: int) -> str:
    return f"{100 * n / d:.1f} % ({n}/{d})" if d else "-"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--noises", default="kitchen", help="comma list of " + ", ".join(NOISE_FILES) + " or 'all'")
    p.add_argument("--snrs", default="20,12,6", help="SNRs in dB (default 20,12,6)")
    p.add_argument("--no-clean", action="store_true", help="skip the stream without added noise")
    p.add_argument("--utterances", type=int, default=60)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--quick", action="store_true", help="12 utterances, clean + kitchen 12 dB")
    p.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"),
                   help="the Whisper model (given to the default engine or --engine whisper)")
    p.add_argument("--engine", default=None, help="passed to gcs-voice recognize (default: what it picks)")
    p.add_argument("--vad", default=None, choices=("silero", "energy"), help="segmenter (default: vad.toml's)")
    p.add_argument("--vad-settings", default=None, metavar="TOML",
                   help="a segmenter settings file for gcs-voice recognize --vad-settings (to compare settings)")
    p.add_argument("--split", default="test", choices=("test", "dev"),
                   help="speakers to build the streams from: test (the report) or dev (to choose settings on)")
    p.add_argument("--work", default=str(ROOT / "out" / "bench" / "stream"))
    p.add_argument("--out", default=None, help="markdown report (default docs/bench/stream.md; '-' = stdout only)")
    args = p.parse_args(argv)
    if args.quick:
        args.utterances, args.noises, args.snrs = 12, "kitchen", "12"
    noises = list(NOISE_FILES) if args.noises == "all" else [n for n in args.noises.split(",") if n]
    unknown = set(noises) - set(NOISE_FILES)
    if unknown:
        raise SystemExit(f"bench_stream: unknown noise(s) {', '.join(sorted(unknown))}")
    snrs = [float(s) for s in args.snrs.split(",") if s]
    conditions: list[tuple[str, float | None]] = [] if args.no_clean else [("none", None)]
    conditions += [(n, s) for n in noises for s in snrs]
    # the Whisper model goes only to an engine that takes it (PocketSphinx's model is in its wheel)
    model = ["--model", args.model] if args.engine in (None, "whisper") else []
    extra = model + (["--engine", args.engine] if args.engine else []) + \
        (["--vad", args.vad] if args.vad else []) + \
        (["--vad-settings", str(Path(args.vad_settings).resolve())] if args.vad_settings else [])
    work = Path(args.work)
    clips = choose(load_recordings(split=args.split), args.utterances, np.random.default_rng(args.seed))
    lines = []
    shown_cmd = ""
    for noise_name, snr in conditions:
        noise = read_wav(SHARED / "noise" / NOISE_FILES[noise_name]) if snr is not None else None
        x, placed = build_stream(clips, noise, snr, args.seed)
        label = "clean" if snr is None else f"{noise_name}{snr:g}"
        wav = work / f"stream_{label}_n{args.utterances}_s{args.seed}{'' if args.split == 'test' else '_' + args.split}.wav"
        write_wav(wav, x)
        write_truth(wav.with_suffix(".tsv"), placed)
        rows, shown_cmd, seconds = recognize(wav, extra, work / "cache")
        c = score(rows, placed, x.size / RATE)
        line = (f"| {'none' if snr is None else NOISE_FILES[noise_name]} | {'-' if snr is None else f'{snr:g}'} | "
                f"{c.minutes:.1f} | {c.segments} / {len(placed)} | {pct(c.right, c.commands)} | "
                f"{c.wrong} | {c.missed} | {c.false_speech} / {c.others} | {c.false_noise} | "
                f"{(c.false_speech + c.false_noise) / c.minutes * 5:.1f} | {seconds:.0f} |")
        print(line, flush=True)
        lines.append(line)
    report = "\n".join([
        "# Live listening: continuous streams of real speech over real noise",
        "",
        "Command: `" + " ".join(["python -m tools.bench_stream",
                                 *(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))]) + "`",
        "",
        f"Each stream: {args.utterances} real utterances from the "
        + ("held-out test part of `../shared/speech` (the test split of `python -m tools.real_speech`, speakers no "
           "tuning heard; " if args.split == "test" else "dev part of `../shared/speech` (the split settings are "
           "chosen on; ") + "70 % commands, "
        "15 % non-command words, 15 % sentences), "
        f"seed {args.seed}, pauses 1.5-6 s, each utterance at {SPEECH_DBFS:g} dBFS over its voiced frames; the real "
        "noise under the whole stream at the stated SNR. The stream WAV is fed as one file to "
        f"`{shown_cmd.rsplit(' ', 1)[0]} STREAM.wav`.",
        "A command is right when its segments carry its action and no other, wrong when any other action, missed "
        "when none. A false action is an action during non-command speech (words, sentences) or noise alone.",
        f"Segmenter: {args.vad or 'silero'}, settings "
        f"{args.vad_settings or 'gcs_voice/audio/vad.toml'}; no stop spotter here (`recognize` is the main "
        "recogniser only; the spotter is measured in stop.md). A missed command is either not segmented (fewer "
        "segments than utterances) or segmented and rejected by the recogniser's decision.",
        f"Load average at the end of the run: {os.getloadavg()[0]:.1f} (2 cores).",
        "",
        "| noise | SNR dB | minutes | segments / utterances | commands right | wrong | missed | "
        "false actions on speech / non-command utterances | false actions on noise alone | false actions per 5 min | "
        "run s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *lines, "",
    ])
    out = args.out or str(ROOT / "docs" / "bench" / "stream.md")
    if out != "-":
        Path(out).write_text(report, encoding="utf-8")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
