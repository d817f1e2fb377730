"""A whole flight heard through the microphone path: a long noisy recording flown live, and the same clips decided offline.

``gcs-voice --listen-wav`` hears a recording exactly as a microphone would: in real time, cut by the
Silero segmenter, heard by the stop spotter while spoken, decided while the closing silence runs out,
flown over MAVLink. This tool builds one long recording of held-out real speech
(``tools.speech.real_speech.load_recordings(split="test")``, the one speaker split of every real-speech tool)
over real noise (``tools.listen.bench_stream``'s room: all four noises of ``../shared/noise`` in turn, at 12 dB
below the speech, one level or ``--level-spread``), with about one motion a minute: a motion command, a
little other talk, a real "stop", then other talk (non-command words and sentences) until the next minute.

It then:

1. decides every command's own clip, cut from that same recording (its audio with the noise around it),
   offline with ``gcs-voice recognize --json`` (the whole-file path);
2. flies the recording live against the bundled simulator (ArduPilot personality, open field) through
   ``gcs_voice.session.run.run_session(listen_wav=...)``, what ``gcs-voice --listen-wav`` runs;
3. counts, from the session's log: commands the offline decision got right and the live session acted on
   with the same action (the target: all of them), live right / wrong / missed, false actions on other
   speech and on noise alone, and the time from the end of speech (the segmenter's) to the decision and to
   the setpoint on the wire, p50 / p95.

    python -m tools.listen.bench_listen --minutes 30 --out docs/bench/listen.md

Real time: a 30-minute recording takes 30 minutes. The load average before and after is in the report.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tools.flight.bench_latency import percentile
from tools.listen.stream_score import KINDS
from tools.listen.streams import owner as owner_of, NOISE_FILES, RATE, Placed, lay_clips, noise_track, read_wav, write_wav
from tools.speech.real_speech import SHARED, Recording, load_recordings

ROOT = Path(__file__).resolve().parents[2]
MOTIONS = ("go_forward", "go_back", "go_left", "go_right", "up", "down")
#: utterances in each minute: the motion, one other, the stop, then others (at 1.5-4 s pauses, about a minute)
PER_MINUTE = 12


def script(recordings: list[Recording], minutes: int, seed: int) -> list[Recording]:
    """Per minute: a motion, an other utterance, a stop, then other talk; clips drawn at random (seeded)."""
    rng = np.random.default_rng(seed)
    motions = [r for r in recordings if r.action in MOTIONS]
    stops = [r for r in recordings if r.action == "stop"]
    others = [r for r in recordings if r.action is None]
    order: list[Recording] = []
    for _ in range(minutes):
        order.append(motions[int(rng.integers(len(motions)))])
        order.append(others[int(rng.integers(len(others)))])
        order.append(stops[int(rng.integers(len(stops)))])
        order += [others[int(rng.integers(len(others)))] for _ in range(PER_MINUTE - 3)]
    return order


def offline(wav: np.ndarray, placed: list[Placed], work: Path, model: str) -> dict[int, str | None]:
    """Each command's own clip (cut from the stream, noise and all) decided by ``gcs-voice recognize``
    (kept in ``offline.json`` in the work folder: ``--analyse`` reads it again)."""
    kept = work / "offline.json"
    if kept.is_file():
        return {int(k): v for k, v in json.loads(kept.read_text(encoding="utf-8")).items()}
    paths = {}
    for i, p in enumerate(placed):
        if p.clip.action is None:
            continue
        path = work / "clips" / f"{i:04d}.wav"
        write_wav(path, wav[int(p.start_s * RATE):int(p.end_s * RATE)])
        paths[i] = path
    cmd = ["gcs-voice", "recognize", "--json", "--lang", "en", "--engine", "whisper", "--model", model,
           *map(str, paths.values())]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(f"bench_listen: gcs-voice recognize failed: {done.stderr.strip()[-300:]}")
    rows = {Path(r["file"]).name: r for r in map(json.loads, (ln for ln in done.stdout.splitlines() if ln.startswith("{")))}
    decided = {i: rows[path.name].get("action") for i, path in paths.items()}
    kept.write_text(json.dumps(decided), encoding="utf-8")
    return decided


@dataclass
class Live:
    """What the live session did, per placed utterance (voice decisions only; the spotter apart)."""

    actions: dict[int, list[str]]
    spotted: dict[int, int]
    noise_actions: int
    decide_ms: list[float]
    sent_ms: list[float]
    #: rejections of a voice barely above the room, by what was said (command, word, sentence, noise): marked loud,
    #: given the hint on screen, and "too noisy" said aloud
    loud: dict[tuple[str, str], int] = field(default_factory=dict)


def live(jsonl: Path, placed: list[Placed]) -> Live:
    from gcs_voice.session.session_log import read_session_log

    events = read_session_log(jsonl)
    t0 = next(e["audio_t0"] for e in events if e["kind"] == "session" and e.get("phase") == "listening")

    def owner(end_t: float) -> int | None:
        return owner_of(placed, end_t - t0)

    result = Live({i: [] for i in range(len(placed))}, {}, 0, [], [])
    for e in events:
        if e["kind"] == "rejected" and e.get("loud_room") and e.get("utterance_end_t"):
            i = owner(e["utterance_end_t"])
            kind = "noise" if i is None else placed[i].clip.kind
            for stage, key in (("loud", "loud_room"), ("hint", "hint"), ("said", "say_loud_room")):
                if e.get(key):
                    result.loud[kind, stage] = result.loud.get((kind, stage), 0) + 1
        if e["kind"] != "command":
            continue
        if e.get("origin") == "spotter" and e.get("sent_t"):  # fired while the word was being said
            i = owner(e["sent_t"])
            if i is not None:
                result.spotted[i] = result.spotted.get(i, 0) + 1
            continue
        if e.get("origin") != "voice" or not e.get("utterance_end_t"):
            continue
        i = owner(e["utterance_end_t"])
        if e.get("decided_t"):
            result.decide_ms.append((e["decided_t"] - e["utterance_end_t"]) * 1000)
        if e.get("sent_t"):
            result.sent_ms.append((e["sent_t"] - e["utterance_end_t"]) * 1000)
        if i is None:
            result.noise_actions += 1
        else:
            result.actions[i].append(e["action"])
    return result


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.session.run import SessionConfig, load_voice, run_session
    from gcs_voice.session.sim_process import BundledSim

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--minutes", type=int, default=30)
    p.add_argument("--snr", type=float, default=12.0)
    p.add_argument("--noise", default="mixed", help="one of " + ", ".join(NOISE_FILES) + " or mixed (the four in turn)")
    p.add_argument("--level-spread", type=float, default=0.0, metavar="DB")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--model", default=str(SHARED / "models" / "faster-whisper-base"))
    p.add_argument("--work", type=Path, default=None, help="where the recording, clips and logs go (default: a temp dir)")
    p.add_argument("--out", default=None, help="markdown report ('-' or none: stdout only)")
    p.add_argument("--analyse", action="store_true",
                   help="count again from the session log and offline decisions already in --work (no flight)")
    args = p.parse_args(argv)
    if args.analyse and not (args.work and (args.work / "flight.jsonl").is_file()):
        p.error("--analyse needs --work FOLDER with a flight.jsonl from an earlier run")
    if args.noise != "mixed" and args.noise not in NOISE_FILES:
        p.error(f"--noise: unknown {args.noise!r}")
    work = args.work or Path(tempfile.mkdtemp(prefix="bench-listen-"))
    work.mkdir(parents=True, exist_ok=True)

    clips = script(load_recordings(split="test"), args.minutes, args.seed)
    speech, placed, rng = lay_clips(clips, args.seed, (1.5, 4.0), args.level_spread)
    noises = [read_wav(SHARED / "noise" / f) for f in NOISE_FILES.values()] if args.noise == "mixed" \
        else read_wav(SHARED / "noise" / NOISE_FILES[args.noise])
    x = np.clip(speech + noise_track(noises, speech.size, args.snr, rng), -1, 1)
    wav = work / "flight.wav"
    if not args.analyse:
        write_wav(wav, x)
    print(f"bench_listen: {x.size / RATE / 60:.1f} min, {len(placed)} utterances -> {wav}", flush=True)

    expected = offline(x, placed, work, args.model)
    print(f"bench_listen: offline decisions of {len(expected)} command clips done", flush=True)

    loads = work / "load.json"
    if not args.analyse:
        voice = load_voice("en", "whisper", args.model, None)
        load_before = os.getloadavg()[0]
        with BundledSim(autopilot="ardupilot", room="open_field", log_path=work / "sim.log") as sim:
            run_session(SessionConfig(connection=sim.connection, lang="en", listen_wav=wav, takeoff_m=1.5,
                                      hold_s=1.0, headless=True, quiet=True, log_dir=work, log_name="flight"),
                        voice=voice)
        loads.write_text(json.dumps([load_before, os.getloadavg()[0]]), encoding="utf-8")
    load_before, load_after = json.loads(loads.read_text(encoding="utf-8")) if loads.is_file() else (-1.0, -1.0)
    got = live(work / "flight.jsonl", placed)

    commands = [i for i, p in enumerate(placed) if p.clip.action is not None]
    others = [i for i, p in enumerate(placed) if p.clip.action is None]
    offline_right = [i for i in commands if expected[i] == placed[i].clip.action]
    for i in commands:  # a stop the spotter made while the word was said is that stop, acted on
        if placed[i].clip.action == "stop" and got.spotted.get(i) and "stop" not in got.actions[i]:
            got.actions[i].append("stop")
    kept = [i for i in offline_right if placed[i].clip.action in got.actions[i]
            and all(a == placed[i].clip.action for a in got.actions[i])]
    lost = [i for i in offline_right if i not in kept]
    right = [i for i in commands if got.actions[i] and all(a == placed[i].clip.action for a in got.actions[i])]
    wrong = [i for i in commands if any(a != placed[i].clip.action for a in got.actions[i])]
    false_speech = sum(len(got.actions[i]) for i in others)
    false_moves = sum(1 for i in others for a in got.actions[i] if a != "stop")
    fmt = lambda v: f"{percentile(v, .5):.0f} / {percentile(v, .95):.0f} (n={len(v)})" if v else "-"  # noqa: E731
    shown = " ".join(["python -m tools.listen.bench_listen", *(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))])
    minutes = x.size / RATE / 60
    lines = [
        "# A whole flight through the microphone path",
        "",
        f"Command: `{shown}`. One recording of {minutes:.1f} min: {len(placed)} held-out real utterances "
        f"(`../shared/speech`, test split) at 1.5-4 s pauses, each minute a motion, one other utterance, a real "
        f"\"stop\", then other talk (non-command words and sentences); "
        + ("the four real noises of `../shared/noise` in turn (60 s each, 1 s crossfades)" if args.noise == "mixed"
           else f"the real noise `{NOISE_FILES[args.noise]}`")
        + f" under all of it, {args.snr:g} dB below the speech level"
        + (f", each utterance up to ±{args.level_spread:g} dB from it" if args.level_spread else "") + ". "
        "Offline: each command's own clip, cut from the same recording, decided by `gcs-voice recognize --json "
        "--engine whisper` (Whisper base). Live: the recording flown in real time with `--listen-wav` "
        "(run_session) against the bundled simulator (ardupilot, open_field), stop spotter and pause on; a "
        "live action belongs to the utterance in whose audio its segment ended.",
        f"Load average before / after: {load_before:.1f} / {load_after:.1f} (2 cores). Work folder: `{work}`.",
        "",
        "| what | count |",
        "|---|---|",
        f"| commands said (motions + stops) | {len(commands)} |",
        f"| right offline (own clip) | {len(offline_right)} |",
        f"| of those, acted on live with the same action | **{len(kept)} / {len(offline_right)}** |",
        f"| live: right / wrong / no action (a stop made by the spotter counts) | {len(right)} / {len(wrong)} / "
        f"{len(commands) - len(right) - len(wrong)} |",
        f"| live: stops the spotter made (of {sum(1 for i in commands if placed[i].clip.action == 'stop')} said) | "
        f"{sum(1 for i in commands if placed[i].clip.action == 'stop' and got.spotted.get(i))} |",
        f"| false actions on other speech (of {len(others)} utterances); of them motions (not a stop) | "
        f"{false_speech}; {false_moves} |",
        f"| false actions on noise alone | {got.noise_actions} |",
        f"| end of speech to decision, ms p50 / p95 | {fmt(got.decide_ms)} |",
        f"| end of speech to setpoint on the wire, ms p50 / p95 | {fmt(got.sent_ms)} |",
        "",
        "Rejections of a voice less than `loud_room_snr_db` above the room (gcs_voice/audio/vad.toml), by what was "
        "said: marked loud, the hint shown (\"the room is loud ...; speak up\"), and \"too noisy\" said aloud (at most "
        "every 30 s; the session plays no sound here, but the event says what it would say).",
        "",
        "| what was said | marked loud | hint shown | said aloud |",
        "|---|---|---|---|",
        *(f"| {name} | {got.loud.get((kind, 'loud'), 0)} | {got.loud.get((kind, 'hint'), 0)} | "
          f"{got.loud.get((kind, 'said'), 0)} |" for kind, name in KINDS.items()),
        "",
    ]
    if lost:
        lines += ["Right offline, not acted on live the same way:", ""]
        lines += [f"- {placed[i].start_s:.1f} s `{placed[i].clip.path.name}` ({placed[i].clip.action}): live "
                  f"{got.actions[i] or 'nothing'}" for i in lost]
        lines.append("")
    acted_others = [(i, a) for i in others for a in got.actions[i]]
    if acted_others:
        lines += ["Other speech acted on:", ""]
        lines += [f"- {placed[i].start_s:.1f} s `{placed[i].clip.path.name}` (\"{placed[i].clip.word}\"): {a}"
                  for i, a in acted_others]
        lines.append("")
    text = "\n".join(lines)
    print(text)
    if args.out and args.out != "-":
        Path(args.out).write_text(text, encoding="utf-8")
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
