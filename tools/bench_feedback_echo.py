#!/usr/bin/env python3
"""A long ``--listen-wav`` session with the bridge's own speech mixed back into the microphone: what it causes.

Builds a stream of real speech (the held-out test speakers of ../shared/speech: commands, other words and
sentences at random pauses, ``tools.bench_stream.build_stream``, each at the same voiced level), then flies
it once, as a user would (``python -m gcs_voice --listen-wav STREAM --takeoff 1.5 --feedback speech
--feedback-echo=DB:MS`` against the bundled simulator in real time): every cue the bridge plays is added
back into what it hears, ``--echo-db`` relative to the pilot's voiced level and ``--delay-ms`` late.

Every utterance the bridge heard, and every stop the spotter fired, is put down to the pilot when it
overlaps a placed clip of the stream (the stream is clean: nothing else is in it), else to the bridge's
own audio. The targets: 0 actions and 0 rejections caused by the bridge's own audio. Also counted: the
pilot's clips said while the bridge was speaking (deaf to commands then: only a stop is heard).

    python -m tools.bench_feedback_echo --minutes 30 --out docs/bench/feedback_echo.md
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tools.bench_stream import SPEECH_DBFS, build_stream, choose, voiced_level, write_truth, write_wav
from tools.real_speech import SHARED, load_recordings

ROOT = Path(__file__).resolve().parent.parent
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


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.session.sim_process import BundledSim
    from gcs_voice.session.session_log import read_session_log

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--echo-db", type=float, default=0.0, help="the bridge's voice vs the pilot's (default 0)")
    parser.add_argument("--delay-ms", type=float, default=60.0)
    parser.add_argument("--engine", default="whisper")
    parser.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    parser.add_argument("--work", type=Path, help="keep the stream and the logs here")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)

    work = args.work or Path(tempfile.mkdtemp(prefix="bench-feedback-echo-"))
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
    events = read_session_log(work / "session.jsonl")
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
    spotted = [e for e in events if e["kind"] == "spotted"]

    def spot_is_pilots(e: dict) -> bool:
        """A spot over the bridge's voice decided on the audio from the bridge's sound on: the pilot's only if
        the pilot's voice is in it. Any other spot: the pilot's if a clip is within a second before it."""
        t = e["spotted_t"] - t0
        if not e.get("over_voice"):
            return pilot(t - 1.0, t)
        began = max((f["played_t"] - t0 for f in said if f["played_t"] - t0 <= t), default=t - 1.0) - VOICE_MARGIN_S
        return any(p.voiced_start_s - VOICE_MARGIN_S <= t and began <= p.voiced_end_s + VOICE_MARGIN_S
                   for p in placed)

    own_spotted = [e for e in spotted if not spot_is_pilots(e)]
    over_spotted = [e for e in spotted if e.get("over_voice")]
    own_over = [e for e in own_spotted if e.get("over_voice")]
    deaf = [(e["played_t"] - t0, e["played_t"] - t0 + e["seconds"] + 0.4) for e in said]
    over = [p for p in placed if any(a <= p.voiced_end_s and p.voiced_start_s <= b for a, b in deaf)]
    over_commands = [p for p in over if p.clip.action]
    over_stops = [p for p in over_commands if p.clip.action == "stop"]
    heard_stops = [p for p in over_stops
                   if any(p.voiced_start_s <= e["spotted_t"] - t0 <= p.voiced_end_s + 1.0 for e in over_spotted)]
    by_tone: dict[str, int] = {}
    for e in said:
        by_tone[e["tone"]] = by_tone.get(e["tone"], 0) + 1
    minutes = stream.size / RATE / 60
    shown = " ".join(["python -m tools.bench_feedback_echo", f"--minutes {args.minutes:g}", f"--seed {args.seed}",
                      f"--echo-db {args.echo_db:g}", f"--delay-ms {args.delay_ms:g}", f"--engine {args.engine}"]
                     + ([f"--out {args.out}"] if args.out else []))
    report = "\n".join([
        "# The bridge's own speech in its microphone",
        "",
        f"Command: `{shown}`",
        "",
        f"Stream: {len(placed)} real utterances of the held-out test speakers of ../shared/speech "
        f"({sum(1 for p in placed if p.clip.action)} commands, the rest other words and sentences), random pauses "
        f"2-6.5 s (seed {args.seed}), {minutes:.1f} min, clean, each at {SPEECH_DBFS:g} dBFS over its voiced part. "
        f"Session: `gcs-voice --listen-wav` (real time, Silero segmenter, stop spotter, {args.engine}) flying the "
        f"bundled simulator (ArduPilot, open field), `--feedback speech --feedback-echo={gain_db:.1f}:{args.delay_ms:g}`: "
        f"every cue played back into the microphone {args.echo_db:+g} dB relative to the pilot's voiced level, "
        f"{args.delay_ms:g} ms late. Wall time {took_s / 60:.1f} min; machine shared (load in the note below).",
        "",
        "| | total | caused by the bridge's own audio |",
        "| --- | --- | --- |",
        f"| cues played into the microphone | {len(said)} ({', '.join(f'{k} {v}' for k, v in sorted(by_tone.items()))}) | |",
        f"| utterances heard | {len(heard)} | {len(own_heard)} |",
        f"| actions (voice) | {len(commands)} | {len(own_commands)} |",
        f"| rejections | {len(rejected)} | {len(own_rejected)} |",
        f"| stops fired by the spotter | {len(spotted)} | {len(own_spotted)} |",
        f"| of them over the bridge's voice (the stricter threshold) | {len(over_spotted)} | {len(own_over)} |",
        "",
        "A stop over the bridge's voice is put down to the pilot only if the pilot's voiced speech (within "
        f"{VOICE_MARGIN_S:g} s) is in the audio the spotter heard from the bridge's sound on; any other stop if a "
        f"clip ends within {MARGIN_S:g} s of the second before it.",
        "",
        f"The pilot's clips said while the bridge was speaking (its sound + 0.4 s): {len(over)} of {len(placed)}, "
        f"{len(over_commands)} of them commands (not heard as commands then: only a stop is); "
        f"{len(over_stops)} of them a stop, {len(heard_stops)} of those spotted over the bridge's voice.",
        "",
        f"Load average after the run: {_load()} (2 CPUs).",
        "",
    ])
    print(report)
    for e in own_heard + own_spotted:
        print("own audio:", e["msg"])
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report, encoding="utf-8")
    return 0


def _load() -> str:
    import os

    try:
        return " / ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:
        return "?"


if __name__ == "__main__":
    raise SystemExit(main())
