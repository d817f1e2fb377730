#!/usr/bin/env python3
"""A long ``--listen-wav`` session with the bridge's own speech mixed back into the microphone: what it causes.

Builds a stream of real speech (the held-out test speakers of ../shared/speech: commands, other words and
sentences at random pauses, ``tools.listen.streams.build_stream``, each at the same voiced level), then flies
it once, as a user would (``python -m gcs_voice --listen-wav STREAM --takeoff 1.5 --feedback speech
--feedback-echo=DB:MS`` against the bundled simulator in real time): every cue the bridge plays is added
back into what it hears, ``--echo-db`` relative to the pilot's voiced level and ``--delay-ms`` late.

Every utterance the bridge heard, and every stop the spotter fired, is put down to the pilot when it
overlaps a placed clip of the stream (the stream is clean: nothing else is in it), else to the bridge's
own audio. The targets: 0 actions and 0 rejections caused by the bridge's own audio. Also counted: the
pilot's clips said while the bridge was speaking (deaf to commands then: only a stop is heard).

    python -m tools.listen.bench_feedback_echo --minutes 30 --out docs/bench/feedback_echo.md
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tools.listen.streams import SPEECH_DBFS, build_stream, choose, voiced_level, write_truth, write_wav
from tools.speech.real_speech import SHARED, load_recordings

ROOT = Path(__file__).resolve().parents[2]
RATE = 16_000
#: an utterance or a spot within this of a pilot's clip is the pilot's (the segmenter's pre-roll and padding)
MARGIN_S = 0.5
#: a spot over the bridge's voice is the pilot's if the pilot's voiced speech is within this of what it heard
VOICE_MARGIN_S = 0.1


def _bridge_level_dbfs() -> float:
    """Voiced level of the bridge's usual cue (doing tone + "going left") as rendered."""
    from gcs_voice.audio.sounds import Speech, tone
    from gcs_voice.session.feedback import load_sound_settings

    s = load_sound_settings()
    pcm = tone(s.tones["doing"], s.amplitude, s.fade_s) + Speech("en-us", s.speed_wpm).say("going left")
    return float(20 * np.log10(voiced_level(np.frombuffer(pcm, "<i2").astype(np.float64) / 32768)[0]))


@dataclass(frozen=True)
class Clip:
    """A placed clip of the stream as stream.tsv keeps it: where it is and its voiced part, s; its action."""

    start_s: float
    end_s: float
    voiced_start_s: float
    voiced_end_s: float
    action: str | None


def read_clips(path: Path) -> list[Clip]:
    """The clips of a stream's truth file (``tools.listen.streams.write_truth``)."""
    with open(path, encoding="utf-8") as f:
        return [Clip(float(r["start_s"]), float(r["end_s"]), float(r["voiced_start_s"]), float(r["voiced_end_s"]),
                     None if r["truth"] == "none" else r["truth"]) for r in csv.DictReader(f, delimiter="\t")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--echo-db", type=float, default=0.0, help="the bridge's voice vs the pilot's (default 0)")
    parser.add_argument("--delay-ms", type=float, default=60.0)
    parser.add_argument("--engine", default="whisper")
    parser.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    parser.add_argument("--work", type=Path, help="keep the stream and the logs here")
    parser.add_argument("--reanalyse", type=Path, metavar="WORK",
                        help="no session: count again from an earlier run's --work directory (stream.tsv, "
                             "session.jsonl; give the run's --seed, --echo-db and --delay-ms for the report's text)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)

    shown = " ".join(["python -m tools.listen.bench_feedback_echo", f"--minutes {args.minutes:g}", f"--seed {args.seed}",
                      f"--echo-db {args.echo_db:g}", f"--delay-ms {args.delay_ms:g}", f"--engine {args.engine}"]
                     + ([f"--out {args.out}"] if args.out and args.reanalyse is None else []))
    if args.reanalyse is not None:
        again = " ".join(["python -m tools.listen.bench_feedback_echo --reanalyse", str(args.reanalyse)]
                         + ([f"--seed {args.seed}"] if args.seed != 1 else []) + ([f"--out {args.out}"] if args.out else []))
        work, took = args.reanalyse, f"Counted again from the logs of an earlier run: `{again}`."
    else:
        work = args.work or Path(tempfile.mkdtemp(prefix="bench-feedback-echo-"))
        took = run_session(args, work)
    report = analyse(work, shown, took, args.echo_db, args.delay_ms, args.seed, args.engine)
    print(report)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report, encoding="utf-8")
    return 0


def run_session(args: argparse.Namespace, work: Path) -> str:
    """Build the stream into ``work`` and fly it once with the cues mixed back; what it took, as a sentence."""
    from gcs_voice.session.sim_process import BundledSim

    work.mkdir(parents=True, exist_ok=True)
    clips = load_recordings(SHARED / "speech", split="test")
    count = max(1, int(args.minutes * 60 / 5.8))  # ~1.5 s of speech and ~4.3 s of pause each
    rng = np.random.default_rng(args.seed)
    stream, placed = build_stream(choose(clips, count, rng), None, None, args.seed, pause_s=(2.0, 6.5))
    wav = work / "stream.wav"
    write_wav(wav, stream)
    write_truth(work / "stream.tsv", placed)
    gain_db = SPEECH_DBFS - _bridge_level_dbfs() + args.echo_db
    engine = ["--engine", args.engine] + (["--model", args.model] if args.engine == "whisper" else [])
    cmd = [sys.executable, "-m", "gcs_voice", "--listen-wav", str(wav), "--takeoff", "1.5", "--hold", "1",
           "--feedback", "speech", f"--feedback-echo={gain_db:.1f}:{args.delay_ms:g}", *engine, "--headless",
           "--json", "--log-dir", str(work), "--log-name", "session"]
    started = time.monotonic()
    with BundledSim(autopilot="ardupilot", room="open_field", log_path=work / "sim.log") as sim:
        done = subprocess.run([*cmd[:3], "--connect", sim.connection, *cmd[3:]], cwd=ROOT, capture_output=True,
                              text=True)
    took_s = time.monotonic() - started
    if done.returncode != 0:
        raise SystemExit(f"the session failed ({done.returncode}): {done.stderr.strip()[-600:]}")
    (work / "feedback_echo.txt").write_text(f"--feedback-echo={gain_db:.1f}:{args.delay_ms:g}\n", encoding="utf-8")
    return f"Wall time {took_s / 60:.1f} min; machine shared (load in the note below)."


def analyse(work: Path, shown: str, took: str, echo_db: float, delay_ms: float, seed: int, engine: str) -> str:
    """The report for a flown session's logs in ``work``: what was heard, acted on, rejected and spotted, and
    whether the pilot or the bridge's own audio caused it."""
    from gcs_voice.session.feedback import load_sound_settings
    from gcs_voice.session.session_log import read_session_log

    placed = read_clips(work / "stream.tsv")
    events = read_session_log(work / "session.jsonl")
    tail_s = load_sound_settings().tail_s
    t0 = next(e["audio_t0"] for e in events if e.get("phase") == "listening")
    spans = [(p.start_s - MARGIN_S, p.end_s + MARGIN_S) for p in placed]

    def pilot(a_s: float, b_s: float) -> bool:
        return any(lo <= b_s and a_s <= hi for lo, hi in spans)

    heard = [e for e in events if e["kind"] == "heard"]
    own_heard = [e for e in heard
                 if not pilot(e["utterance_end_t"] - t0 - e["audio_s"], e["utterance_end_t"] - t0)]
    own_ends = {e["utterance_end_t"] for e in own_heard}
    rejected = [e for e in events if e["kind"] == "rejected"]
    own_rejected = [e for e in rejected if e.get("utterance_end_t") in own_ends]
    commands = [e for e in events if e["kind"] == "command" and e.get("origin") == "voice"]
    own_commands = [e for e in commands if e.get("utterance_end_t") in own_ends]
    said = [e for e in events if e["kind"] == "feedback" and e["played_t"] >= t0]  # (before: no microphone yet)
    deaf = [(e["played_t"] - t0, e["played_t"] - t0 + e["seconds"] + tail_s) for e in said]
    # a stop word heard again over the bridge's voice while the vehicle still held on the stop just sent is not sent
    # (StopPath, session 31): counted apart
    repeats = [e for e in events if e["kind"] == "spotted" and e.get("repeat")]
    spotted = [e for e in events if e["kind"] == "spotted" and not e.get("repeat")]
    # a log of before the over_voice field: a stop spotted while the microphone was deaf was spotted over the voice
    inferred = any("over_voice" not in e for e in spotted)

    def over_voice(e: dict) -> bool:
        if "over_voice" in e:
            return bool(e["over_voice"])
        t = e["spotted_t"] - t0
        return any(a <= t <= b for a, b in deaf)

    def spot_is_pilots(e: dict) -> bool:
        """A spot over the bridge's voice decided on the audio from the bridge's sound on: the pilot's only if
        the pilot's voice is in it. Any other spot: the pilot's if a clip is within a second before it."""
        t = e["spotted_t"] - t0
        if not over_voice(e):
            return pilot(t - 1.0, t)
        began = max((f["played_t"] - t0 for f in said if f["played_t"] - t0 <= t), default=t - 1.0) - VOICE_MARGIN_S
        return any(p.voiced_start_s - VOICE_MARGIN_S <= t and began <= p.voiced_end_s + VOICE_MARGIN_S
                   for p in placed)

    own_spotted = [e for e in spotted if not spot_is_pilots(e)]
    # stop words the spotter heard over the bridge's voice and the canceller said were its own echo's remains
    dismissed = [e for e in events if e["kind"] == "own_echo"]
    pilots_dismissed = [e for e in dismissed if pilot(e["t"] - t0 - 1.0, e["t"] - t0)]
    over_spotted = [e for e in spotted if over_voice(e)]
    own_over = [e for e in own_spotted if over_voice(e)]
    over = [p for p in placed if any(a <= p.voiced_end_s and p.voiced_start_s <= b for a, b in deaf)]
    over_commands = [p for p in over if p.action]
    over_stops = [p for p in over_commands if p.action == "stop"]
    heard_over = [p for p in over_stops
                  if any(p.voiced_start_s <= e["spotted_t"] - t0 <= p.voiced_end_s + 1.0 for e in over_spotted)]
    heard_stops = [p for p in over_stops
                   if any(p.voiced_start_s <= e["spotted_t"] - t0 <= p.voiced_end_s + 1.0 for e in spotted)]
    by_tone: dict[str, int] = {}
    for e in said:
        by_tone[e["tone"]] = by_tone.get(e["tone"], 0) + 1
    # which of the bridge's own sounds the spotter fired on
    by_cue: dict[str, list[int]] = {}
    for e in said:
        words = e["msg"].split(": ", 1)[-1]
        fired = any(e["played_t"] - t0 <= s["spotted_t"] - t0 <= e["played_t"] - t0 + e["seconds"] + tail_s
                    for s in own_over)
        by_cue.setdefault(words, [0, 0])
        by_cue[words][0] += 1
        by_cue[words][1] += fired
    minutes = max(p.end_s for p in placed) / 60 if placed else 0.0
    echo_file = work / "feedback_echo.txt"
    echo = echo_file.read_text(encoding="utf-8").strip() if echo_file.exists() else f"--feedback-echo=DB:{delay_ms:g}"
    lines = [
        "# The bridge's own speech in its microphone",
        "",
        f"Command: `{shown}`",
        "",
        f"Stream: {len(placed)} real utterances of the held-out test speakers of ../shared/speech "
        f"({sum(1 for p in placed if p.action)} commands, the rest other words and sentences), random pauses "
        f"2-6.5 s (seed {seed}), {minutes:.1f} min, clean, each at {SPEECH_DBFS:g} dBFS over its voiced part. "
        f"Session: `gcs-voice --listen-wav` (real time, Silero segmenter, stop spotter, {engine}) flying the "
        f"bundled simulator (ArduPilot, open field), `--feedback speech {echo}`: every cue played back into the "
        f"microphone {echo_db:+g} dB relative to the pilot's voiced level, {delay_ms:g} ms late. {took}",
        "",
        "| | total | caused by the bridge's own audio |",
        "| --- | --- | --- |",
        f"| cues played into the microphone | {len(said)} ({', '.join(f'{k} {v}' for k, v in sorted(by_tone.items()))}) | |",
        f"| utterances heard | {len(heard)} | {len(own_heard)} |",
        f"| actions (voice) | {len(commands)} | {len(own_commands)} |",
        f"| rejections | {len(rejected)} | {len(own_rejected)} |",
        f"| stops fired by the spotter | {len(spotted)} | {len(own_spotted)} |",
        f"| of them over the bridge's voice | {len(over_spotted)} | {len(own_over)} |",
        f"| stop words heard again over the bridge's voice, the vehicle still holding on the stop just sent (no stop)"
        f" | {len(repeats)} | |",
        f"| stop words dismissed as the bridge's own echo's remains (no stop) | {len(dismissed)} | "
        f"{len(dismissed) - len(pilots_dismissed)} (the rest near a pilot's clip: {len(pilots_dismissed)}) |",
        "",
        "A stop over the bridge's voice is put down to the pilot only if the pilot's voiced speech (within "
        f"{VOICE_MARGIN_S:g} s) is in the audio the spotter heard from the bridge's sound on; any other stop if a "
        f"clip ends within {MARGIN_S:g} s of the second before it."
        + (" This log predates the spotter saying whether it heard a stop over the bridge's voice: a stop spotted "
           f"while the microphone was deaf (a cue's sound + {tail_s:g} s) is taken as one." if inferred else ""),
        "",
        f"The pilot's clips said while the bridge was speaking (its sound + {tail_s:g} s): {len(over)} of {len(placed)}, "
        f"{len(over_commands)} of them commands (not heard as commands then: only a stop is); "
        f"{len(over_stops)} of them a stop: {len(heard_stops)} of those spotted within a second of their end, "
        f"{len(heard_over)} of them over the bridge's voice (the others once it had finished).",
        "",
        "The bridge's sounds the spotter fired on by themselves (a stop for nothing), of the times each was played:",
        "",
        "| cue | played | the spotter fired on it |",
        "| --- | --- | --- |",
        *[f"| {words} | {n} | {fired} |" for words, (n, fired) in sorted(by_cue.items(), key=lambda kv: -kv[1][0])],
        "",
        f"Load average {'now' if inferred or 'earlier' in took else 'after the run'}: {_load()} (2 CPUs).",
        "",
    ]
    for e in own_heard + own_spotted:
        print("own audio:", e["msg"])
    return "\n".join(lines)


def _load() -> str:
    import os

    try:
        return " / ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:
        return "?"


if __name__ == "__main__":
    raise SystemExit(main())
