"""Stops in a noisy room, on the live path: stops for nothing, real stops, and motions they cancel.

``gcs-voice --listen-wav`` hears a recording as a microphone would (real time, the segmenter, the stop spotter
while the words are said, Whisper and the domain ear deciding), and flies the bundled simulator. This tool builds
a stream of held-out real speech (``tools.speech.real_speech``, test split) in cycles (a motion, three other
utterances, and a real "stop" every other cycle) over the SECOND half of each real noise in turn (the domain ear
trained on the first), flies it once per condition (a room level and a feedback: the bridge's speech mixed back
into the recording as ``--feedback-echo`` does, tones, or none) and counts from each session's log:

- stops for nothing: the stop spotter fired where no stop was said; of those, the ones that changed what the
  vehicle does (a motion stopped and not resumed), and the motions so cancelled;
- real stops: held (by the spotter or the decision) within 300 ms of the end of the word, and that time's p95.

    python -m tools.listen.bench_room_stops --minutes 5 --rooms clean,20,12,6 --feedback speech,tones,off

Real time: each condition takes ``--minutes``. The report is per 5 minutes of stream.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tools.flight.bench_latency import percentile
from tools.listen.streams import owner as owner_of, RATE, Placed, lay_clips, noise_track, write_wav
from tools.speech.ear_data import NOISES, noise_half
from tools.speech.real_speech import SHARED, Recording, load_recordings

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "bench" / "room_stops.md"
MOTIONS = ("go_forward", "go_back", "go_left", "go_right", "up", "down")
#: the bridge's voice in the microphone, as docs/bridge.md shows it: 3 dB below the pilot, 60 ms late
ECHO = (-3.0, 0.06)
STOP_WITHIN_S = 0.3


def script(recordings: list[Recording], minutes: float, seed: int) -> list[Recording]:
    """Cycles of a motion, three other utterances and, every other cycle, a real stop (about 20 s a cycle)."""
    rng = np.random.default_rng(seed)
    pick = lambda pool: pool[int(rng.integers(len(pool)))]  # noqa: E731
    motions = [r for r in recordings if r.action in MOTIONS]
    stops = [r for r in recordings if r.action == "stop"]
    others = [r for r in recordings if r.action is None]
    order: list[Recording] = []
    for cycle in range(max(1, int(minutes * 3))):
        order += [pick(motions)] + [pick(others) for _ in range(3)] + ([pick(stops)] if cycle % 2 else [])
    return order


@dataclass
class Outcome:
    """One condition's counts."""

    minutes: float
    spotted_nothing: int = 0
    changed: int = 0
    cancelled: int = 0
    stops: int = 0
    stops_held: int = 0
    stop_s: list[float] | None = None
    false_actions: int = 0
    #: holds for nothing that resumed the motion: each would have been a cancelled motion before the hold (issue 52)
    resumed: int = 0


def count(jsonl: Path, placed: list[Placed], minutes: float) -> Outcome:
    """What the session did, from its log (``gcs_voice.session.session_log``)."""
    from gcs_voice.session.session_log import read_session_log

    events = read_session_log(jsonl)
    t0 = next(e["audio_t0"] for e in events if e["kind"] == "session" and e.get("phase") == "listening")

    def owner(t: float) -> int | None:
        return owner_of(placed, t - t0)

    out = Outcome(minutes, stop_s=[])
    held_t: dict[int, float] = {}  # real stop utterance -> first time the vehicle was held for it
    moving = None  # the motion flying now (from the log's commands, pauses and resumes)
    paused = None  # the motion paused while an utterance is decided
    pending_nothing = None  # a provisional hold for nothing, waiting for its outcome: the motion it held
    for e in events:
        kind, origin = e["kind"], e.get("origin")
        if kind == "spotted" and not e.get("repeat"):
            i = owner(e["spotted_t"])
            real = i is not None and placed[i].clip.action == "stop"
            if not real:
                out.spotted_nothing += 1
                if e.get("provisional"):
                    pending_nothing = moving or paused
                elif moving is not None or paused is not None:
                    out.changed += 1
                    out.cancelled += 1
        if kind == "command":
            t = e.get("sent_t") or e.get("decided_t") or 0.0
            i = owner(e.get("utterance_end_t") or t)
            if e["action"] == "stop" and i is not None and placed[i].clip.action == "stop":
                held_t.setdefault(i, t)
            if origin == "voice" and (i is None or placed[i].clip.action is None):
                out.false_actions += 1
            moving = e["action"] if e["action"] in MOTIONS else None
            pending_nothing = paused = None
        if kind == "warning" and " -> stop" in e.get("msg", ""):  # a motion that ended by itself (the floor)
            moving = None
        if kind == "paused":
            state = e.get("state")
            if state == "paused":
                i = owner(e.get("utterance_end_t") or e.get("sent_t") or 0.0)
                if i is not None and placed[i].clip.action == "stop" and e.get("sent_t"):
                    held_t.setdefault(i, e["sent_t"])
                paused, moving = moving or paused, None
            elif state == "resumed":
                i = owner(e.get("utterance_end_t") or e.get("sent_t") or 0.0)
                if i is not None and placed[i].clip.action == "stop":
                    held_t.pop(i, None)  # a real stop held and then let go: not a stop (unless a later one stops)
                out.resumed += pending_nothing is not None
                moving, pending_nothing, paused = e.get("action"), None, None
            elif state == "stayed":
                if pending_nothing is not None:
                    out.changed += 1
                    out.cancelled += 1
                pending_nothing = paused = None
    stops = [i for i, p in enumerate(placed) if p.clip.action == "stop"]
    out.stops = len(stops)
    for i in stops:
        if i in held_t:
            late = held_t[i] - (t0 + placed[i].voiced_end_s)
            out.stop_s.append(max(0.0, late))
            out.stops_held += late <= STOP_WITHIN_S
    return out


def fly(wav: Path, work: Path, name: str, model: str, feedback: str) -> Path:
    """One live session on the recording; the session log's path."""
    from gcs_voice.session.run import SessionConfig, load_voice, run_session
    from gcs_voice.session.sim_process import BundledSim

    voice = load_voice("en", "whisper", model, None)
    with BundledSim(autopilot="ardupilot", room="open_field", log_path=work / f"{name}-sim.log") as sim:
        run_session(SessionConfig(connection=sim.connection, lang="en", listen_wav=wav, takeoff_m=1.5, hold_s=1.0,
                                  headless=True, quiet=True, log_dir=work, log_name=name,
                                  feedback=feedback,
                                  feedback_echo=ECHO if feedback != "off" else None),
                    voice=voice)
    return work / f"{name}.jsonl"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.listen.bench_room_stops", description=__doc__.splitlines()[0])
    p.add_argument("--minutes", type=float, default=5.0)
    p.add_argument("--rooms", default="clean,20,12,6", help="clean, or the SNR in dB of the room under the speech")
    p.add_argument("--feedback", default="speech,tones,off")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    p.add_argument("--work", type=Path, help="where recordings and logs go (default: a temp folder)")
    p.add_argument("--out", type=Path, help=f"write the report here (e.g. {DOC.relative_to(ROOT)})")
    p.add_argument("--analyse", action="store_true", help="count again from the logs already in --work (no flight)")
    args = p.parse_args(argv)
    if args.analyse and args.work is None:
        p.error("--analyse needs --work FOLDER")
    feedbacks = args.feedback.split(",")
    if set(feedbacks) - {"speech", "tones", "off"}:
        p.error("--feedback: speech, tones or off")
    try:
        rooms = [None if r == "clean" else float(r) for r in args.rooms.split(",")]
    except ValueError:
        p.error("--rooms: clean or numbers (dB)")
    work = args.work or Path(tempfile.mkdtemp(prefix="room-stops-"))
    work.mkdir(parents=True, exist_ok=True)
    clips = script(load_recordings(split="test"), args.minutes, args.seed)
    speech, placed, rng = lay_clips(clips, args.seed, (1.5, 4.0))
    noises = [noise_half(name, "test") for name in NOISES]
    rows = []
    load_before = os.getloadavg()[0]
    for room in rooms:
        x = speech if room is None else np.clip(speech + noise_track(noises, speech.size, room, rng), -1, 1)
        wav = work / f"room-{room or 'clean'}.wav"
        if not args.analyse:
            write_wav(wav, x)
        for feedback in feedbacks:
            name = f"room-{room or 'clean'}-{feedback}"
            log = work / f"{name}.jsonl" if args.analyse else fly(wav, work, name, args.model, feedback)
            out = count(log, placed, x.size / RATE / 60)
            rows.append((room, feedback, out))
            print(json.dumps({"room": room, "feedback": feedback, **{k: v for k, v in vars(out).items()
                                                                     if k != "stop_s"}}), flush=True)
    per5 = lambda n, o: f"{n} ({5 * n / o.minutes:.1f})"  # noqa: E731
    from tools.report import header

    lines = [
        header("tools.listen.bench_room_stops", argv).rstrip("\n"),
        "",
        "# Stops in a noisy room, on the live path",
        "",
        f"Load average before / after the flights: {load_before:.1f} / {os.getloadavg()[0]:.1f} (2 cores).",
        "",
        f"One stream of {x.size / RATE / 60:.1f} min: {len(placed)} held-out real utterances, {sum(p.clip.action in MOTIONS for p in placed)} "
        f"motions, {sum(p.clip.action == 'stop' for p in placed)} real stops, the rest other talk; the second half of each "
        "real noise in turn under it. Flown live with `--listen-wav` (Whisper base, domain ear, stop spotter) against "
        f"the bundled simulator; feedback speech and tones are mixed back into the recording {ECHO[0]:g} dB, "
        f"{ECHO[1] * 1000:.0f} ms late (`--feedback-echo`). Counts, and per 5 minutes in brackets.",
        "",
        "Stops for nothing: the spotter fired where no stop was said. Changed the flight: a motion stopped and not "
        "resumed by it. Resumed: a motion held for nothing and then resumed: before the hold (issue 52) each was a "
        "motion cancelled.",
        "",
        "| room | feedback | stops for nothing | of them changed the flight | motions cancelled | resumed (cancelled "
        f"before) | real stops held within {STOP_WITHIN_S * 1000:.0f} ms | p95 s | false actions on other speech |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for room, feedback, o in rows:
        p95 = f"{percentile(o.stop_s, 0.95):.2f}" if o.stop_s else "-"
        lines.append(f"| {'clean' if room is None else f'{room:g} dB'} | {feedback} | {per5(o.spotted_nothing, o)} | "
                     f"{per5(o.changed, o)} | {o.cancelled} | {o.resumed} | {o.stops_held}/{o.stops} | {p95} | "
                     f"{o.false_actions} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
