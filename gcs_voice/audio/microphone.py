"""Live utterances for a session: the microphone through the segmenter, always listening or push-to-talk.

Push-to-talk (``--push-to-talk``) gates the same stream: while the talk key is not held open the
segmenter is fed silence, so closing it ends the utterance at once and nothing said outside it counts.
Each utterance comes with the wall-clock time its speech ended (the segmenter's end, not the moment
its hangover ran out), which is where latency is counted from.

The bridge never hears itself (``deaf``, an ``gcs_voice.audio.speaker.EchoGate``): while its own sound may
be in the microphone, the segmenter is fed silence, so that sound never becomes an utterance, and the
speech listener (the stop spotter) is fed the microphone itself, less the echo of what the bridge played
(``clean``, a ``gcs_voice.audio.echo_cancel.PlayedEcho``), so a "stop" said over the bridge's voice still
stops. That listener hears one stream at a time: the segmenter's speech, or the deaf time's audio. When the
pilot is still speaking as the deaf time ends (a reply begun in its tail, or words said over the bridge's voice),
the word is taken whole from 0.3 s before the edge, where the bridge's sound has ended: the stop spotter hears it
as a stream of its own and the segmenter's utterance is that whole word, not its start and end apart. A word begun
over the bridge's sound itself is still cut; its utterance is marked, and the session does not act on it (a
"turn left" begun over the bridge's voice must not fly "left").
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.sources import MICROPHONE_BLOCK_S

if TYPE_CHECKING:
    from gcs_voice.audio.sources import AudioChunk
    from gcs_voice.audio.vad import Utterance

__all__ = ["microphone_utterances", "check_microphone", "HeardUtterance"]


def check_microphone(device: int | str | None = None) -> str:
    """The input device's name, or AudioError now (before any link opens) when there is none."""
    from gcs_voice.errors import AudioError

    try:
        import sounddevice as sd
    except (ImportError, OSError) as exc:
        raise AudioError(f"microphone unavailable: {exc} (install libportaudio2)") from None
    try:
        info = sd.query_devices(device, kind="input")
    except Exception as exc:  # sounddevice raises PortAudioError / ValueError
        raise AudioError(f"no microphone: {str(exc).splitlines()[0]} (use --say FILE.wav to fly from "
                         "recordings)") from None
    return str(info.get("name", "input"))


#: after the microphone stops being deaf, this much of its audio says whether the pilot was already speaking
EDGE_S = 0.064
#: ... when a block of it is this far above the room's level before the bridge spoke (the 20th percentile of the
#: blocks of the last ``ROOM_S``): speech under way, not the room
UNDER_WAY_DB = 9.0
ROOM_S = 3.0
#: a word carried across the edge is marked as begun over the bridge's own sound when its first EDGE_S (from
#: LOOKBACK_S before the edge, less the bridge's echo) was this far above the quiet: the room before the bridge
#: spoke, or the quietest the microphone less the echo was while it spoke, whichever is louder (chosen on the dev
#: speakers by python -m tools.listen.bench_deaf_edge)
MARK_ABOVE_DB = 9.0
#: speech under way at the edge that the segmenter has not found within this long is let go
CARRY_LIMIT_S = 1.0
#: the stream that carries a word said across the edge starts this long before it (the deaf time ends the tail
#: after the bridge's sound really ended, EchoGate.record: what the room returned of it, 0.4 s)
LOOKBACK_S = 0.3


class HeardUtterance(NamedTuple):
    """One utterance of the microphone path."""

    pcm: bytes
    #: UNIX time its speech ended
    end_t: float
    #: it began over the bridge's own sound (the microphone was deaf to it): only its end is here
    began_deaf: bool = False
    #: how far the voice stood above the room, in dB (gcs_voice.audio.vad.Utterance.snr_db)
    snr_db: float | None = None


def _level_db(pcm: bytes) -> float:
    x = np.frombuffer(pcm, "<i2").astype(np.float64)
    return float(10 * np.log10(np.mean(x * x) + 1e-3)) if x.size else -30.0


class _Ear:
    """Which listener hears the microphone, block by block, when it has a deaf time (see the module's docstring).

    A word said across the end of the deaf time is not cut in two. When the pilot is speaking as the microphone stops
    being deaf (a block of the first ``EDGE_S`` well above the room before the bridge spoke), the word is taken from
    ``LOOKBACK_S`` before the edge (the deaf time's tail, after the bridge's sound ended), the microphone as it is, to
    the end of the segmenter's utterance: the stop spotter hears it as a stream of its own (the deaf time's stream is
    still decided on its own, as before), and the segmenter's utterance is that whole word (``whole``). When even
    that began mid-word (its first ``EDGE_S``, less the bridge's echo, ``MARK_ABOVE_DB`` above the quiet: the pilot
    began over the bridge's own sound), the utterance is marked (``began_deaf``): only its end is there. ``carry="none"``
    is the way before (the word cut in two, nothing marked), for the benchmark."""

    def __init__(self, on_speech: Callable[[bytes | None], None], over_voice: Callable[[bytes | None], None],
                 clean: Callable[[float, bytes], bytes] | None, block_s: float, carry: str = "lookback") -> None:
        if carry not in ("lookback", "none"):
            raise ValueError(f"carry must be lookback or none, not {carry!r}")
        self.on_speech = on_speech
        self.over_voice = over_voice
        self.clean = clean
        self.carry = carry
        self.block_s = block_s
        self.deaf = False
        self.state = "open"  # open | edge (judging the first blocks after the deaf time) | carry
        self.edge_t = 0.0
        self.edge_loud = False
        self.floor_db = -30.0
        self.room: deque[float] = deque(maxlen=max(1, round(ROOM_S / block_s)))
        self.recent: deque[bytes] = deque(maxlen=max(1, round(LOOKBACK_S / block_s)))  # the raw deaf audio
        self.deaf_levels: list[float] = []  # the levels of the microphone less the bridge's echo, this deaf time
        self.lookback_rise_db = 0.0  # how far the start of the word carried was above the quiet
        self.edge: list[bytes] = []  # the blocks since the edge, while it is judged
        self.held: list[bytes | None] = []  # the segmenter's speech while the edge is judged
        self.word: list[bytes] = []  # the word carried across the edge, from LOOKBACK_S before it
        self.lookback_bytes = 0  # how much of ``word`` is from before the edge
        self.segment_began: str | None = None  # the state the segmenter's utterance in progress began in
        #: for the utterance the segmenter yields next: whether it began at an edge, and then the whole word (from
        #: ``LOOKBACK_S`` before the edge, on), how much of it is from before the edge, and the edge's capture time
        self.whole: tuple[bytes, int, float] | None = None
        #: ... how far its first EDGE_S was above the quiet, dB (what MARK_ABOVE_DB is judged on)
        self.edge_gap_db: float | None = None
        self.began_deaf = False  # ... it began over the bridge's own sound: only its end is here

    def chunk(self, start_t: float, deaf: bool, pcm: bytes) -> bool:
        """One block captured at ``start_t``; whether the segmenter is to hear it (else silence)."""
        was, self.deaf = self.deaf, deaf
        if deaf:
            if not was:
                if self.state == "open":  # the segmenter's speech so far is decided on its own
                    self.on_speech(None)
                elif self.state == "carry" and self.word:
                    self.on_speech(None)
                self.floor_db = float(np.percentile(self.room, 20)) if self.room else -30.0
                self.state, self.held, self.word = "open", [], []
                self.recent.clear()
                self.deaf_levels = []
            cleaned = self.clean(start_t, pcm) if self.clean is not None else pcm
            self.recent.append(pcm)
            self.deaf_levels.append(_level_db(cleaned))
            self.over_voice(cleaned)
            return False
        if was:  # the end of the deaf time: is the pilot speaking?
            self.state, self.edge_t, self.edge_loud, self.held, self.edge = "edge", start_t, False, [], []
        if self.state == "open":
            self.room.append(_level_db(pcm))
            return True
        if self.state == "edge":
            self.over_voice(pcm)  # as it is: the deaf time ends when nothing of the bridge's is left in the room
            self.edge.append(pcm)
            self.edge_loud = self.edge_loud or _level_db(pcm) >= self.floor_db + UNDER_WAY_DB
            if start_t + self.block_s >= self.edge_t + EDGE_S - 1e-6:
                self._judge_edge()
        else:
            if self.word:
                self.word.append(pcm)
                self.on_speech(pcm)
            if self.segment_began is None and start_t > self.edge_t + CARRY_LIMIT_S:
                self._end_carry()  # the segmenter never found the speech: let the word go
        return True

    def _judge_edge(self) -> None:
        self.over_voice(None)  # the deaf time's stream is decided on its own
        if self.edge_loud and self.carry == "lookback":
            self.state = "carry"
            self.word = [*self.recent, *self.edge]
            self.lookback_bytes = sum(map(len, self.recent))
            lookback_levels = self.deaf_levels[len(self.deaf_levels) - len(self.recent):]  # ``recent``, less the echo
            start = max(lookback_levels[:max(1, round(EDGE_S / self.block_s))], default=-30.0)
            quiet = max(self.floor_db, float(np.percentile(self.deaf_levels, 10)) if self.deaf_levels else -30.0)
            self.lookback_rise_db = start - quiet
            self.on_speech(b"".join(self.word))
            return
        self.state = "open"
        for held in self.held:  # the segmenter's listener has its speech from its start
            self.on_speech(held)
        self.held = []

    @staticmethod
    def word_to(carried: tuple[bytes, int, float], end_t: float) -> bytes:
        """A carried word (``whole`` or ``carrying``) up to ``end_t``, on the clock ``chunk`` was given."""
        word, before, edge_t = carried
        return word[:before + 2 * max(0, round((end_t - edge_t) * SAMPLE_RATE))]

    def carrying(self) -> tuple[bytes, int, float] | None:
        """The word being carried across the edge so far (as ``whole``), while the segmenter's utterance of it goes on."""
        if self.state == "carry" and self.word and self.segment_began in ("edge", "carry"):
            return b"".join(self.word), self.lookback_bytes, self.edge_t
        return None

    def _end_carry(self) -> None:
        if self.word:
            self.on_speech(None)
        self.state, self.word = "open", []

    def segmenter_speech(self, pcm: bytes | None) -> None:
        """The segmenter's listener: its utterance's audio, then None at its end."""
        if pcm is not None and self.segment_began is None:
            self.segment_began = self.state
        if pcm is None:
            began, self.segment_began = self.segment_began, None
            self.whole, self.edge_gap_db, self.began_deaf = None, None, False
            if began in ("edge", "carry") and self.word and not self.deaf:
                word = b"".join(self.word)
                self.whole = (word, self.lookback_bytes, self.edge_t)
                self.edge_gap_db = self.lookback_rise_db
                self.began_deaf = self.edge_gap_db >= MARK_ABOVE_DB
        if self.deaf:
            return  # while deaf the listener has the microphone's own audio instead
        if self.state == "edge":
            self.held.append(pcm)
        elif self.state == "carry":
            if pcm is None:  # the word said across the edge has ended: so does its stream
                self._end_carry()
        else:
            self.on_speech(pcm)


def microphone_utterances(talk: threading.Event | None = None, device: int | str | None = None,
                          on_speech: Callable[[bytes | None], None] | None = None,
                          on_tentative: Callable[[bytes], None] | None = None,
                          chunks: Iterable[AudioChunk] | None = None,
                          deaf: Callable[[float, float], bool] | None = None,
                          clean: Callable[[float, bytes], bytes] | None = None,
                          on_speech_over_voice: Callable[[bytes | None], None] | None = None,
                          speaking: Callable[[bool], None] | None = None
                          ) -> Iterator[HeardUtterance]:
    """Each utterance (PCM, UNIX time the speech ended, whether it began deaf), until the consumer stops.

    ``talk`` is the push-to-talk key (None: always listening): while it is clear, silence is fed.
    ``on_speech`` hears each utterance's audio while it is spoken; ``on_tentative`` gets an utterance's
    PCM as soon as it is final if no speech follows (see ``segment_utterances``). ``chunks`` replaces the
    microphone (``gcs_voice.audio.sources.paced_chunks``: a recording heard as if spoken now).
    ``deaf(from_t, to_t)`` says whether audio captured then (UNIX times) may be the bridge's own sound;
    ``clean(start_t, pcm)`` takes the bridge's own sound out of what the listener hears while deaf, and
    ``on_speech_over_voice`` (default ``on_speech``) hears that deaf time's audio, as a stream of its own: it is
    judged more strictly, since what is left of the bridge's words can sound like a stop word; a word said across
    the end of the deaf time goes to it whole (``_Ear``). ``speaking(True)`` is said while the segmenter is in an
    utterance (from its first sign of speech to the end of its closing silence), ``speaking(False)`` after: the
    bridge's speaker waits for it (``EchoGate.pilot_speaking``).
    """
    from gcs_voice.audio.sources import AudioChunk, microphone_chunks
    from gcs_voice.audio.vad import segment_utterances

    ignore = (lambda pcm: None)
    ear = _Ear(on_speech or ignore, on_speech_over_voice or on_speech or ignore, clean, MICROPHONE_BLOCK_S)
    t0: list[float] = []
    #: captured (UNIX time of its first sample) = captured_t0 + chunk.start_s; a chunk arrives once captured
    captured_t0: list[float] = []

    def gated() -> Iterator[AudioChunk]:
        for chunk in (microphone_chunks(device) if chunks is None else chunks):
            # A chunk arrives once captured, never before, and late when this thread was busy: the clock is the
            # earliest arrival seen (taken from the first chunk alone, a first chunk held up set it late for the
            # whole session: the deaf time and the echo canceller's reference off by as much)
            now = time.time()
            if not t0:
                t0.append(now - chunk.start_s)
                captured_t0.append(now - chunk.start_s - chunk.duration_s)
            else:
                t0[0] = min(t0[0], now - chunk.start_s)
                captured_t0[0] = min(captured_t0[0], now - chunk.start_s - chunk.duration_s)
            if talk is not None and not talk.is_set():
                chunk = AudioChunk(bytes(len(chunk.pcm)), chunk.start_s)
            elif deaf is not None:
                start_t = captured_t0[0] + chunk.start_s
                if not ear.chunk(start_t, deaf(start_t, start_t + chunk.duration_s), chunk.pcm):
                    chunk = AudioChunk(bytes(len(chunk.pcm)), chunk.start_s)
            yield chunk

    segmenter_listener = on_speech if deaf is None else ear.segmenter_speech

    def listen(pcm: bytes | None) -> None:
        if speaking is not None:
            speaking(pcm is not None)
        if segmenter_listener is not None:
            segmenter_listener(pcm)

    def whole(utterance: Utterance, carried: tuple[bytes, int, float] | None) -> bytes:
        """The utterance, or when it began at the edge the whole word (from before the edge) to its end."""
        return utterance.pcm if carried is None else ear.word_to(carried, captured_t0[0] + utterance.end_s)

    tentative = ((lambda utt: on_tentative(whole(utt, ear.carrying()))) if on_tentative is not None else None)
    for utterance in segment_utterances(gated(), on_speech=listen, on_tentative=tentative):
        yield HeardUtterance(whole(utterance, ear.whole), t0[0] + utterance.end_s, ear.began_deaf, utterance.snr_db)
