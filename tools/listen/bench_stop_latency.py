"""Stop latency with both cores loaded by another process: end of speech to the stop setpoint on the wire.

Flies one real session per engine and condition (``gcs_voice.session.run.run_session`` with
``listen_wav``: what ``gcs-voice --listen-wav`` runs) against the bundled simulator in real time on
loopback, while this tool keeps two busy-loop processes running (one per core: "another process" loading
the machine). The session hears one recording as its microphone would: played in real time, cut by the
segmenter, heard by the stop spotter while spoken, recognised while the closing silence runs out. The
recording alternates a motion (a bundled demo recording: forward, left, climb, descend, each a motion
through space) with a real recorded "stop" from the held-out test part of ``../shared/speech``
(``tools.speech.real_speech.load_recordings(split="test")``, the one split of every real-speech tool; this file
has none of its own), 2 s of silence after each, every stop at the same speech level.
``--conditions clean,kitchen12`` flies one session per condition: under a noisy condition that real noise
runs under the whole recording at that SNR below the speech (``tools.listen.streams.under_noise``: the
stream benchmark's room), so the motions are said in the noise too.

For each stop: the end of speech is the end of the stop recording's voiced frames (25 dB below its peak,
``tools.listen.streams.voiced_level``) on the wall clock of the playback (the session logs when its first
sample played); the stop is the first zero-velocity SET_POSITION_TARGET_LOCAL_NED on the wire after the
recording began that stays so until the next motion is said (the session's tlog): a pause that was resumed
is no stop. Each is put down to what sent it: the stop spotter, the pause while the utterance is decided
(kept by the decision), or the main decision. A stop said to a vehicle that was not moving (its motion
was not heard) is counted apart.

    python -m tools.listen.bench_stop_latency --engines sphinx,whisper --conditions clean,kitchen12 --out docs/bench/latency.md

``--out`` replaces this benchmark's section ("## Stop latency with both cores loaded") in that file, or
appends it: the rest of the file (tools/flight/bench_latency.py's tables) stays.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tools.flight.bench_latency import percentile
from tools.listen.streams import at_speech_level, read_wav, under_noise, voiced_level, write_wav
from tools.cpu_steal import busy_loops
from tools.speech.real_speech import CONDITIONS, SHARED, Recording, load_recordings

ROOT = Path(__file__).resolve().parents[2]
#: motions through space (a turn only rotates the vehicle: nothing for a stop to stop)
MOTIONS = ("go_forward", "move_left", "climb", "go_down")
GAP_S = 2.0
LEAD_S = 1.0
RATE = 16_000
DEMO = ROOT / "gcs_voice" / "session" / "demo_audio" / "en"
SECTION = "## Stop latency with both cores loaded"


@dataclass
class Stream:
    """The recording a session hears, and where in it each stop is (seconds from its first sample)."""

    path: Path
    #: per stop: (start of the stop recording, end of its voiced frames, start of the next motion or None)
    stops: list[tuple[float, float, float | None]] = field(default_factory=list)


def build_stream(recordings: list[Recording], condition: str, path: Path) -> Stream:
    """Motion, 2 s, stop, 2 s, ... as one WAV, the stops at the same speech level (a person at a steady
    distance), and under a noisy ``condition`` its noise under the whole stream at its SNR below that level, as
    ``tools.listen.bench_stream`` lays it (a room is noisy between the words too). The motions keep their own
    (louder) level: they are there to be stopped, and one not heard leaves nothing to stop."""
    gap = np.zeros(int(GAP_S * RATE))
    parts: list[np.ndarray] = [np.zeros(int(LEAD_S * RATE))]
    at = parts[0].size
    stream = Stream(path)
    for i, rec in enumerate(recordings):
        motion = read_wav(DEMO / f"{MOTIONS[i % len(MOTIONS)]}.wav")  # its own level: it is there to be stopped
        stop = read_wav(rec.path)
        _, _, voiced_end = voiced_level(stop)
        if stream.stops:
            start, end, _ = stream.stops[-1]
            stream.stops[-1] = (start, end, at / RATE)
        stop_at = at + motion.size + gap.size
        stream.stops.append((stop_at / RATE, (stop_at + voiced_end) / RATE, None))
        parts += [motion, gap, at_speech_level(stop), gap]
        at = stop_at + stop.size + gap.size
    stem, snr_db = CONDITIONS[condition]
    noise = read_wav(SHARED / "noise" / f"{stem}.wav") if stem else None
    write_wav(path, under_noise(np.concatenate(parts), noise, snr_db, np.random.default_rng(1)))
    return stream


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.session.run import SessionConfig, load_voice, run_session
    from gcs_voice.session.sim_process import BundledSim

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--engines", default="sphinx", help="comma list of main recognisers, one session each per "
                   "condition (default sphinx: quick runs; the stop spotter runs before it whatever it is)")
    p.add_argument("--whisper-model", default=str(SHARED / "models" / "faster-whisper-base"))
    p.add_argument("--hogs", type=int, default=2, help="busy-loop processes (default 2: both cores)")
    p.add_argument("--stops", type=int, default=0, help="use only this many stop recordings (0: all)")
    p.add_argument("--no-spotter", action="store_true", help="without the stop spotter (for comparison)")
    p.add_argument("--no-pause", action="store_true", help="without the pause while deciding (for comparison)")
    p.add_argument("--out", default=None)
    p.add_argument("--speech", type=Path, default=SHARED / "speech")
    p.add_argument("--conditions", default="clean",
                   help="comma list of " + ", ".join(CONDITIONS) + ": one session each (default clean)")
    args = p.parse_args(argv)
    conditions = [c for c in args.conditions.split(",") if c]
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown or not conditions:
        p.error(f"--conditions: unknown {', '.join(unknown) or '(none)'}; known: {', '.join(CONDITIONS)}")

    recordings = [r for r in load_recordings(args.speech, split="test") if r.action == "stop"]
    if args.stops:
        recordings = recordings[:args.stops]
    work = Path(tempfile.mkdtemp(prefix="bench-stop-"))
    rows = []
    for engine, cond in [(e, c) for e in args.engines.split(",") if e for c in conditions]:
        name = "-".join(["stop", engine, cond])
        stream = build_stream(recordings, cond, work / f"{name}.wav")
        voice = load_voice("en", engine, args.whisper_model if engine == "whisper" else None, None)
        with busy_loops(args.hogs):
            time.sleep(1.0)
            load_before = os.getloadavg()[0]
            with BundledSim(autopilot="ardupilot", room="open_field", log_path=work / f"sim-{name}.log") as sim:
                result = run_session(SessionConfig(connection=sim.connection, lang="en", listen_wav=stream.path,
                                                   takeoff_m=1.5, hold_s=1.0, headless=True, quiet=True,
                                                   log_dir=work, log_name=name, stop_spotter=not args.no_spotter,
                                                   pause_while_deciding=not args.no_pause), voice=voice)
            load_after = os.getloadavg()[0]
        rows.append((engine, cond, analyse(result.jsonl, result.tlog, stream),
                     (f"{load_before:.1f}", f"{load_after:.1f}")))
    return report(args, argv, len(recordings), rows, work)


@dataclass
class Result:
    """Per session: latencies (ms) of the stops, by what sent them; and the stops not made."""

    by: dict[str, list[float]] = field(default_factory=lambda: {"spotter": [], "pause": [], "decision": []})
    missed: int = 0
    not_moving: int = 0

    @property
    def stopped(self) -> list[float]:
        return [ms for v in self.by.values() for ms in v]


def analyse(jsonl: Path, tlog: Path, stream: Stream) -> Result:
    """Per stop: ms from its end of speech to the stop that stayed on the wire, and what sent it."""
    from gcs_voice.session.flight_log import read_flight
    from gcs_voice.session.session_log import read_session_log

    events = read_session_log(jsonl)
    flight = read_flight(tlog)
    t0 = next(e["audio_t0"] for e in events if e["kind"] == "session" and e.get("phase") == "listening")
    senders = ([("spotter", e["sent_t"]) for e in events if e["kind"] == "command" and e.get("origin") == "spotter"]
               + [("pause", e["sent_t"]) for e in events if e["kind"] == "paused" and e.get("state") == "paused"]
               + [("decision", e["sent_t"]) for e in events
                  if e["kind"] == "command" and e.get("action") == "stop" and e.get("origin") == "voice"])
    still = lambda sp: abs(sp.vx_m_s) < 0.02 and abs(sp.vy_m_s) < 0.02 and abs(sp.vz_m_s) < 0.02  # noqa: E731
    result = Result()
    for start_s, voiced_end_s, next_s in stream.stops:
        start, end = t0 + start_s, t0 + voiced_end_s
        until = t0 + next_s if next_s is not None else float("inf")
        before = [sp for sp in flight.setpoints if sp.t_s < start]
        if not before or still(before[-1]):
            result.not_moving += 1
            continue
        window = [sp for sp in flight.setpoints if start <= sp.t_s < until]
        # the first still setpoint from which the stream stays still up to the next motion
        first = None
        for i in range(len(window) - 1, -1, -1):
            if not still(window[i]):
                break
            first = window[i]
        if first is None:
            result.missed += 1
            continue
        sender = min(senders, key=lambda s: abs(s[1] - first.t_s))[0] if senders else "decision"
        result.by[sender].append((first.t_s - end) * 1000)
    return result


def report(args: argparse.Namespace, argv: list[str] | None, n_stops: int,
           rows: list[tuple[str, str, Result, tuple[str, str]]], work: Path) -> int:
    shown = " ".join(["python -m tools.listen.bench_stop_latency", *(shlex.quote(a) for a in (argv or sys.argv[1:]))])
    fmt = lambda v: f"{percentile(v, .5):.0f} | {percentile(v, .95):.0f}" if v else "- | -"  # noqa: E731
    path = ("main recogniser only" if args.no_spotter else "stop spotter") + ("" if args.no_pause else ", pause")
    lines = [
        f"| {path}, {engine} | {cond} | {n_stops} | {r.not_moving} | {len(r.by['spotter'])} | "
        f"{len(r.by['pause'])} | {len(r.by['decision'])} | {len(r.stopped)} | {fmt(r.stopped)} | "
        f"{max(r.stopped):.0f} | {r.missed} | {load[0]} / {load[1]} |" if r.stopped else
        f"| {path}, {engine} | {cond} | {n_stops} | {r.not_moving} | 0 | 0 | 0 | 0 | - | - | - | {r.missed} | "
        f"{load[0]} / {load[1]} |"
        for engine, cond, r, load in rows
    ]
    report = "\n".join([
        SECTION,
        "",
        f"Command: `{shown}`. {args.hogs} busy-loop processes run beside the session (load average before / after "
        "in the last column, 2 cores). Real time, bundled simulator (ardupilot, open_field) on UDP loopback; "
        "the session hears one recording as its microphone would (`--listen-wav`: real time, the Silero "
        "segmenter, the stop spotter while the word is spoken).",
        "Stops: the real \"stop\" recordings of the held-out test split of `../shared/speech` "
        "(`python -m tools.speech.real_speech`), each 2 s after a motion (a demo recording: forward, left, climb, "
        "descend, at the demo recordings' own level), every stop at -26 dBFS over its voiced frames; under a noise "
        "condition (kitchen12: the real kitchen recording of ../shared/noise) the noise runs under the whole "
        "recording 12 dB below the stops' level, as in `tools.listen.bench_stream`, so the motions are said in it too. "
        "Clock origin: the end of the "
        "stop's speech (its last voiced frame, on the playback's clock); end: the first zero-velocity setpoint "
        "on the wire that stays until the next motion is said (tlog), put down to what sent it: the stop "
        "spotter, the pause while the utterance is decided (then kept by the decision), or the main decision. "
        "Milliseconds; negative: on the wire before the last voiced frame (the spotter fires while the word is "
        f"said). Session logs, tlogs and recordings: `{work}`.",
        "",
        "| path | noise | stops said | vehicle not moving | by the spotter | by the pause | by the decision | "
        "stopped | p50 | p95 | max | missed | load |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *lines, "",
    ])
    print(report)
    if args.out:
        write_section(Path(args.out), report)
    return 0


def write_section(path: Path, section: str) -> None:
    """Replace the section that starts with ``section``'s heading (up to the next "## "), or append it."""
    heading = section.splitlines()[0]
    text = path.read_text(encoding="utf-8") if path.is_file() else ""
    if heading in text:
        before, rest = text.split(heading, 1)
        nxt = rest.find("\n## ")
        after = rest[nxt + 1:] if nxt >= 0 else ""
        text = before + section + ("\n" + after if after else "")
    else:
        text = text.rstrip("\n") + ("\n\n" if text else "") + section
    path.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    raise SystemExit(main())
