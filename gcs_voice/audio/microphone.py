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
pilot is still speaking as the deaf time ends, the deaf time's stream goes on until the segmenter's utterance ends
(the stop spotter hears the word whole, not its start over the bridge and its end alone), and that utterance is
marked: the segmenter heard only its end, so the session does not act on it (a "turn left" begun over the
bridge's voice must not fly "left").
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
#: the utterance is marked as begun deaf when those blocks were within this of its loudest block after the edge:
#: its voice, not the breath or the room before a word said just after the edge
MARK_DB = 12.0
#: speech under way at the edge that the segmenter has not found within this long is let go
CARRY_LIMIT_S = 1.0
#: the stream that carries a word said across the edge starts this long before it (the end of the deaf time is
#: the tail after the bridge's sound: the speaker's latency and the room)
LOOKBACK_S = 0.3


class HeardUtterance(NamedTuple):
    """One utterance of the microphone path."""

    pcm: bytes
    #: UNIX time its speech ended
    end_t: float
    #: it was under way when the microphone stopped being deaf to the bridge's own sound: only its end is here
    began_deaf: bool = False


def _level_db(pcm: bytes) -> float:
    x = np.frombuffer(pcm, "<i2").astype(np.float64)
    return float(10 * np.log10(np.mean(x * x) + 1e-3)) if x.size else -30.0


class _Ear:
    """Which listener hears the microphone, block by block, when it has a deaf time (see the module's docstring).

    A word said across the end of the deaf time is not cut in two. When the pilot is speaking as the microphone stops
    being deaf (a block of the first ``EDGE_S`` well above the room before the bridge spoke), one stream carries the
    word until the segmenter's utterance ends, and that utterance is marked (``began_deaf``: the segmenter has only
    its end). ``carry`` says which stream: ``"lookback"``, a stream of its own for the listener that starts
    ``LOOKBACK_S`` before the edge, the microphone as it is (the deaf time's stream ends at the edge, as it did
    before); ``"over_voice"``, the deaf time's stream goes on; ``"none"``, none (the word is cut, as before)."""

    def __init__(self, on_speech: Callable[[bytes | None], None], over_voice: Callable[[bytes | None], None],
                 clean: Callable[[float, bytes], bytes] | None, block_s: float, carry: str = "lookback") -> None:
        if carry not in ("lookback", "over_voice", "none"):
            raise ValueError(f"carry must be lookback, over_voice or none, not {carry!r}")
        self.on_speech = on_speech
        self.over_voice = over_voice
        self.clean = clean
        self.carry = carry
        self.block_s = block_s
        self.deaf = False
        self.state = "open"  # open | edge (judging the first blocks after the deaf time) | carry
        self.edge_t = 0.0
        self.edge_loud = False
        self.edge_db = -30.0  # the loudest block of the first EDGE_S after the edge
        self.peak_db = -30.0  # the loudest block since the edge
        self.floor_db = -30.0
        self.room: deque[float] = deque(maxlen=max(1, round(ROOM_S / block_s)))
        self.recent: deque[bytes] = deque(maxlen=max(1, round(LOOKBACK_S / block_s)))  # the raw deaf audio
        self.edge: list[bytes] = []  # the blocks since the edge, while it is judged
        self.held: list[bytes | None] = []  # the segmenter's speech while the edge is judged
        self.carried: Callable[[bytes | None], None] | None = None  # the stream that carries the word
        self.segment_began: str | None = None  # the state the segmenter's utterance in progress began in
        self.began_deaf = False  # the utterance the segmenter yields next began deaf
        #: for the utterance the segmenter yields next, when it began at an edge: its loudest block after the edge
        #: less the loudest of the edge's, dB (None otherwise; what MARK_DB is judged on)
        self.edge_gap_db: float | None = None

    def chunk(self, start_t: float, deaf: bool, pcm: bytes) -> bool:
        """One block captured at ``start_t``; whether the segmenter is to hear it (else silence)."""
        was, self.deaf = self.deaf, deaf
        if deaf:
            if not was:
                if self.state == "open":  # the segmenter's speech so far is decided on its own
                    self.on_speech(None)
                elif self.carried is not None and self.carried is not self.over_voice:
                    self.carried(None)
                self.floor_db = float(np.percentile(self.room, 20)) if self.room else -30.0
                self.state, self.held, self.carried = "open", [], None
                self.recent.clear()
            self.recent.append(pcm)
            self.over_voice(self.clean(start_t, pcm) if self.clean is not None else pcm)
            return False
        if was:  # the end of the deaf time: is the pilot speaking?
            self.state, self.edge_t, self.edge_loud, self.held, self.edge = "edge", start_t, False, [], []
            self.edge_db = self.peak_db = -30.0
        level = _level_db(pcm)
        self.peak_db = max(self.peak_db, level)
        if self.state == "open":
            self.room.append(level)
            return True
        if self.state == "edge":
            self.over_voice(pcm)  # as it is: the deaf time ends when nothing of the bridge's is left in the room
            self.edge.append(pcm)
            self.edge_db = max(self.edge_db, level)
            self.edge_loud = self.edge_loud or level >= self.floor_db + UNDER_WAY_DB
            if start_t + self.block_s >= self.edge_t + EDGE_S - 1e-6:
                self._judge_edge()
        else:
            if self.carried is not None:
                self.carried(pcm)
            if self.segment_began is None and start_t > self.edge_t + CARRY_LIMIT_S:
                self._end_carry()  # the segmenter never found the speech: let the stream go
        return True

    def _judge_edge(self) -> None:
        if self.edge_loud and self.carry == "over_voice":
            self.state, self.carried = "carry", self.over_voice
            return
        self.over_voice(None)  # the deaf time's stream is decided on its own
        if self.edge_loud and self.carry == "lookback":
            self.state, self.carried = "carry", self.on_speech
            self.on_speech(b"".join([*self.recent, *self.edge]))
            return
        self.state = "carry" if self.edge_loud else "open"  # "none": the word is cut, its end still marked
        for held in self.held:  # the segmenter's listener has its speech from its start
            self.on_speech(held)
        self.held = []

    def _end_carry(self) -> None:
        carried, self.carried, self.state = self.carried, None, "open"
        if carried is not None:
            carried(None)

    def segmenter_speech(self, pcm: bytes | None) -> None:
        """The segmenter's listener: its utterance's audio, then None at its end."""
        if pcm is not None and self.segment_began is None:
            self.segment_began = self.state
        if pcm is None:
            began, self.segment_began = self.segment_began, None
            at_edge = began in ("edge", "carry") and self.edge_loud
            self.edge_gap_db = self.peak_db - self.edge_db if at_edge else None
            self.began_deaf = self.edge_gap_db is not None and self.edge_gap_db <= MARK_DB
        if self.deaf:
            return  # while deaf the listener has the microphone's own audio instead
        if self.state == "edge":
            self.held.append(pcm)
        elif self.carried is not None:
            if pcm is None:  # the word said across the edge has ended: so does its stream
                self._end_carry()
        else:
            if self.state == "carry" and pcm is None:
                self.state = "open"
            self.on_speech(pcm)


def microphone_utterances(talk: threading.Event | None = None, device: int | str | None = None,
                          on_speech: Callable[[bytes | None], None] | None = None,
                          on_tentative: Callable[[bytes], None] | None = None,
                          chunks: Iterable[AudioChunk] | None = None,
                          deaf: Callable[[float, float], bool] | None = None,
                          clean: Callable[[float, bytes], bytes] | None = None,
                          on_speech_over_voice: Callable[[bytes | None], None] | None = None
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
    the end of the deaf time goes to it whole (``_Ear``).
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

    listen = on_speech if deaf is None else ear.segmenter_speech
    tentative = (lambda utt: on_tentative(utt.pcm)) if on_tentative is not None else None
    for utterance in segment_utterances(gated(), on_speech=listen, on_tentative=tentative):
        yield HeardUtterance(utterance.pcm, t0[0] + utterance.end_s, ear.began_deaf)
