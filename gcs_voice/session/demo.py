"""The demo: shipped spoken sequences flown against the bundled simulator, one flight per language.

The sequence is data (``demo_audio/sequence.toml``: WAV, expected action, seconds of flight after it);
hold times there are simulated seconds, divided by the simulator's speed-up to wait in wall time.
"""

from __future__ import annotations

import os
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.listen import ScriptStep

__all__ = ["DemoStep", "load_sequence", "run_demo", "whisper_model_candidates", "choose_voice"]

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


def whisper_model_candidates() -> list[Path]:
    """faster-whisper model folders the demo may use without being told: $GCS_VOICE_SHARED, ../shared."""
    roots = []
    if os.environ.get("GCS_VOICE_SHARED"):
        roots.append(Path(os.environ["GCS_VOICE_SHARED"]))
    roots += [Path.cwd().parent / "shared", Path(__file__).resolve().parents[3] / "shared"]
    return [r / "models" / "faster-whisper-base" for r in roots if (r / "models" / "faster-whisper-base").is_dir()]


def choose_voice(lang: str, engine: str | None, model: str | None) -> tuple[Any, list[str]]:
    """Load the first engine that works for ``lang``: (voice tuple or None, notes on what was skipped and why)."""
    from gcs_voice.session.run import load_voice

    notes: list[str] = []
    for name in ((engine,) if engine else ENGINE_ORDER.get(lang, ())):
        models: list[str | None] = [model]
        if name == "whisper" and model is None:
            models = [str(p) for p in whisper_model_candidates()] or [None]
        for candidate in models:
            try:
                return load_voice(lang, name, candidate, None), notes
            except GcsVoiceError as exc:
                notes.append(f"{lang}: {name} skipped: {exc}")
            except ImportError as exc:
                notes.append(f"{lang}: {name} skipped: package missing ({exc.name})")
    return None, notes


def _summary(steps: list[DemoStep], events: list[dict]) -> tuple[list[str], int]:
    """One line per step: said -> heard -> action; and how many were heard as the intended action."""
    heard = [e for e in events if e["kind"] == "heard"]
    outcome: dict[int, dict] = {}
    by_end = {}
    for i, h in enumerate(heard):
        by_end[h.get("utterance_end_t")] = i
    for e in events:
        # the main decision, not the stop spotter's early stop (which may be followed by another action)
        if (e["kind"] in ("command", "rejected") and e.get("origin") != "spotter"
                and e.get("utterance_end_t") in by_end):
            outcome.setdefault(by_end[e["utterance_end_t"]], e)
    lines, good = [], 0
    for i, step in enumerate(steps):
        h = heard[i] if i < len(heard) else None
        o = outcome.get(i)
        got = o.get("action") if o and o["kind"] == "command" else None
        good += got == step.expect
        verdict = "ok" if got == step.expect else ("REJECTED: " + o.get("reason", "") if o and o["kind"] ==
                                                   "rejected" else f"expected {step.expect}")
        lines.append(f"  said {step.text!r:22} heard {(h or {}).get('text', '-')!r:24} -> {got or 'no action':11} "
                     f"{verdict}")
    return lines, good


def run_demo(langs: tuple[str, ...], engine: str | None, model: str | None, autopilot: str, room: str,
             speedup: float, out_dir: Path, as_json: bool = False) -> int:
    from gcs_voice.session.plot import load_room, plot_flight
    from gcs_voice.session.run import SessionConfig, run_session
    from gcs_voice.session.sim_process import BundledSim

    if speedup <= 0:
        raise GcsVoiceError("--speedup must be > 0")
    room_data = load_room(room)  # a bad room name fails before anything starts
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    worst = 0
    flown = []
    # Load every language's recogniser in the background while the first flies (Whisper takes seconds).
    from concurrent.futures import ThreadPoolExecutor

    loader = ThreadPoolExecutor(max_workers=1)
    pending = {lang: loader.submit(choose_voice, lang, engine, model) for lang in langs}
    loader.shutdown(wait=False)
    for lang in langs:
        voice, notes = pending[lang].result()
        for note in notes:
            print(f"demo: {note}")
        if voice is None:
            print(f"demo: {lang}: no recogniser available, sequence skipped")
            continue
        steps = load_sequence(lang)
        print(f"demo: flying the {lang} sequence with {getattr(voice[0], 'name', '?')} "
              f"(simulator: {autopilot}, room {room}, speed-up {speedup:g})")
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
        lines, good = _summary(steps, result.events)
        print(f"demo: {lang}: {good}/{len(steps)} utterances heard as intended")
        for line in lines:
            print(line)
        print(f"demo: {lang}: wrote {result.tlog}, {result.jsonl}, {png}")
        worst = max(worst, result.exit_code)
        flown.append(lang)
    if not flown:
        raise GcsVoiceError("no sequence could be flown: no recogniser available (see the notes above)")
    print(f"demo: done in {time.monotonic() - started:.0f} s ({', '.join(flown)})")
    return worst
