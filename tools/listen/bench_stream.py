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

The streams are built by tools/listen/streams.py and counted by tools/listen/stream_score.py; this module runs
``gcs-voice recognize`` on them (cached) and writes the report.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shlex
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.audio.vad import VAD_SETTINGS_PATH, load_vad_settings
from gcs_voice.session.listen import LOUD_ROOM_REPEAT_S
from tools.listen.stream_score import (
    AUDIBLE_DB, HeardLevel, heard_levels, hint_report, hint_tally, levels_report, local_snr_db, outcomes, pct, score,
)
from tools.listen.streams import NOISE_FILES, RATE, SPEECH_DBFS, choose, lay_clips, noise_track, read_wav, write_truth, write_wav
from tools.speech.real_speech import SHARED, load_recordings

ROOT = Path(__file__).resolve().parents[2]


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
#: goes deaf (docs/bench/stream.md, Tried and not taken; git history: docs/bench/vad_memory_sweep.md)
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
    from tools.report import header

    report = "\n".join([
        header("tools.listen.bench_stream", argv).rstrip("\n"),
        "",
        "# Live listening: continuous streams of real speech over real noise",
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
