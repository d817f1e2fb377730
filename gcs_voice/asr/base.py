"""The recogniser interface every engine implements: 16 kHz mono int16 PCM in, hypotheses out.

Shape borrowed from wyoming's ``Transcriber``/streaming session and Vosk's examples: a model is loaded
once (``Recognizer``), each utterance gets a ``RecognizerStream`` that accepts PCM chunks and returns a
``Recognition`` from ``finish()``. Recognitions keep every alternative with its score, because the
matcher needs them to decide and, above all, to reject.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from gcs_voice.audio import SAMPLE_RATE  # every engine takes 16 kHz, mono, signed 16-bit LE PCM

__all__ = ["SAMPLE_RATE", "Hypothesis", "Recognition", "RecognizerStream", "Recognizer", "BufferedStream", "Abandoned"]


@dataclass(frozen=True)
class Hypothesis:
    """One transcript candidate.

    ``confidence`` is in [0, 1] when the engine gives a probability-like value (None otherwise);
    ``score`` is the engine's own raw score (log-probability, acoustic score...) for diagnostics.
    """

    text: str
    confidence: float | None = None
    score: float | None = None


@dataclass(frozen=True)
class Recognition:
    """What an engine heard in one utterance: alternatives best first (may be empty: nothing heard)."""

    hypotheses: tuple[Hypothesis, ...]
    engine: str
    lang: str | None = None
    audio_s: float = 0.0
    #: Engine-specific evidence useful for rejection (e.g. Whisper's no_speech_prob), by name.
    extra: dict[str, float] = field(default_factory=dict)
    #: The engine's own unconstrained transcript when the hypotheses are dictionary phrases it was
    #: asked to score (Whisper mode "score"); "" otherwise. Matchers read it as evidence.
    transcript: str = ""

    @property
    def best(self) -> Hypothesis | None:
        return self.hypotheses[0] if self.hypotheses else None

    @property
    def text(self) -> str:
        """The best hypothesis; with none, the engine's own transcript (what was heard, even when no phrase
        was worth scoring: Whisper scores none for speech that went on past its free pass)."""
        return self.hypotheses[0].text if self.hypotheses else self.transcript

    @property
    def heard(self) -> str:
        """What the engine heard, for people to read: its own transcript where its hypotheses are the
        dictionary phrases it scored (Whisper wrote "Um" while the best-scored phrase was "ahead"; showing
        "ahead" as heard misled), else the best hypothesis."""
        return self.transcript or self.text


@runtime_checkable
class RecognizerStream(Protocol):
    """Per-utterance state. Feed PCM with ``accept``; ``finish`` returns the result and ends the stream."""

    def accept(self, pcm: bytes) -> None: ...

    def finish(self) -> Recognition: ...


@runtime_checkable
class Recognizer(Protocol):
    """A loaded model for one or more languages."""

    name: str
    languages: tuple[str, ...]

    def start_stream(self, lang: str | None = None) -> RecognizerStream: ...


class Abandoned(Exception):
    """``finish()`` stopped early because the stream's ``abandon`` check said its result is no longer wanted."""


class BufferedStream:
    """Base for engines that decode a whole utterance at ``finish`` (Whisper, PocketSphinx): ``accept``
    only buffers; a subclass's ``finish`` calls ``_take()`` to end the stream and get the PCM.

    ``abandon``, when set, is asked between an engine's costly stages whether to go on: a recognition
    begun on a guess (speech that then went on) gives the CPU back instead of delaying the real one.
    A ``finish`` that stops raises :class:`Abandoned`; one that runs to the end is unchanged.
    """

    def __init__(self) -> None:
        self._pcm = bytearray()
        self._done = False
        self.abandon: Callable[[], bool] | None = None

    def check_abandon(self) -> None:
        """Raise :class:`Abandoned` if the result is no longer wanted (engines call it between stages)."""
        if self.abandon is not None and self.abandon():
            raise Abandoned("recognition abandoned: its utterance went on")

    def accept(self, pcm: bytes) -> None:
        if self._done:
            raise RuntimeError("stream already finished")
        self._pcm += pcm

    def _take(self) -> bytes:
        if self._done:
            raise RuntimeError("stream already finished")
        self._done = True
        return bytes(self._pcm)
