"""Live listening in noise: continuous streams of real speech over real noise, fed to ``gcs-voice recognize --segment``.

A microphone in a room hears commands and other talk at random pauses, over noise that never stops,
from people at different distances, for a whole flight. This builds such streams from the held-out test
part of the real recordings: ``../shared/speech`` as ``tools.speech.real_speech.load_recordings(split="test")``
splits it, the one speaker split of every real-speech tool (this file has no split of its own), so no
speaker heard here was heard by any tuning. It mixes them over the real noises of ``../shared/noise`` (one
noise, or ``mixed``: the four in turn, changing every ``--noise-change-s`` seconds with a 1 s crossfade)
at a stated SNR (speech level measured over its voiced frames, noise over the whole track; with
``--level-spread D`` each utterance is D dB louder or quieter at random around that level, so its own
SNR varies), writes the stream WAV and a truth TSV (and, once scored, ``*.outcomes.tsv``: per
utterance what was heard and what acted), and feeds the stream to
``gcs-voice recognize --segment --json`` AS ONE FILE in a real subprocess. Then it counts, per stream:

- commands right, wrong (another action), missed (no action), and of the missed those that produced no
  segment at all (the segmenter never heard them);
- false actions: any action during non-command speech, or during noise alone;
- the longest deaf stretch: the longest time from the start of an utterance whose speech is at least
  10 dB above the noise around it to the end of a later one, both producing no segment and no utterance
  between them producing one either (0 when every such utterance produced one).

    python -m tools.listen.bench_stream                    # clean + kitchen 20/12/6 dB, 60 utterances each
    python -m tools.listen.bench_stream --noises all       # the four real noises
    python -m tools.listen.bench_stream --room             # the room as issue 30 sets it (see ROOM below)
    python -m tools.listen.bench_stream --quick            # 12 utterances, clean + kitchen 12 dB
    python -m tools.listen.bench_stream --vad energy       # the fallback segmenter, for comparison

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

from gcs_voice.audio.vad import VAD_SETTINGS_PATH, load_vad_settings
from gcs_voice.session.listen import LOUD_ROOM_REPEAT_S, loud_room_hint
from tools.speech.real_speech import SHARED, Recording, load_recordings

ROOT = Path(__file__).resolve().parents[2]
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


def build_stream(clips: list[Recording], noise: np.ndarray | list[np.ndarray] | None, snr_db: float | None,
                 seed: int, pause_s: tuple[float, float] = (1.5, 6.0), level_spread_db: float = 0.0,
                 noise_change_s: float = 60.0) -> tuple[np.ndarray, list[Placed]]:
    """Clips at random pauses (seeded) over a noise track; each clip at SPEECH_DBFS over its voiced part
    (give or take up to ``level_spread_db``, uniformly: people at different distances). A list of noises
    takes turns every ``noise_change_s`` seconds."""
    speech, placed, rng = lay_clips(clips, seed, pause_s, level_spread_db)
    return under_noise(speech, noise, snr_db, rng, noise_change_s), placed


def lay_clips(clips: list[Recording], seed: int, pause_s: tuple[float, float] = (1.5, 6.0),
              level_spread_db: float = 0.0) -> tuple[np.ndarray, list[Placed], np.random.Generator]:
    """The speech track alone: clips at their levels and random pauses; the generator goes on to the noise."""
    rng = np.random.default_rng(seed)
    pieces, placed = [], []
    lead = int(rng.uniform(*pause_s) * RATE)
    pieces.append(np.zeros(lead))
    t = lead
    for clip in clips:
        x = read_wav(clip.path)
        _, v0, v1 = voiced_level(x)
        x = at_speech_level(x)
        if level_spread_db:
            x = x * 10 ** (rng.uniform(-level_spread_db, level_spread_db) / 20)
        placed.append(Placed(clip, t / RATE, (t + x.size) / RATE, (t + v0) / RATE, (t + v1) / RATE))
        pause = int(rng.uniform(*pause_s) * RATE)
        pieces += [x, np.zeros(pause)]
        t += x.size + pause
    return np.concatenate(pieces), placed, rng


def at_speech_level(x: np.ndarray) -> np.ndarray:
    """A clip brought to SPEECH_DBFS over its voiced frames: a person at a steady distance."""
    level, _, _ = voiced_level(x)
    return x * (10 ** (SPEECH_DBFS / 20) / max(level, 1e-6))


def noise_track(noise: np.ndarray | list[np.ndarray], n: int, snr_db: float, rng: np.random.Generator,
                change_s: float = 60.0) -> np.ndarray:
    """``n`` samples of noise ``snr_db`` below SPEECH_DBFS, each noise from a random point, looped; a list of
    noises takes turns every ``change_s`` seconds (1 s crossfades), each at that level."""
    target = 10 ** (SPEECH_DBFS / 20) / 10 ** (snr_db / 20)

    def level(track: np.ndarray) -> np.ndarray:
        return track * target / max(float(np.sqrt(np.mean(track**2))), 1e-9)

    if isinstance(noise, np.ndarray):
        start = int(rng.integers(0, noise.size))
        return level(np.resize(np.roll(noise, -start), n))
    tracks = [level(np.resize(np.roll(x, -int(rng.integers(0, x.size))), n)) for x in noise]
    period, fade = int(change_s * RATE), RATE
    t = np.arange(n)
    turn = t // period
    # the last second of each turn fades (equal power) into the next noise
    alpha = np.clip((t - turn * period - (period - fade)) / fade, 0.0, 1.0)
    out = np.zeros(n)
    for k, track in enumerate(tracks):
        out += np.where(turn % len(tracks) == k, np.sqrt(1 - alpha), 0.0) * track
        out += np.where((turn + 1) % len(tracks) == k, np.sqrt(alpha), 0.0) * track
    return out


def under_noise(speech: np.ndarray, noise: np.ndarray | list[np.ndarray] | None, snr_db: float | None,
                rng: np.random.Generator, change_s: float = 60.0) -> np.ndarray:
    """A stream of speech at SPEECH_DBFS with the noise (from a random point, looped) under all of it,
    ``snr_db`` below the speech's level; clean when either is None."""
    if noise is None or snr_db is None:
        return np.clip(speech, -1, 1)
    return np.clip(speech + noise_track(noise, speech.size, snr_db, rng, change_s), -1, 1)


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
    wrong_stop: int = 0  # of the wrong: a stop where a motion was said (the vehicle held; it did not go astray)
    missed: int = 0
    unsegmented: int = 0  # missed commands that produced no segment at all
    others: int = 0  # non-command utterances
    false_speech: int = 0  # actions during non-command speech
    false_noise: int = 0  # actions during noise alone
    minutes: float = 0.0
    deaf_s: float = 0.0  # the longest deaf stretch (see the module's docstring)


#: speech at least this far above the noise around it must be heard (the deaf-stretch rule)
AUDIBLE_DB = 10.0


def overlaps(a0: float, a1: float, b0: float, b1: float) -> bool:
    return min(a1, b1) - max(a0, b0) > 0


def local_snr_db(speech: np.ndarray, noise: np.ndarray | None, p: Placed) -> float:
    """The utterance's voiced level over the noise's level around it (its voiced span and 0.5 s either side)."""
    if noise is None:
        return float("inf")
    v0, v1 = int(p.voiced_start_s * RATE), int(p.voiced_end_s * RATE)
    s_rms = float(np.sqrt(np.mean(speech[v0:v1] ** 2) + 1e-12))
    n_rms = float(np.sqrt(np.mean(noise[max(0, v0 - RATE // 2):v1 + RATE // 2] ** 2) + 1e-12))
    return 20 * np.log10(s_rms / n_rms)


def deaf_stretch_s(placed: list[Placed], heard: list[bool], audible: list[bool]) -> float:
    """Longest time over which audible utterances produced no segment and nothing said between them did either.

    A quieter utterance missed in between does not end the stretch (nor start one); one heard, however quiet,
    does: the segmenter was listening."""
    longest, run_start = 0.0, None
    for p, h, a in zip(placed, heard, audible):
        if h:
            run_start = None
            continue
        if not a:
            continue
        run_start = p.voiced_start_s if run_start is None else run_start
        longest = max(longest, p.voiced_end_s - run_start)
    return longest


def owner_of(row: dict, placed: list[Placed]) -> int | None:
    """The utterance a segment overlaps most (None: it lies on noise alone)."""
    best, overlap = None, 0.0
    for i, p in enumerate(placed):
        o = min(row["end_s"], p.end_s) - max(row["start_s"], p.start_s)
        if o > overlap:
            best, overlap = i, o
    return best


def score(rows: list[dict], placed: list[Placed], total_s: float,
          audible: list[bool] | None = None) -> Counts:
    """Give each segment to the utterance it overlaps most (none: noise alone) and count the outcomes.

    ``audible``: which utterances the deaf-stretch rule counts (default: all)."""
    c = Counts(segments=len(rows), minutes=total_s / 60)
    actions: dict[int, list[str]] = {i: [] for i in range(len(placed))}
    for row in rows:
        best = owner_of(row, placed)
        if row.get("action"):
            if best is None:
                c.false_noise += 1
            else:
                actions[best].append(row["action"])
    heard = [any(overlaps(r["start_s"], r["end_s"], p.voiced_start_s, p.voiced_end_s) for r in rows) for p in placed]
    for i, p in enumerate(placed):
        got = actions[i]
        if p.clip.action is None:
            c.others += 1
            c.false_speech += len(got)
        else:
            c.commands += 1
            if any(a != p.clip.action for a in got):
                c.wrong += 1
                c.wrong_stop += all(a in (p.clip.action, "stop") for a in got)
            elif got:
                c.right += 1
            else:
                c.missed += 1
                c.unsegmented += not heard[i]
    c.deaf_s = deaf_stretch_s(placed, heard, audible if audible is not None else [True] * len(placed))
    return c


def outcomes(rows: list[dict], placed: list[Placed]) -> list[str]:
    """One TSV line per utterance (and per segment over noise alone): what was said, what the segments heard,
    what acted and why not, so that a wrong or missed command can be looked at, not only counted."""
    owner: dict[int | None, list[dict]] = {}
    for row in rows:
        owner.setdefault(owner_of(row, placed), []).append(row)
    lines = ["index\tstart_s\ttruth\toutcome\tactions\theard\treasons\tpath"]
    for i, p in enumerate([*placed, None]):
        got = owner.get(None if p is None else i, [])
        if p is None and not got:
            continue
        acts = [r["action"] for r in got if r.get("action")]
        truth = "noise" if p is None else (p.clip.action or "none")
        if p is None or p.clip.action is None:
            outcome = "false action" if acts else "ignored"
        else:
            # "no segment" as score() counts it: no segment overlaps the utterance's speech at all
            cut = any(overlaps(r["start_s"], r["end_s"], p.voiced_start_s, p.voiced_end_s) for r in rows)
            outcome = "wrong" if any(a != p.clip.action for a in acts) else "right" if acts else \
                ("missed" if cut else "no segment")
        heard = " | ".join(r.get("transcript") or r.get("text") or "" for r in got)
        reasons = " | ".join(r.get("reason", "") for r in got if r.get("reason"))
        lines.append("\t".join([str(i) if p else "-", f"{p.start_s:.2f}" if p else
                                 ",".join(f"{r['start_s']:.2f}" for r in got), truth, outcome, ",".join(acts),
                                 heard, reasons, str(p.clip.path) if p else ""]))
    return lines


def pct(n: int, d: int) -> str:
    return f"{100 * n / d:.1f} % ({n}/{d})" if d else "-"


@dataclass(frozen=True)
class HeardLevel:
    """One utterance: how far the segmenter heard its voice above the room (its first segment's ``snr_db``; None
    when not segmented or no room was heard before it), how far it truly was (``local_snr_db``), what came of it."""

    heard_db: float | None
    true_db: float
    command: bool
    outcome: str  # right / wrong / missed (commands); acted / ignored (other speech)


def heard_levels(rows: list[dict], placed: list[Placed], true_db: list[float]) -> list[HeardLevel]:
    owner: dict[int | None, list[dict]] = {}
    for row in rows:
        owner.setdefault(owner_of(row, placed), []).append(row)
    out = []
    for i, p in enumerate(placed):
        got = owner.get(i, [])
        heard = next((r["snr_db"] for r in got if r.get("snr_db") is not None), None)
        acts = [r["action"] for r in got if r.get("action")]
        if p.clip.action is None:
            outcome = "acted" if acts else "ignored"
        else:
            outcome = "wrong" if any(a != p.clip.action for a in acts) else "right" if acts else "missed"
        out.append(HeardLevel(heard, true_db[i], p.clip.action is not None, outcome))
    return out


#: the bins of the SNR the segmenter heard, dB (issue 30: what a "the room is loud" hint can go by)
LEVEL_BINS = (6.0, 10.0, 14.0, 18.0)


def levels_report(levels: list[HeardLevel], limit_db: float) -> list[str]:
    """Commands right and other speech acted on by the SNR the segmenter heard; and how near it was to the truth."""
    edges = [-np.inf, *LEVEL_BINS, np.inf]
    names = [f"below {LEVEL_BINS[0]:g}", *(f"{a:g} to {b:g}" for a, b in zip(LEVEL_BINS, LEVEL_BINS[1:])),
             f"{LEVEL_BINS[-1]:g} and above"]
    lines = ["| voice over the room, as heard (dB) | commands right | wrong | other speech acted on |",
             "|---|---|---|---|"]
    seen = [h for h in levels if h.heard_db is not None]
    for name, lo, hi in zip(names, edges, edges[1:]):
        group = [h for h in seen if lo <= h.heard_db < hi]
        commands = [h for h in group if h.command]
        others = [h for h in group if not h.command]
        lines.append(f"| {name} | {pct(sum(h.outcome == 'right' for h in commands), len(commands))} | "
                     f"{sum(h.outcome == 'wrong' for h in commands)} | "
                     f"{pct(sum(h.outcome == 'acted' for h in others), len(others))} |")
    below = [h for h in seen if h.command and h.heard_db < limit_db]
    above = [h for h in seen if h.command and h.heard_db >= limit_db]
    error = np.array([h.heard_db - h.true_db for h in seen if np.isfinite(h.true_db)])
    lines += ["", f"Commands heard less than `loud_room_snr_db` = {limit_db:g} dB above the room (gcs_voice/audio/vad.toml: "
              "a rejection of such a voice tells the pilot the room is loud): "
              f"{pct(sum(h.outcome == 'right' for h in below), len(below))} right; at or above it "
              f"{pct(sum(h.outcome == 'right' for h in above), len(above))}."]
    if error.size:
        lines.append(f"The SNR as heard, less the true one (the voiced level over the noise in the utterance's span and "
                     f"0.5 s either side): median {np.median(error):+.1f} dB, 10th to 90th percentile "
                     f"{np.percentile(error, 10):+.1f} to {np.percentile(error, 90):+.1f} dB (n = {error.size}; the "
                     "recordings' own background, which the true figure leaves out, counts as room).")
    return lines


#: what was said, in the order the hint's table gives it
KINDS = {"command": "commands", "word": "non-command words", "sentence": "sentences", "noise": "noise alone"}


def hint_tally(rows: list[dict], placed: list[Placed], limit_db: float, repeat_s: float,
               min_margin: float = -float("inf")) -> dict[tuple[str, str], int]:
    """Rejected segments whose voice stood less than ``limit_db`` above the room, by what was said: how many
    (``loud``), how many the pilot is told the room is loud (``hint``: gcs_voice.session.listen.loud_room_hint), and
    how many of those it says aloud (``said``: at most every ``repeat_s`` of the stream); ``said_any``: aloud if every
    such rejection were told (session 33's rule)."""
    tally: dict[tuple[str, str], int] = {}
    said_t = said_any_t = -float("inf")
    for row in sorted(rows, key=lambda r: r["end_s"]):
        if row.get("action") or row.get("snr_db") is None or row["snr_db"] >= limit_db:
            continue
        owner = owner_of(row, placed)
        kind = "noise" if owner is None else placed[owner].clip.kind
        tally[kind, "loud"] = tally.get((kind, "loud"), 0) + 1
        if row["end_s"] - said_any_t >= repeat_s:
            said_any_t = row["end_s"]
            tally[kind, "said_any"] = tally.get((kind, "said_any"), 0) + 1
        if loud_room_hint(row["snr_db"], limit_db, bool(row.get("went_on")), row.get("extra", {}).get("margin"),
                          min_margin):
            tally[kind, "hint"] = tally.get((kind, "hint"), 0) + 1
            if row["end_s"] - said_t >= repeat_s:
                said_t = row["end_s"]
                tally[kind, "said"] = tally.get((kind, "said"), 0) + 1
    return tally


def hint_report(tally: dict[tuple[str, str], int], minutes: float, limit_db: float, repeat_s: float) -> list[str]:
    """The hint's table: for what it was said, and how often aloud."""
    lines = [f"What a rejection of a voice less than {limit_db:g} dB above the room says, by what was said: the hint "
             "(\"the room is loud ...; speak up\") on the pilot's screen, and \"too noisy\" aloud at most every "
             f"{repeat_s:g} s of the stream (gcs_voice/session/listen.py `loud_room_hint`: not for talk that went on "
             "past a command's words, nor when no command phrase came within `loud_room_min_margin` of what Whisper "
             "heard).", "",
             "| what was said | rejected below the limit | the hint shown | said aloud | said aloud if every one were told |",
             "|---|---|---|---|---|"]
    for kind, name in KINDS.items():
        lines.append(f"| {name} | {tally.get((kind, 'loud'), 0)} | {tally.get((kind, 'hint'), 0)} | "
                     f"{tally.get((kind, 'said'), 0)} | {tally.get((kind, 'said_any'), 0)} |")
    said = sum(v for (k, stage), v in tally.items() if stage == "said")
    said_any = sum(v for (k, stage), v in tally.items() if stage == "said_any")
    lines += ["", f"Said aloud {said} times in {minutes:.0f} minutes of noisy streams ({said / minutes:.2f} a minute; "
              f"{said_any} if every one were told, session 33's rule)."]
    return lines


@dataclass(frozen=True)
class StreamSpec:
    """One stream to build and score: its noise ('none', a NOISE_FILES key or 'mixed'), SNR, level spread, length."""

    noise: str
    snr_db: float | None
    spread_db: float = 0.0
    minutes: float | None = None  # None: --utterances utterances
    pauses: tuple[float, float] | None = None  # None: --pauses

    @property
    def label(self) -> str:
        if self.snr_db is None:
            base = "clean"
        else:
            base = f"{self.noise}{self.snr_db:g}"
        return base + (f"_spread{self.spread_db:g}" if self.spread_db else "") + \
            (f"_{self.minutes:g}min" if self.minutes else "") + \
            (f"_p{self.pauses[0]:g}-{self.pauses[1]:g}" if self.pauses else "")


#: pauses of a pilot who speaks now and then: minutes of noise with little speech, where a drifting segmenter
#: goes deaf (docs/bench/vad_memory_sweep.md)
SPARSE = (5.0, 40.0)
#: issue 30's room: 5-minute streams at 12 dB over each noise and over the four in turn, at one level and
#: with levels varying +-6 dB, and 30-minute streams (a whole flight) over the four in turn: talkative both ways,
#: and sparse
ROOM = [*(StreamSpec(n, 12.0, 0.0, 5.0) for n in [*NOISE_FILES, "mixed"]),
        *(StreamSpec(n, 12.0, 6.0, 5.0) for n in [*NOISE_FILES, "mixed"]),
        StreamSpec("mixed", 12.0, 0.0, 30.0), StreamSpec("mixed", 12.0, 6.0, 30.0),
        StreamSpec("mixed", 12.0, 0.0, 30.0, SPARSE)]


def utterances_for(minutes: float, pause_s: tuple[float, float]) -> int:
    """About how many utterances fill ``minutes`` at these pauses (a clip lasts about 1.2 s on average)."""
    return max(1, round(minutes * 60 / (sum(pause_s) / 2 + 1.2)))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--noises", default="kitchen",
                   help="comma list of " + ", ".join(NOISE_FILES) + ", mixed (the four in turn), or 'all'")
    p.add_argument("--snrs", default="20,12,6", help="SNRs in dB (default 20,12,6)")
    p.add_argument("--no-clean", action="store_true", help="skip the stream without added noise")
    p.add_argument("--utterances", type=int, default=60)
    p.add_argument("--minutes", type=float, default=None,
                   help="streams of about this length (instead of --utterances)")
    p.add_argument("--level-spread", type=float, default=0.0, metavar="DB",
                   help="each utterance up to DB louder or quieter than the others (people at different distances)")
    p.add_argument("--pauses", default="1.5,6", metavar="MIN,MAX", help="pauses between utterances, s")
    p.add_argument("--noise-change-s", type=float, default=60.0, help="with 'mixed': each noise's turn, s")
    p.add_argument("--room", action="store_true",
                   help="the room of issue 30: 5-min streams at 12 dB over every noise and 'mixed', one level and "
                        "+-6 dB, and 30-min 'mixed' streams, pauses 1.5-4 s, and one with pauses 5-40 s (ignores --noises/--snrs/--minutes)")
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
    pause_s = tuple(float(v) for v in args.pauses.split(","))
    if len(pause_s) != 2 or not 0 < pause_s[0] <= pause_s[1]:
        raise SystemExit("bench_stream: --pauses is MIN,MAX in seconds")
    if args.room:
        specs = list(ROOM)
        pause_s = (1.5, 4.0)
    else:
        noises = [*NOISE_FILES] if args.noises == "all" else [n for n in args.noises.split(",") if n]
        unknown = set(noises) - {*NOISE_FILES, "mixed"}
        if unknown:
            raise SystemExit(f"bench_stream: unknown noise(s) {', '.join(sorted(unknown))}")
        snrs = [float(v) for v in args.snrs.split(",") if v]
        specs = [] if args.no_clean else [StreamSpec("none", None, args.level_spread, args.minutes)]
        specs += [StreamSpec(n, v, args.level_spread, args.minutes) for n in noises for v in snrs]
    # the Whisper model goes only to an engine that takes it (PocketSphinx's model is in its wheel)
    model = ["--model", args.model] if args.engine in (None, "whisper") else []
    extra = model + (["--engine", args.engine] if args.engine else []) + \
        (["--vad", args.vad] if args.vad else []) + \
        (["--vad-settings", str(Path(args.vad_settings).resolve())] if args.vad_settings else [])
    work = Path(args.work)
    recordings = load_recordings(split=args.split)
    noise_audio = {name: read_wav(SHARED / "noise" / f) for name, f in NOISE_FILES.items()}
    lines = []
    levels: list[HeardLevel] = []
    hints: dict[tuple[str, str], int] = {}
    noisy_minutes = 0.0
    vad_settings = load_vad_settings(Path(args.vad_settings) if args.vad_settings else VAD_SETTINGS_PATH)
    loud_db = vad_settings.loud_room_snr_db
    shown_cmd = ""
    for spec in specs:
        pauses_s = spec.pauses or pause_s
        n_utt = utterances_for(spec.minutes, pauses_s) if spec.minutes else args.utterances
        clips = choose(recordings, n_utt, np.random.default_rng(args.seed))
        speech, placed, rng = lay_clips(clips, args.seed, pauses_s, spec.spread_db)
        noise = None
        if spec.snr_db is not None:
            source = list(noise_audio.values()) if spec.noise == "mixed" else noise_audio[spec.noise]
            noise = noise_track(source, speech.size, spec.snr_db, rng, args.noise_change_s)
        x = np.clip(speech + (noise if noise is not None else 0.0), -1, 1)
        true_db = [local_snr_db(speech, noise, pl) for pl in placed]
        audible = [db >= AUDIBLE_DB for db in true_db]
        pauses = "" if pause_s == (1.5, 6.0) or spec.pauses else f"_p{pause_s[0]:g}-{pause_s[1]:g}"
        wav = work / (f"stream_{spec.label}_n{n_utt}_s{args.seed}{pauses}"
                      f"{'' if args.split == 'test' else '_' + args.split}.wav")
        write_wav(wav, x)
        write_truth(wav.with_suffix(".tsv"), placed)
        rows, shown_cmd, seconds = recognize(wav, extra, work / "cache")
        c = score(rows, placed, x.size / RATE, audible)
        if spec.snr_db is not None:
            levels += heard_levels(rows, placed, true_db)
            for key, n in hint_tally(rows, placed, loud_db, LOUD_ROOM_REPEAT_S, vad_settings.loud_room_min_margin).items():
                hints[key] = hints.get(key, 0) + n
            noisy_minutes += x.size / RATE / 60
        wav.with_suffix(".outcomes.tsv").write_text("\n".join(outcomes(rows, placed)) + "\n", encoding="utf-8")
        noise_name = {"none": "none", "mixed": "all four in turn"}.get(spec.noise, NOISE_FILES.get(spec.noise, ""))
        line = (f"| {noise_name} | {pauses_s[0]:g}-{pauses_s[1]:g} | {'-' if spec.snr_db is None else f'{spec.snr_db:g}'} | "
                f"{'±' + format(spec.spread_db, 'g') if spec.spread_db else '0'} | "
                f"{c.minutes:.1f} | {c.segments} / {len(placed)} | {pct(c.right, c.commands)} | "
                f"{c.wrong} ({c.wrong_stop}) | {c.missed} | {c.unsegmented} | {c.false_speech} / {c.others} | {c.false_noise} | "
                f"{(c.false_speech + c.false_noise) / c.minutes * 5:.1f} | {c.right / c.minutes:.1f} | "
                f"{c.deaf_s:.1f} ({sum(audible)}) | {seconds:.0f} |")
        print(line, flush=True)
        lines.append(line)
    spreads = sorted({sp.spread_db for sp in specs})
    report = "\n".join([
        "# Live listening: continuous streams of real speech over real noise",
        "",
        "Command: `" + " ".join(["python -m tools.listen.bench_stream",
                                 *(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))]) + "`",
        "",
        "Each stream: real utterances from the "
        + ("held-out test part of `../shared/speech` (the test split of `python -m tools.speech.real_speech`, speakers no "
           "tuning heard; " if args.split == "test" else "dev part of `../shared/speech` (the split settings are "
           "chosen on; ") + "70 % commands, "
        "15 % non-command words, 15 % sentences), "
        f"seed {args.seed}, pauses as in the table (uniform, seeded), each utterance at {SPEECH_DBFS:g} dBFS over its "
        "voiced frames"
        + (" (level spread ±D: each utterance up to D dB louder or quieter, uniformly)" if any(spreads) else "")
        + "; the real noise under the whole stream at the stated SNR below that level (all four in turn: each "
        f"for {args.noise_change_s:g} s, 1 s crossfades). The stream WAV is fed as one file to "
        f"`{shown_cmd.rsplit(' ', 1)[0]} STREAM.wav`.",
        "A command is right when its segments carry its action and no other, wrong when any other action (in "
        "brackets: of them, a stop where a motion was said: the vehicle held instead of moving), missed "
        "when none; *no segment*: missed commands the segmenter never cut (no segment overlaps their speech). A "
        "false action is an action during non-command speech (words, sentences) or noise alone. *Deaf stretch*: "
        f"the longest time from an utterance at least {AUDIBLE_DB:g} dB above the noise around it to a later one, "
        "both producing no segment and nothing said between them producing one either (in brackets: how many "
        "utterances were that audible).",
        f"Segmenter: {args.vad or 'silero'}, settings "
        f"{args.vad_settings or 'gcs_voice/audio/vad.toml'}; no stop spotter here (`recognize` is the main "
        "recogniser only; the spotter is measured in stop.md).",
        f"Load average at the end of the run: {os.getloadavg()[0]:.1f} (2 cores).",
        "",
        "| noise | pauses s | SNR dB | level spread dB | minutes | segments / utterances | commands right | wrong (a stop) | missed | "
        "no segment | false actions on speech / non-command utterances | false actions on noise alone | "
        "false actions per 5 min | commands right per min | longest deaf stretch s (audible) | run s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *lines, "",
        *(["## The voice over the room, as the segmenter heard it", "",
           "Every utterance of the noisy streams above, by the SNR the segmenter gave its first segment "
           "(`snr_db` of `gcs-voice recognize --segment --json`: the voiced windows' level over the mean level of "
           "the last 10 s outside speech, gcs_voice/audio/vad.py `RoomLevel`); utterances never segmented are left "
           "out.", "", *levels_report(levels, loud_db), "",
           *hint_report(hints, noisy_minutes, loud_db, LOUD_ROOM_REPEAT_S), ""]
          if levels else []),
    ])
    out = args.out or str(ROOT / "docs" / "bench" / "stream.md")
    if out != "-":
        Path(out).write_text(report, encoding="utf-8")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
