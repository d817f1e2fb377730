"""Shared test fixtures: where ../shared is, and small helpers every test module may use."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

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


@pytest.fixture(scope="session")
def whisper_model_dir() -> Path:
    return shared_path("models", "faster-whisper-base")


@pytest.fixture(scope="session")
def real_speech_dir() -> Path:
    return shared_path("speech")


@pytest.fixture(scope="session")
def tlogs_dir() -> Path:
    return shared_path("tlogs")
