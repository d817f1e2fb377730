"""User-facing errors: each one becomes a single line on stderr, never a traceback."""

from __future__ import annotations

__all__ = ["GcsVoiceError", "DictionaryError", "AudioError", "ModelError", "LinkError"]


class GcsVoiceError(Exception):
    """Base for every error caused by user input or the environment (files, models, devices, links).

    The command line prints ``gcs-voice: error: <message>`` and exits with status 2; anything
    that is *not* a GcsVoiceError is a bug and keeps its traceback.
    """


class DictionaryError(GcsVoiceError):
    """A domain dictionary file is missing, malformed or inconsistent (message names file and phrase)."""


class AudioError(GcsVoiceError):
    """Audio input is unusable: no microphone, not a WAV file, empty, or an unsupported sample format."""


class ModelError(GcsVoiceError):
    """A speech model is missing, unreadable or not installed."""


class LinkError(GcsVoiceError):
    """A MAVLink connection string is wrong or the vehicle cannot be reached."""
