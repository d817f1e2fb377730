"""The demo: shipped spoken sequences flown against the bundled simulator, one flight per language.

The sequence is data (``demo_audio/sequence.toml``: WAV, expected action, seconds of flight after it);
hold times there are simulated seconds, divided by the simulator's speed-up to wait in wall time.
"""

from __future__ import annotations

import math
import os
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.events import heard_words
from gcs_voice.session.listen import ScriptStep

if TYPE_CHECKING:
    from gcs_voice.session.run import Voice

__all__ = ["DemoStep", "load_sequence", "run_demo", "whisper_model_candidates", "choose_voice", "step_summary",
           "collision_lines"]

AUDIO_DIR = Path(__file__).resolve().parent / "demo_audio"
#: preferred engines per language, fastest first (PocketSphinx ships an English model in its wheel)
ENGINE_ORDER = {"en": ("sphinx", "vosk", "whisper"), "es": ("vosk", "whisper")}


@dataclass(frozen=True)
class DemoStep:
    text: str
    path: Path
    expect: str
    hold_s: float


def load_sequence(lang: str) -> list[DemoStep]:
    data = tomllib.loads((AUDIO_DIR / "sequence.toml").read_text(encoding="utf-8"))
    steps = data.get(lang)
    if not steps:
        raise GcsVoiceError(f"no demo sequence for language {lang!r}")
    return [DemoStep(s["text"], AUDIO_DIR / s["file"], s["expect"], float(s["hold_s"])) for s in steps]


def whisper_model_candidates() -> list[tuple[Path, str]]:
    """faster-whisper model folders the demo may use without being told, each with where it was found:
    $GCS_VOICE_SHARED, ../shared beside the current directory, the shared folder beside this checkout."""
    roots = []
    if os.environ.get("GCS_VOICE_SHARED"):
        roots.append((Path(os.environ["GCS_VOICE_SHARED"]), "$GCS_VOICE_SHARED"))
    roots += [(Path.cwd().parent / "shared", "../shared beside the current directory"),
              (Path(__file__).resolve().parents[3] / "shared", "the shared folder beside the gcs-voice checkout")]
    out: list[tuple[Path, str]] = []
    for root, where in roots:
        folder = root / "models" / "faster-whisper-base"
        if folder.is_dir() and all(folder.resolve() != p.resolve() for p, _ in out):
            out.append((folder, where))
    return out


#: why each engine is the demo's choice when nobody named one
_WHY = {
    "sphinx": "the English default: its model is inside the pocketsphinx wheel, nothing to fetch",
    "vosk": "a Vosk model for the language was found ($VOSK_MODEL_PATH, /usr/share/vosk, ~/.cache/vosk)",
    "whisper": "no Vosk model for the language; Whisper scores the dictionary's phrases",
}


def choose_voice(lang: str, engine: str | None, model: str | None) -> tuple[Voice | None, list[str], str]:
    """Load the first engine that works for ``lang``: (voice tuple or None, notes on what was skipped and why,
    one line saying which engine and model fly the language, and why).

    ``--model`` is for the languages that need a model: English stays on PocketSphinx (what its sequence
    was chosen for, and what README promises) unless ``--engine`` names another engine."""
    from gcs_voice.session.run import load_voice

    notes: list[str] = []
    for name in ((engine,) if engine else ENGINE_ORDER.get(lang, ())):
        candidates: list[tuple[str | None, str]]
        if engine is None and name == "sphinx":
            candidates = [(None, "PocketSphinx's bundled US-English model")]
        elif model is not None:
            candidates = [(model, f"{model} (--model)")]
        elif name == "whisper":
            candidates = [(str(p), f"{p} (found in {where})") for p, where in whisper_model_candidates()]
            candidates.append((None, "the model the engine finds itself ($GCS_VOICE_WHISPER_MODEL, its model folders)"))
        else:
            candidates = [(None, f"the {name} model the engine finds for {lang!r}")]
        for candidate, described in candidates:
            try:
                voice = load_voice(lang, name, candidate, None)
            except GcsVoiceError as exc:
                notes.append(f"{lang}: {name} skipped: {exc}")
                continue
            except ImportError as exc:
                notes.append(f"{lang}: {name} skipped: package missing ({exc.name})")
                break
            why = "--engine" if engine else _WHY.get(name, "the first that loaded")
            extra = ("; --model is for Spanish: add --engine whisper to fly English on it"
                     if engine is None and name == "sphinx" and model is not None else "")
            return voice, notes, f"{lang}: {getattr(voice[0], 'name', name)} with {described}; why: {why}{extra}"
    return None, notes, f"{lang}: no recogniser"


def step_summary(steps: list[DemoStep], events: list[dict]) -> tuple[list[str], int]:
    """One line per step: said -> heard -> action -> done?; and how many were heard *and done* as intended.

    A step counts only when the action was carried out: a motion the bridge refused (a disarmed vehicle
    after a crash) or a take-off / land that failed is not "ok", even when it was heard right."""
    heard = [e for e in events if e["kind"] == "heard"]
    by_end = {h.get("utterance_end_t"): i for i, h in enumerate(heard)}
    outcome: dict[int, dict] = {}
    flown: dict[int, dict] = {}
    for e in events:
        i = by_end.get(e.get("utterance_end_t"))
        if i is None:
            continue
        # the main decision, not the stop spotter's early stop (which may be followed by another action)
        if e["kind"] in ("command", "rejected", "refused") and e.get("origin") != "spotter":
            outcome.setdefault(i, e)
        elif e["kind"] == "flight":
            flown.setdefault(i, e)
    lines, good = [], 0
    for i, step in enumerate(steps):
        h = heard[i] if i < len(heard) else None
        o = outcome.get(i)
        got = o.get("action") if o and o["kind"] in ("command", "refused") else None
        if o is None or got != step.expect:
            verdict = ("REJECTED: " + o.get("reason", "")) if o and o["kind"] == "rejected" else f"expected {step.expect}"
        elif o["kind"] == "refused":
            verdict = f"NOT DONE: {o.get('reason', '')}"
        elif step.expect in ("take_off", "land") and not (flown.get(i) or {}).get("ok"):
            verdict = f"FAILED: {(flown.get(i) or {}).get('detail', 'no result')}"
        else:
            verdict = "ok"
        good += verdict == "ok"
        lines.append(f"  said {step.text!r:22} heard {(heard_words(h) if h else '-')!r:24} -> {got or 'no action':11} "
                     f"{verdict}")
    return lines, good


def collision_lines(events: list[dict]) -> list[str]:
    """Every collision of the flight, with its time from the start of the session."""
    from gcs_voice.session.collisions import collisions_in

    t0 = events[0]["t"] if events else 0.0
    return [f"  COLLISION at +{e['t'] - t0:.1f} s: {e['msg'].removeprefix('COLLISION: ')} ({e.get('text')!r})"
            for e in collisions_in(events)]


def run_demo(langs: tuple[str, ...], engine: str | None, model: str | None, autopilot: str, room: str,
             speedup: float, out_dir: Path, as_json: bool = False) -> int:
    from gcs_voice.session.plot import load_room, plot_flight
    from gcs_voice.session.run import SessionConfig, run_session
    from gcs_voice.session.sim_process import BundledSim

    if not speedup > 0:
        raise GcsVoiceError("--speedup must be > 0 or 'max'")
    pace = "max" if math.isinf(speedup) else f"{speedup:g}"
    if math.isinf(speedup):
        print("demo: speed-up max: the simulator runs as fast as this CPU allows; spoken commands and the 10 Hz "
              "setpoints keep wall time, so every action lasts many simulated seconds and no hold is waited "
              "for: expect a distorted flight (collisions are reported). A number (--speedup 2) flies the plan.")
    room_data = load_room(room)  # a bad room name fails before anything starts
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GcsVoiceError(f"--out {out_dir}: cannot create it ({exc.strerror or exc})") from None
    started = time.monotonic()
    worst = 0
    flown: list[str] = []
    collided: list[str] = []
    # Load every language's recogniser in the background while the first flies (Whisper takes seconds).
    from concurrent.futures import ThreadPoolExecutor

    loader = ThreadPoolExecutor(max_workers=1)
    pending = {lang: loader.submit(choose_voice, lang, engine, model) for lang in langs}
    loader.shutdown(wait=False)
    for lang in langs:
        voice, notes, choice = pending[lang].result()
        for note in notes:
            print(f"demo: {note}")
        if voice is not None:
            print(f"demo: {choice}")
        if voice is None:
            print(f"demo: {lang}: no recogniser available, sequence skipped")
            continue
        steps = load_sequence(lang)
        print(f"demo: flying the {lang} sequence with {getattr(voice[0], 'name', '?')} "
              f"(simulator: {autopilot}, room {room}, speed-up {pace})")
        script = [ScriptStep(s.path, s.hold_s / speedup, s.expect if s.expect in ("take_off", "land") else None)
                  for s in steps]
        stem = f"demo-{lang}"
        for suffix in (".tlog", ".jsonl"):
            (out_dir / f"{stem}{suffix}").unlink(missing_ok=True)
        with BundledSim(autopilot=autopilot, speedup=speedup, room=room,
                        log_path=out_dir / f"{stem}-sim.log") as sim:
            result = run_session(SessionConfig(connection=sim.connection, lang=lang, script=script,
                                               headless=True, as_json=as_json, log_dir=out_dir, log_name=stem),
                                 voice=voice)
        png = plot_flight(result.tlog, out_dir / f"{stem}.png", room=room_data, session_log=result.jsonl,
                          title=f"gcs-voice demo ({lang}, {getattr(voice[0], 'name', '?')}, {autopilot})")
        lines, good = step_summary(steps, result.events)
        hits = collision_lines(result.events)
        print(f"demo: {lang}: {good}/{len(steps)} utterances heard as intended and done"
              + (f"; the vehicle COLLIDED {len(hits)} time{'s' if len(hits) > 1 else ''}" if hits else ""))
        for line in lines + hits:
            print(line)
        print(f"demo: {lang}: wrote {result.tlog}, {result.jsonl}, {png}")
        worst = max(worst, result.exit_code)
        flown.append(lang)
        if hits:
            collided.append(lang)
    if not flown:
        raise GcsVoiceError("no sequence could be flown: no recogniser available (see the notes above)")
    print(f"demo: done in {time.monotonic() - started:.0f} s ({', '.join(flown)})"
          + (f"; FAILED: the vehicle collided in {', '.join(collided)} (exit {worst})" if collided else ""))
    return worst
