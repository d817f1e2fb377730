"""A word said across the end of the deaf time: the stop spotter hears it whole, and the rest is not acted on.

While the bridge speaks the segmenter is deaf (it is fed silence) and the stop spotter hears the microphone less
the bridge's echo. A pilot who speaks as the deaf time ends had the word cut in two: its start went to the stream
over the bridge's voice, its end to the segmenter. Live (session 27, tools.listen.bench_feedback_echo), a real "stop"
said over the end of "fence reached" was cut so and never heard as a stop by either half. Real parts: the bridge's
cues as espeak-ng renders them, real held-out recordings of ../shared/speech, the microphone path in real time with
the echo room of ``--listen-wav`` sessions, PocketSphinx's stop spotter, Whisper's decision.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.echo_cancel import EchoCanceller, PlayedEcho
from gcs_voice.audio.microphone import microphone_utterances
from gcs_voice.audio.sources import paced_chunks, read_wav
from gcs_voice.audio.speaker import EchoGate, EchoRoom
from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.feedback import load_sound_settings
from tools.listen.bench_deaf_edge import SpotterStreams
from tools.listen.bench_echo import room_response, voiced_dbfs
from tools.listen.streams import voiced_level

DELAY_S = 0.06
PILOT_DBFS = -26.0


def _cue(tone_name: str, words: str) -> bytes:
    from gcs_voice.audio.sounds import Speech, tone

    s = load_sound_settings()
    try:
        said = Speech("en-us", s.speed_wpm).say(words)
    except GcsVoiceError as exc:
        pytest.skip(str(exc))
    return tone(s.tones[tone_name], s.amplitude, s.fade_s) + said


def _clip(path: Path) -> tuple[np.ndarray, float, float]:
    """The recording at the pilot's level, and where its voiced part starts and ends (s)."""
    x = np.frombuffer(read_wav(path), "<i2").astype(np.float64)
    x *= 10 ** ((PILOT_DBFS - voiced_dbfs(x)) / 20)
    _rms, first, last = voiced_level(x / 32768)
    return x, first / SAMPLE_RATE, last / SAMPLE_RATE


def _listen_over_cues(recording: bytes, plays_s: list[float], cue: bytes, canceller: EchoCanceller, block_s: float
                      ) -> tuple[list, SpotterStreams, float, EchoRoom]:
    """The microphone path in real time on ``recording`` (PCM), the bridge playing ``cue`` into the echo room at each
    of ``plays_s`` (recording time; the cue starts with the first block at or after it, and the gate is held once
    that block has arrived, as Feedback does). (utterances, what the spotter was given, the recording's start on the
    path's clock, the room)."""
    settings = load_sound_settings()
    cue_s = len(cue) / 2 / SAMPLE_RATE
    room = EchoRoom(10 ** ((PILOT_DBFS - voiced_dbfs(np.frombuffer(cue, "<i2").astype(np.float64))) / 20), DELAY_S,
                    room_response(0.3, 6.0))
    gate = EchoGate(settings.tail_s)
    heard_streams = SpotterStreams(block_s)
    started_at: list[float] = []

    def chunks():
        pending = list(plays_s)
        for chunk in room.hear(paced_chunks(recording, on_start=lambda t: (started_at.append(t), room.start(t)))):
            heard_streams.where = chunk.start_s
            if pending and chunk.start_s >= pending[0] - 1e-6:
                pending.pop(0)

                def play() -> None:
                    gate.hold(time.time(), cue_s)  # as Feedback does
                    room.play(cue, started=lambda t: gate.record(t, cue))

                threading.Thread(target=play, daemon=True).start()
            yield chunk

    utterances = list(microphone_utterances(on_speech=heard_streams.listener(False),
                                            on_speech_over_voice=heard_streams.listener(True),
                                            chunks=chunks(), deaf=gate.deaf, clean=PlayedEcho(gate, canceller)))
    return utterances, heard_streams, started_at[0] + block_s, room


def _has_voice_at(said: np.ndarray, start_s: float, pcm: bytes, at_s: float) -> bool:
    """Whether ``pcm`` (a stream starting at ``start_s`` of the recording ``said``) has what the pilot said at
    ``at_s`` (not silence fed in its place)."""
    x = np.frombuffer(pcm, "<i2").astype(np.float64)
    i, j = int((at_s - start_s) * SAMPLE_RATE), int(at_s * SAMPLE_RATE)
    n = int(0.05 * SAMPLE_RATE)
    if i < 0 or i + n > x.size:
        return False
    return float(np.sum(x[i:i + n] ** 2)) > 0.25 * float(np.sum(said[j:j + n] ** 2))


def test_a_word_said_across_the_end_of_the_deaf_time_is_heard_whole(real_speech_dir: Path) -> None:
    """Three cues ("fence reached"), each answered by a real held-out word: two stops begun 0.15 s before the
    microphone stops being deaf (in the tail after the bridge's sound: a quick reply), and a spoken sentence begun
    0.5 s before the bridge's sound itself ended. A stream the spotter hears has each stop's voice whole and the
    spotter fires on them; the segmenter's utterance of each stop has its voice from the start and is not marked;
    the sentence, begun over the bridge's sound, is marked (only its end is there: a "turn left" so said must not
    fly "left")."""
    pytest.importorskip("pocketsphinx")
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from tools.speech.real_speech import load_recordings

    settings = load_sound_settings()
    spotter = load_stop_spotter(["en"])
    held_out = load_recordings(real_speech_dir, split="test")
    stops = [c for c in (_clip(r.path) for r in held_out if r.action == "stop")
             if spotter.spot(np.clip(c[0], -32768, 32767).astype("<i2").tobytes()).fired][:2]
    sentence = _clip(next(r.path for r in held_out if r.kind == "sentence"))
    assert len(stops) == 2
    cue = _cue("warning", "fence reached")
    cue_s = len(cue) / 2 / SAMPLE_RATE
    block_s = 512 / SAMPLE_RATE
    # the cue starts with the first block at or after its time, and the gate opens once that block has arrived
    plan, placed, at = [], [], 0.5
    for (clip, voiced_start, voiced_end), before_edge_s in zip((*stops, sentence), (0.15, 0.15, settings.tail_s + 0.5)):
        play_s = np.ceil(at / block_s) * block_s
        edge_s = play_s + block_s + cue_s + settings.tail_s
        said_s = edge_s - before_edge_s - voiced_start
        plan.append((play_s, edge_s, said_s + voiced_start, said_s + voiced_end))
        placed.append((int(round(said_s * SAMPLE_RATE)), clip))
        at = said_s + clip.size / SAMPLE_RATE + 1.5
    mic = np.zeros(int((at + 1.0) * SAMPLE_RATE))
    for offset, clip in placed:
        mic[offset:offset + clip.size] += clip
    recording = np.clip(mic, -32768, 32767).astype("<i2").tobytes()
    utterances, heard_streams, t0, room = _listen_over_cues(recording, [p[0] for p in plan], cue,
                                                            EchoCanceller(**settings.echo_cancel), block_s)
    streams = heard_streams.streams
    assert len(room.played) == 3
    said = np.frombuffer(recording, "<i2").astype(np.float64)

    def has_voice_at(start_s: float, pcm: bytes, at_s: float) -> bool:
        return _has_voice_at(said, start_s, pcm, at_s)

    fired = 0
    for play_s, edge_s, voiced_start_s, voiced_end_s in plan[:2]:
        whole = [(over, b"".join(parts)) for over, start_s, parts in streams
                 if has_voice_at(start_s, b"".join(parts), voiced_start_s + 0.02)
                 and has_voice_at(start_s, b"".join(parts), voiced_end_s - 0.07)]
        assert whole, (f"no stream the spotter heard has the stop's voice ({voiced_start_s:.2f}-{voiced_end_s:.2f} s, "
                       f"the deaf time ended {edge_s:.2f} s) whole")
        fired += any(spotter.spot(pcm, over).fired for over, pcm in whole)
    # whether the spotter fires on a word is its own business (tools.listen.bench_deaf_edge measures it): here, that what
    # it is given is a word it can hear
    assert fired >= 1, "the spotter heard neither stop, each whole in a stream of its own"
    # the segmenter's utterances, in the recording's time (the path's clock starts once the first block arrived)
    spans = [(u.end_t - t0 - len(u.pcm) / 2 / SAMPLE_RATE, u.end_t - t0, u) for u in utterances]
    for n, (play_s, edge_s, voiced_start_s, voiced_end_s) in enumerate(plan):
        mine = [u for start_s, end_s, u in spans if start_s < voiced_end_s and end_s > voiced_start_s]
        assert mine, (n, [(round(a, 2), round(b, 2)) for a, b, _u in spans], plan)
        if n < 2:  # a quick reply: the whole word, from its start, and acted on as any
            assert not mine[0].began_deaf
            start_s = mine[0].end_t - t0 - len(mine[0].pcm) / 2 / SAMPLE_RATE
            assert has_voice_at(start_s, mine[0].pcm, voiced_start_s + 0.05), "the utterance lacks the word's start"
        else:  # begun over the bridge's own sound: only its end is there
            assert mine[0].began_deaf, [round(b - a, 2) for a, b, _u in spans]


def test_what_began_over_the_bridge_voice_is_not_acted_on_unless_it_is_a_stop(whisper_model_dir: Path,
                                                                               real_speech_dir: Path) -> None:
    """Only the end of a word begun during the deaf time reaches the decision ("left" of a "turn left"): a motion
    heard in it is not flown, a stop is (stopping is always safe). Whisper on real held-out recordings."""
    pytest.importorskip("faster_whisper")
    from gcs_voice.session.events import EventBus
    from gcs_voice.session.listen import VoicePipeline
    from gcs_voice.session.run import load_voice
    from tools.speech.real_speech import load_recordings

    recognizer, matcher, dictionaries, lang = load_voice("en", "whisper", str(whisper_model_dir), None)
    pipeline = VoicePipeline(recognizer, matcher, dictionaries, lang, EventBus(), realtime=False)
    held_out = load_recordings(real_speech_dir, split="test")

    def first_acted(action: str) -> bytes:
        for rec in held_out:
            if rec.action == action:
                pcm = read_wav(rec.path)
                if pipeline.hear(pcm, rec.path.name).action == action:
                    return pcm
        raise AssertionError(f"no held-out {action} decided right")

    left, stop = first_acted("go_left"), first_acted("stop")
    cut = pipeline.hear(left, "left", began_deaf=True)
    assert cut.action is None and "began while the bridge was speaking" in cut.reason, cut
    assert pipeline.hear(stop, "stop", began_deaf=True).action == "stop"


def test_the_deaf_time_counts_from_when_the_sound_really_started() -> None:
    """A player's output latency (PortAudio reports up to 0.2 s) delays the sound after the gate was held: the
    deaf time runs to the sound's real end plus the tail, so the tail stays whole for the room (and what the
    spotter is given from just before the deaf time's end holds none of the bridge's own voice)."""
    gate = EchoGate(0.4)
    gate.hold(100.0, 1.0)
    gate.record(100.2, bytes(2 * SAMPLE_RATE))  # one second of sound, out 0.2 s after the gate was held
    assert gate.deaf(101.5, 101.55)  # held alone, the deaf time ended at 101.4
    assert not gate.deaf(101.65, 101.7)
    gate.record(200.0, bytes(2 * SAMPLE_RATE))  # a sound nobody held for is still one the microphone hears
    assert gate.deaf(201.3, 201.35)
