"""Live utterances for a session: the microphone through the segmenter, always listening or push-to-talk.

Push-to-talk (``--push-to-talk``) gates the same stream: while the talk key is not held open the
segmenter is fed silence, so closing it ends the utterance at once and nothing said outside it counts.
Each utterance comes with the wall-clock time its speech ended (the segmenter's end, not the moment
its hangover ran out), which is where latency is counted from.

The bridge never hears itself (``deaf``, an ``gcs_voice.audio.speaker.EchoGate``): while its own sound may
be in the microphone, the segmenter is fed silence, so that sound never becomes an utterance, and the
speech listener (the stop spotter) is fed the microphone itself, less the echo of what the bridge played
(``clean``, a ``gcs_voice.audio.echo_cancel.PlayedEcho``), so a "stop" said over the bridge's voice still
stops. That listener hears one stream at a time: the segmenter's speech, or the deaf time's audio.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gcs_voice.audio.sources import AudioChunk

__all__ = ["microphone_utterances", "check_microphone"]


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


def microphone_utterances(talk: threading.Event | None = None, device: int | str | None = None,
                          on_speech: Callable[[bytes | None], None] | None = None,
                          on_tentative: Callable[[bytes], None] | None = None,
                          chunks: Iterable[AudioChunk] | None = None,
                          deaf: Callable[[float, float], bool] | None = None,
                          clean: Callable[[float, bytes], bytes] | None = None,
                          on_speech_over_voice: Callable[[bytes | None], None] | None = None
                          ) -> Iterator[tuple[bytes, float]]:
    """(PCM, UNIX time the speech ended) per utterance, until the consumer stops.

    ``talk`` is the push-to-talk key (None: always listening): while it is clear, silence is fed.
    ``on_speech`` hears each utterance's audio while it is spoken; ``on_tentative`` gets an utterance's
    PCM as soon as it is final if no speech follows (see ``segment_utterances``). ``chunks`` replaces the
    microphone (``gcs_voice.audio.sources.paced_chunks``: a recording heard as if spoken now).
    ``deaf(from_t, to_t)`` says whether audio captured then (UNIX times) may be the bridge's own sound;
    ``clean(start_t, pcm)`` takes the bridge's own sound out of what the listener hears while deaf, and
    ``on_speech_over_voice`` (default ``on_speech``) hears that deaf time's audio, as a stream of its own: it is
    judged more strictly, since what is left of the bridge's words can sound like a stop word.
    """
    from gcs_voice.audio.sources import AudioChunk, microphone_chunks
    from gcs_voice.audio.vad import segment_utterances

    over_voice = on_speech_over_voice or on_speech
    t0: list[float] = []
    #: captured (UNIX time of its first sample) = captured_t0 + chunk.start_s; a chunk arrives once captured
    captured_t0: list[float] = []
    deaf_now = [False]

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
                was, deaf_now[0] = deaf_now[0], deaf(start_t, start_t + chunk.duration_s)
                if was != deaf_now[0] and on_speech is not None:
                    # one stream ends where the other starts: the segmenter's speech so far when the bridge
                    # starts to speak, the deaf time's audio when it has finished; the listener decides on each
                    (over_voice if was else on_speech)(None)
                if deaf_now[0]:
                    if on_speech is not None:
                        over_voice(clean(start_t, chunk.pcm) if clean is not None else chunk.pcm)
                    chunk = AudioChunk(bytes(len(chunk.pcm)), chunk.start_s)
            yield chunk

    def segmenter_speech(pcm: bytes | None) -> None:
        if not deaf_now[0]:  # while deaf the listener has the microphone's own audio instead
            on_speech(pcm)

    listen = on_speech if deaf is None or on_speech is None else segmenter_speech
    tentative = (lambda utt: on_tentative(utt.pcm)) if on_tentative is not None else None
    for utterance in segment_utterances(gated(), on_speech=listen, on_tentative=tentative):
        yield utterance.pcm, t0[0] + utterance.end_s
