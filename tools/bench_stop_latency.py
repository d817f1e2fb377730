"""Stop latency with both cores loaded by another process: end of speech to the stop setpoint on the wire.

Flies one real session (``gcs_voice.session.run.run_session``, what ``gcs-voice --say`` runs) against the
bundled simulator in real time on loopback, while this tool keeps two busy-loop processes running (one
per core: "another process" loading the machine). The script alternates a motion (the bundled demo
recording; done by the script anyway if it is not heard, so there is always something to stop) with a
real recorded "stop" from the held-out test part of ``../shared/speech``
(``tools.real_speech.load_recordings(split="test")``, the one split of every real-speech tool; this
file has none of its own). ``--conditions clean,kitchen12`` flies one session per condition: under a noisy
condition each stop recording is mixed with that real noise at that SNR (``tools.real_speech.condition_audio``,
what every real-speech tool hears), so the stop spotter and the recogniser hear a stop said in a noisy room.

For each stop: the end of speech is the end of the recording's voiced frames (25 dB below its peak,
tools/bench_stream.voiced_level) on the wall clock of the feed (recordings are fed at speaking pace);
the stop is the first zero-velocity SET_POSITION_TARGET_LOCAL_NED on the wire after it (the session's
tlog). A stop heard by the stop spotter goes out before the main recogniser runs; one it misses waits for
the main decision (or never comes: missed).

    python -m tools.bench_stop_latency --engines sphinx,whisper --conditions clean,kitchen12 --out docs/bench/latency.md

``--out`` replaces this benchmark's section ("## Stop latency with both cores loaded") in that file, or
appends it: the rest of the file (tools/bench_latency.py's tables) stays.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import tempfile
import time
from pathlib import Path

from tools.bench_latency import percentile
from tools.bench_stream import read_wav, voiced_level, write_wav
from tools.cpu_steal import busy_loops
from tools.real_speech import CONDITIONS, SHARED, Recording, condition_audio, load_recordings

ROOT = Path(__file__).resolve().parent.parent
MOTIONS = ("go_forward", "move_left", "climb", "turn_left")
MOTION_ACTION = {"go_forward": "go_forward", "move_left": "go_left", "climb": "up", "turn_left": "turn_left"}
GAP_S = 2.0
RATE = 16_000
DEMO = ROOT / "gcs_voice" / "session" / "demo_audio" / "en"


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.session.listen import ScriptStep
    from gcs_voice.session.run import SessionConfig, load_voice, run_session
    from gcs_voice.session.sim_process import BundledSim

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--engines", default="sphinx", help="comma list of main recognisers, one session each per "
                   "condition (default sphinx: quick runs; the stop spotter runs before it whatever it is)")
    p.add_argument("--whisper-model", default=str(SHARED / "models" / "faster-whisper-base"))
    p.add_argument("--hogs", type=int, default=2, help="busy-loop processes (default 2: both cores)")
    p.add_argument("--stops", type=int, default=0, help="use only this many stop recordings (0: all)")
    p.add_argument("--no-spotter", action="store_true", help="without the stop spotter (for comparison)")
    p.add_argument("--out", default=None)
    p.add_argument("--speech", type=Path, default=SHARED / "speech")
    p.add_argument("--from", dest="from_dir", type=Path, default=None,
                   help="analyse the sessions this tool left in DIR (stop-ENGINE[-CONDITION].jsonl and .tlog) "
                   "instead of flying")
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
    stops = [r.path for r in recordings]
    voiced_tail = {}
    for s in stops:
        x = read_wav(s)
        _, _, v1 = voiced_level(x)
        voiced_tail[s.name] = (x.size - v1) / RATE  # seconds of the file after its last voiced frame (noise adds none)
    work = args.from_dir or Path(tempfile.mkdtemp(prefix="bench-stop-"))
    rows = []
    for engine, cond in [(e, c) for e in args.engines.split(",") if e for c in conditions]:
        name = "-".join(["stop", engine] + ([cond] if cond != "clean" else []))
        if args.from_dir:
            rows.append((engine, cond, analyse(work / f"{name}.jsonl", work / f"{name}.tlog", stops, voiced_tail),
                         ("-", "-")))
            continue
        heard = stops if cond == "clean" else [noisy_copy(r, cond, work / cond) for r in recordings]
        script = []
        for i, stop in enumerate(heard):
            motion = MOTIONS[i % len(MOTIONS)]
            script.append(ScriptStep(DEMO / f"{motion}.wav", GAP_S, fallback_action=MOTION_ACTION[motion]))
            script.append(ScriptStep(stop, GAP_S))
        voice = load_voice("en", engine, args.whisper_model if engine == "whisper" else None, None)
        with busy_loops(args.hogs):
            time.sleep(1.0)
            load_before = os.getloadavg()[0]
            with BundledSim(autopilot="ardupilot", room="open_field", log_path=work / f"sim-{name}.log") as sim:
                result = run_session(SessionConfig(connection=sim.connection, lang="en", script=script, takeoff_m=1.5,
                                                   headless=True, quiet=True, log_dir=work, log_name=name,
                                                   stop_spotter=not args.no_spotter), voice=voice)
            load_after = os.getloadavg()[0]
        rows.append((engine, cond, analyse(result.jsonl, result.tlog, stops, voiced_tail),
                     (f"{load_before:.1f}", f"{load_after:.1f}")))
    return report(args, argv, stops, rows, work)


def noisy_copy(rec: Recording, condition: str, directory: Path) -> Path:
    """The recording mixed as ``condition`` hears it, written under its own name (the session log names its
    source by file name, which is how :func:`analyse` finds each stop)."""
    path = directory / rec.path.name
    write_wav(path, condition_audio(rec, condition))
    return path


def report(args: argparse.Namespace, argv: list[str] | None, stops: list[Path],
           rows: list[tuple[str, str, tuple[list[float], list[float], int], tuple[str, str]]], work: Path) -> int:
    shown = " ".join(["python -m tools.bench_stop_latency", *(shlex.quote(a) for a in (argv or sys.argv[1:]))])
    fmt = lambda v: f"{percentile(v, .5):.0f} | {percentile(v, .95):.0f}" if v else "- | -"  # noqa: E731
    path = "main recogniser only" if args.no_spotter else "stop spotter, then"
    lines = [
        f"| {path} {engine} | {cond} | {len(stops)} | {len(spotted_l)} | {fmt(spotted_l)} | {len(all_l)} | "
        f"{fmt(all_l)} | {missed} | {load[0]} / {load[1]} |"
        for engine, cond, (spotted_l, all_l, missed), load in rows
    ]
    report = "\n".join([
        "## Stop latency with both cores loaded",
        "",
        f"Command: `{shown}`. {args.hogs} busy-loop processes run beside the session (load average before / after "
        "in the last column, 2 cores). Real time, bundled simulator (ardupilot, open_field) on UDP loopback.",
        "Stops: the real \"stop\" recordings of the held-out test split of `../shared/speech` "
        "(`python -m tools.real_speech`), each after a motion "
        "(demo recording; done by the script if not heard); under a noise condition (kitchen12: the real kitchen "
        "recording of ../shared/noise 12 dB below the speech's voiced level) the stops are mixed with it, one "
        "session per condition. Clock origin: the end of speech (the recording's last "
        "voiced frame, fed at speaking pace); end: the first zero-velocity setpoint on the wire (tlog). "
        f"Milliseconds; negative: the stop was on the wire before the recording's last voiced frame (the spotter "
        f"fires while the word is still being said). Session logs and tlogs: `{work}`.",
        "",
        "| path | noise | stops said | stopped by the spotter | p50 | p95 | stopped at all | p50 | p95 | missed | load |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *lines, "",
    ])
    print(report)
    if args.out:
        write_section(Path(args.out), report)
    return 0


def analyse(jsonl: Path, tlog: Path, stops: list[Path], voiced_tail: dict[str, float]
            ) -> tuple[list[float], list[float], int]:
    """Per stop recording: ms from its end of speech to the stop on the wire (spotted ones, all), and misses.

    The stop of an utterance is the spotter's, sent while it was being fed (from its first chunk to its
    ``thinking`` event), else the main decision's stop right after its ``heard`` event.
    """
    from gcs_voice.session.flight_log import read_flight
    from gcs_voice.session.session_log import read_session_log

    events = read_session_log(jsonl)
    flight = read_flight(tlog)
    spotted_l, all_l, missed = [], [], 0
    for s in stops:
        thinking = next((e for e in events if e["kind"] == "thinking" and e.get("source") == s.name), None)
        heard = next((e for e in events if e["kind"] == "heard" and e.get("source") == s.name), None)
        if thinking is None:
            missed += 1
            continue
        end_t = thinking["utterance_end_t"]
        fed_from = end_t - voiced_tail[s.name] - 1.5  # a recording here is at most ~1 s; with margin
        stops_sent = [e for e in events if e["kind"] == "command" and e.get("action") == "stop" and e.get("sent_t")]
        spot = [e for e in stops_sent if e.get("origin") == "spotter" and fed_from <= e["sent_t"] <= thinking["t"] + 0.5]
        main = [e for e in stops_sent if e.get("origin") == "voice" and heard is not None
                and heard["t"] - 0.01 <= e["sent_t"] <= heard["t"] + 1.0]
        first = (spot or main or [None])[0]
        if first is None:
            missed += 1
            continue
        wire = next((sp for sp in flight.setpoints if sp.t_s >= first["sent_t"] - 0.002
                     and abs(sp.vx_m_s) < 0.02 and abs(sp.vy_m_s) < 0.02 and abs(sp.vz_m_s) < 0.02), None)
        if wire is None:
            missed += 1
            continue
        ms = (wire.t_s - (end_t - voiced_tail[s.name])) * 1000
        all_l.append(ms)
        if first.get("origin") == "spotter":
            spotted_l.append(ms)
    return spotted_l, all_l, missed


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
