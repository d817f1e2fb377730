"""``gcs-voice demo``: the README's first command, run as a user runs it, in a fresh directory."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from e2e_support import REPO, require_parts
from gcs_voice.session.flight_log import read_flight
from gcs_voice.session.session_log import read_session_log

pytestmark = pytest.mark.slow


def test_demo_flies_the_english_sequence_and_writes_its_outputs(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry", "gcs_voice.audio.sources")
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "demo", "--lang", "en", "--engine", "sphinx"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=180,
                          env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    elapsed = time.monotonic() - started
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr
    assert elapsed < 120
    for name in ("demo-en.tlog", "demo-en.jsonl", "demo-en.png"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert "utterances heard as intended" in proc.stdout

    events = read_session_log(tmp_path / "demo-en.jsonl")
    done = [e["action"] for e in events if e["kind"] == "command" and e.get("origin") in ("voice", "script")]
    assert done[0] == "take_off" and done[-1] == "land"
    assert any(e["kind"] == "command" and e.get("origin") == "voice" for e in events)  # flown by voice
    heard = [e for e in events if e["kind"] == "heard"]
    assert len(heard) == 8  # every shipped utterance went through the recogniser
    flight = read_flight(tmp_path / "demo-en.tlog")
    assert max(flight.track.alt_m) > 1.2  # it flew
    assert flight.track.alt_m[-1] < 0.2  # and landed
    # the simulator was stopped: no process is left sending to the demo's port
    port = next(e["connection"] for e in events if e["kind"] == "session" and e.get("phase") == "start").rsplit(":", 1)[1]
    running = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert f"udp:127.0.0.1:{port} " not in running and not running.rstrip().endswith(f"udp:127.0.0.1:{port}")


def test_each_language_says_its_engine_model_and_why(whisper_model_dir: Path, tmp_path: Path, monkeypatch) -> None:
    """A faster-whisper-base in ../shared is used for Spanish, and the demo says where it was found; --model
    does not move English off PocketSphinx (README), and says how to."""
    from gcs_voice.session.demo import choose_voice

    require_parts("gcs_voice.asr.registry")
    (tmp_path / "shared" / "models").mkdir(parents=True)
    (tmp_path / "shared" / "models" / "faster-whisper-base").symlink_to(whisper_model_dir)
    (tmp_path / "here").mkdir()
    monkeypatch.chdir(tmp_path / "here")
    monkeypatch.delenv("GCS_VOICE_SHARED", raising=False)

    voice, _notes, line = choose_voice("es", "whisper", None)  # (a Vosk Spanish model would come first)
    assert voice is not None and voice[0].name.startswith("whisper")
    assert "faster-whisper-base (found in ../shared beside the current directory)" in line
    assert line.startswith("es: whisper") and "why: " in line

    voice, _notes, line = choose_voice("en", None, str(whisper_model_dir))
    assert voice is not None and voice[0].name == "sphinx"
    assert "--model is for Spanish: add --engine whisper" in line


@pytest.mark.parametrize("lang, engine", [("en", "sphinx"), ("en", "whisper"), ("es", "whisper")])
def test_every_demo_utterance_is_heard_as_its_step(lang: str, engine: str, request) -> None:
    """README's demo flies English on PocketSphinx, and on Whisper with ``--engine whisper --model PATH``, and
    Spanish on Whisper when a model is found: every shipped WAV must be its step's command to each (Whisper
    wrote "hover" "Pomer" and "land" "Live" before; in Spanish "adelante" "Armelante", and "alto" was too
    near another class for Spanish's class gap)."""
    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.domain.dictionary import load_language
    from gcs_voice.session.demo import load_sequence
    from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

    require_parts("gcs_voice.asr.registry", "gcs_voice.audio.sources")
    model = str(request.getfixturevalue("whisper_model_dir")) if engine == "whisper" else None
    dictionaries = [load_language(lang)]
    recognizer, matcher = load_recognizer(engine, dictionaries, model=model), get_matcher(DEFAULT_MATCHER)
    heard = {}
    for step in load_sequence(lang):
        stream = recognizer.start_stream(lang)
        stream.accept(read_wav(step.path))
        decision = matcher.decide(stream.finish(), dictionaries)
        heard[step.text] = decision.action if decision.action == step.expect else f"{decision.action}: {decision.reason}"
    assert heard == {step.text: step.expect for step in load_sequence(lang)}


def test_speedup_max_is_accepted_as_gcs_sim_takes_it() -> None:
    import math

    from gcs_voice.cli import build_parser
    from gcs_voice.session.sim_process import BundledSim

    parser = build_parser("demo")
    assert math.isinf(parser.parse_args(["--speedup", "max"]).speedup)
    assert parser.parse_args(["--speedup", "2.5"]).speedup == 2.5
    assert "--speedup max" in " ".join(BundledSim(speedup=math.inf, port=1).command())
    for bad in ("0", "-1", "nan", "fast"):
        with pytest.raises(SystemExit):
            parser.parse_args(["--speedup", bad])


def test_demo_at_speedup_max_flies_and_tells_the_truth(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry", "gcs_voice.audio.sources")
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "demo", "--lang", "en", "--engine", "sphinx",
                           "--speedup", "max"], cwd=tmp_path, capture_output=True, text=True, timeout=180,
                          env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    assert "error" not in proc.stderr, proc.stderr
    assert "speed-up max" in proc.stdout and "utterances heard as intended" in proc.stdout
    assert "speedup max" in (tmp_path / "demo-en-sim.log").read_text()  # the simulator ran unpaced
    collided = "COLLIDED" in proc.stdout
    assert proc.returncode == (1 if collided else 0), proc.stdout[-2000:]
