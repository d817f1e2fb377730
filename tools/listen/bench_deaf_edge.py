#!/usr/bin/env python3
"""A word said across the end of the deaf time: does the stop spotter hear it, and is its end acted on?

While the bridge speaks the segmenter is deaf and the stop spotter hears the microphone less the bridge's echo
(gcs_voice.audio.microphone). A pilot who speaks as the deaf time ends has the word cut in two: live (session
27), a real "stop" said over the end of "fence reached" was heard by neither half. This plays real words of
../shared/speech so that the deaf time ends 0.1 to 0.6 s into their voice (begun in the deaf time's tail, or over the
bridge's sound itself; and, for the cost, words said 0.1 and 0.3 s after it), over the bridge's cues in the textbook room of tools.listen.bench_echo, through the microphone path's
own ear (``gcs_voice.audio.microphone._Ear``, driven offline block by block on the recording's clock), the
session's echo canceller and PocketSphinx's stop spotter, with each way of carrying the word (``carry``):

- ``none``: as before: the deaf time's stream ends at the edge, the segmenter's listener hears the rest, and the
  segmenter's utterance is what came after the edge;
- ``lookback`` (shipped): the word is taken from ``LOOKBACK_S`` before the edge, the microphone as it is: a stream of
  its own for the spotter, and the segmenter's utterance; marked when it began over the bridge's sound itself.

Counted per word: a stop fired in any stream that overlaps it (for stops: heard; for other commands: a false
stop), whether the segmenter's utterance of it was marked as begun deaf, and (``--decide``) what the session's
decision made of the utterances (Whisper base, the shipped matcher; a marked one acts only if it is a stop).

    python -m tools.listen.bench_deaf_edge --split dev --out docs/bench/deaf_edge_dev.md

Its held-out outcome: docs/bench/feedback_echo.md (Tried and not taken); its last full reports: git history:
docs/bench/deaf_edge_*.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.echo_cancel import EchoCanceller, PlayedEcho
from gcs_voice.audio.microphone import MARK_ABOVE_DB, _Ear
from gcs_voice.audio.sources import MICROPHONE_BLOCK_S, AudioChunk, pcm_to_chunks
from gcs_voice.audio.speaker import EchoGate
from gcs_voice.audio.vad import segment_utterances
from gcs_voice.session.feedback import load_sound_settings
from tools.listen.bench_echo import room_response, voiced_dbfs
from tools.listen.streams import voiced_level
from tools.speech.real_speech import SHARED, load_recordings, read_wav

PILOT_DBFS = -26.0
DELAY_S = 0.06
MODES = ("none", "lookback")
#: where the pilot's voice starts against the end of the deaf time (s): negative = before it (the word straddles)
OFFSETS = (-0.6, -0.3, -0.2, -0.1, 0.1, 0.3)
#: the offsets in three groups: begun over the bridge's sound itself (it ends 0.4 s, the tail, before the edge), in
#: its tail, after the edge
GROUPS = (("over the bridge's sound", lambda o: o < -0.4), ("in its tail", lambda o: -0.4 <= o < 0),
          ("after the edge", lambda o: o > 0))
CUES = (("warning", "fence reached"), ("doing", "going down"))
#: the session's earlier answers, which teach the canceller the room (as in tests/test_echo_cancel.py)
MARK_GRID = (3.0, 6.0, 9.0, 12.0, 15.0, 20.0)
WARM_UP = (("doing", "going left"), ("refused", "refused, not armed"), ("doing", "going back"))


@dataclass(frozen=True)
class Trial:
    """One word placed against one cue's deaf time, heard one way."""

    action: str
    offset_s: float
    cue: str
    room: str
    mode: str
    stopped: bool
    marked: bool | None  # None: the segmenter yielded nothing of the word
    #: of the segmenter's utterance of the word, begun at an edge: how far its start was above the quiet (None: not so)
    gap_db: float | None
    #: the same recording without the word fired a stop (the cue's remains): the trial says nothing of the word
    remains_fired: bool
    #: what the decision did with the segmenter's utterances of the word: "right", "wrong", "none" (or "" undecided)
    decided: str = ""


class SpotterStreams:
    """What the stop spotter is given, as the session's StopPath takes it: one stream at a time, a new one when the
    other listener speaks or after an end; each kept as (over the bridge's voice, recording time it starts, audio).
    Set ``where`` to the recording time of the block being heard."""

    def __init__(self, block_s: float) -> None:
        self.block_s = block_s
        self.where = 0.0
        self.streams: list[tuple[bool, float, list[bytes]]] = []
        self._current: int | None = None

    def listener(self, over_voice: bool) -> Callable[[bytes | None], None]:
        def hear(pcm: bytes | None) -> None:
            if pcm is None:  # the end of the stream, whichever it is
                self._current = None
                return
            if self._current is None or self.streams[self._current][0] != over_voice:
                self.streams.append((over_voice, self.where + self.block_s - len(pcm) / 2 / SAMPLE_RATE, []))
                self._current = len(self.streams) - 1
            self.streams[self._current][2].append(pcm)
        return hear


def _cue(tone_name: str, words: str) -> np.ndarray:
    from gcs_voice.audio.sounds import Speech, tone

    s = load_sound_settings()
    pcm = tone(s.tones[tone_name], s.amplitude, s.fade_s) + Speech("en-us", s.speed_wpm).say(words)
    return np.frombuffer(pcm, "<i2").astype(np.float64)


def _word(path: Path) -> tuple[np.ndarray, float, float]:
    x = read_wav(path).astype(np.float64) * 32768
    x *= 10 ** ((PILOT_DBFS - voiced_dbfs(x)) / 20)
    _rms, first, last = voiced_level(x / 32768)
    return x, first / SAMPLE_RATE, last / SAMPLE_RATE


def run_trial(word: np.ndarray, voiced: tuple[float, float], offset_s: float, cue: np.ndarray, warm: list[np.ndarray],
              noise: np.ndarray | None, mode: str, spotter, settings, alone: bool = False
              ) -> tuple[bool, bool | None, float | None, list[tuple[bytes, bool]]]:
    """One recording: the warm-up cues (the session's earlier answers, 1 s apart) from 0.3 s, the cue, the word ``offset_s`` from the cue's deaf time's end; the
    stops fired in streams overlapping the word, whether the segmenter's utterance of it was marked and its gap, and
    the utterances overlapping the word (PCM, marked) as the session would decide them. ``alone``:
    the same recording without the word (what the cue's remains fire by themselves)."""
    block = MICROPHONE_BLOCK_S
    blocks = lambda s: np.ceil(s / block - 1e-9) * block  # noqa: E731 - a cue starts on a block
    room = room_response(0.3, 6.0)
    gain = 10 ** ((PILOT_DBFS - voiced_dbfs(cue)) / 20)
    sounds, at = [], 0.3
    for sound in warm:
        sounds.append((blocks(at), sound))
        at = blocks(at) + sound.size / SAMPLE_RATE + settings.tail_s + 1.0
    cue_at = blocks(at)
    sounds.append((cue_at, cue))
    edge_s = cue_at + cue.size / SAMPLE_RATE + settings.tail_s
    said_s = edge_s + offset_s - voiced[0]
    n = int((said_s + word.size / SAMPLE_RATE + 2.0) * SAMPLE_RATE)
    mic = np.zeros(n)
    gate = EchoGate(settings.tail_s)
    for at, sound in sounds:
        echo = np.convolve(sound * gain, room)
        i = int(round((at + DELAY_S) * SAMPLE_RATE))
        mic[i:i + echo.size] += echo[:max(0, n - i)]
        gate.hold(at, sound.size / SAMPLE_RATE)
        gate.record(at, np.clip(sound * gain, -32768, 32767).astype("<i2").tobytes())
    i = int(round(said_s * SAMPLE_RATE))
    mic[i:i + word.size] += word * (0.0 if alone else 1.0)
    if noise is not None:
        mic += noise[:n]
    pcm = np.clip(np.round(mic), -32768, 32767).astype("<i2").tobytes()
    clean = PlayedEcho(gate, EchoCanceller(**settings.echo_cancel))
    heard_streams = SpotterStreams(block)

    ear = _Ear(heard_streams.listener(False), heard_streams.listener(True), clean, block, carry=mode)

    def chunks():
        for chunk in pcm_to_chunks(pcm, block):
            heard_streams.where = chunk.start_s
            deaf = gate.deaf(chunk.start_s, chunk.start_s + chunk.duration_s)
            yield chunk if ear.chunk(chunk.start_s, deaf, chunk.pcm) else AudioChunk(bytes(len(chunk.pcm)),
                                                                                         chunk.start_s)

    marked, gap, heard = None, None, []
    word_span = (said_s + voiced[0], said_s + voiced[1])
    for utt in segment_utterances(chunks(), on_speech=ear.segmenter_speech):
        if utt.start_s < word_span[1] and utt.end_s > word_span[0]:
            marked = ear.began_deaf if marked is None else marked or ear.began_deaf
            gap = ear.edge_gap_db if gap is None else gap
            pcm_ = utt.pcm
            if ear.whole is not None:  # as microphone_utterances does: the whole word, to the utterance's end
                pcm_ = ear.word_to(ear.whole, utt.end_s)
            heard.append((pcm_, ear.began_deaf))
    stopped = False
    for over_voice, start_s, parts in heard_streams.streams:
        audio = b"".join(parts)
        end_s = start_s + len(audio) / 2 / SAMPLE_RATE
        if start_s < word_span[1] + 0.1 and end_s > word_span[0] - 0.1 and spotter.spot(audio, over_voice).fired:
            stopped = True
    return stopped, marked, gap, heard


def run(split: str, limit: int, rooms: list[str], decide: bool) -> list[Trial]:
    from gcs_voice.asr.stop_spotter import load_stop_spotter

    pipeline = None
    if decide:
        from gcs_voice.session.events import EventBus
        from gcs_voice.session.listen import VoicePipeline
        from gcs_voice.session.run import load_voice

        recognizer, matcher, dictionaries, lang = load_voice("en", "whisper", str(SHARED / "models" /
                                                                                  "faster-whisper-base"), None)
        pipeline = VoicePipeline(recognizer, matcher, dictionaries, lang, EventBus(), realtime=False)

    def decided(action: str, heard: list[tuple[bytes, bool]]) -> str:
        if pipeline is None:
            return ""
        done = [d.action for d in (pipeline.hear(pcm, "edge", began_deaf=m) for pcm, m in heard) if d.action]
        return "none" if not done else "right" if done[0] == action else "wrong"

    settings = load_sound_settings()
    spotter = load_stop_spotter(["en"])
    recs = load_recordings(split=split)
    per_class = Counter()
    chosen = []
    for r in recs:  # every stop, and as many of the other commands as limit allows
        if r.kind != "command" or (r.action != "stop" and per_class[r.action] >= limit // 4):
            continue
        per_class[r.action] += 1
        chosen.append(r)
    stops = [r for r in chosen if r.action == "stop"][:limit]
    others = [r for r in chosen if r.action != "stop"][:limit]
    warm = [_cue(tone_name, words) for tone_name, words in WARM_UP]
    cues = {words: _cue(tone_name, words) for tone_name, words in CUES}
    kitchen = read_wav(SHARED / "noise" / "doing_the_dishes.wav").astype(np.float64) * 32768
    trials: list[Trial] = []
    started = time.monotonic()
    for k, rec in enumerate(stops + others):
        word, v0, v1 = _word(rec.path)
        for room_name in rooms:
            noise = None
            if room_name != "silent":
                snr = float(room_name.removeprefix("kitchen"))
                n = int(20 * SAMPLE_RATE)
                start = (k * 7919) % max(1, kitchen.size - n)
                noise = kitchen[start:start + n]
                noise = noise * 10 ** ((PILOT_DBFS - snr - voiced_dbfs(noise)) / 20)
            for words, cue in cues.items():
                for offset in OFFSETS:
                    # the same, the word left out: what the cue's remains fire by themselves
                    remains = run_trial(word, (v0, v1), offset, cue, warm, noise, "none", spotter, settings,
                                        alone=True)[0]
                    for mode in MODES:
                        stopped, marked, gap, heard = run_trial(word, (v0, v1), offset, cue, warm, noise, mode, spotter,
                                                                settings)
                        trials.append(Trial(rec.action, offset, words, room_name, mode, stopped, marked, gap, remains,
                                            decided(rec.action, heard)))
        print(f"  {k + 1}/{len(stops) + len(others)} {rec.path.name} {time.monotonic() - started:.0f} s",
              file=sys.stderr)
    return trials


def report(trials: list[Trial], split: str, rooms: list[str], decide: bool = False) -> str:
    def cell(subset: list[Trial], what: str) -> str:
        if what == "stopped":  # where the cue's remains alone fired nothing
            fair = [t for t in subset if not t.remains_fired]
            return f"{sum(t.stopped for t in fair)}/{len(fair)}"
        yielded = [t for t in subset if t.marked is not None]
        return f"{sum(bool(t.marked) for t in yielded)}/{len(yielded)}"

    lines = ["# A word said across the end of the deaf time", "",
             f"`python -m tools.listen.bench_deaf_edge --split {split} --rooms {','.join(rooms)}"
             f"{' --decide' if decide else ''}` (corpus: the {split} speakers' "
             "command recordings of ../shared/speech, each at -26 dBFS voiced; the bridge's cues as loud, 60 ms late, "
             "in the textbook room of tools.listen.bench_echo, RT60 0.3 s; three earlier cues first (the canceller learns the "
             "room); the shipped echo canceller "
             "and stop spotter; the microphone path's ear driven offline on the recording's clock). Offset: where "
             "the word's voice starts against the end of the deaf time (negative: before it; the bridge's sound ends "
             "0.4 s before it, the tail).",
             "", "Stops heard (a stop fired in a stream overlapping the word):", "",
             "| room | cue | offset (s) | " + " | ".join(MODES) + " |", "| --- | --- | --- |" + " --- |" * len(MODES)]
    keys = sorted({(t.room, t.cue, t.offset_s) for t in trials}, key=lambda k: (rooms.index(k[0]), k[1], k[2]))
    for room, cue, offset in keys:
        sub = [t for t in trials if (t.room, t.cue, t.offset_s) == (room, cue, offset) and t.action == "stop"]
        lines.append(f"| {room} | {cue} | {offset:+.1f} | " + " | ".join(
            cell([t for t in sub if t.mode == m], "stopped") for m in MODES) + " |")
    lines += ["", "Other commands: stops fired for nothing (all offsets and cues together) and, of the segmenter's "
              "utterances of every word, those marked as begun deaf (not acted on unless a stop):", "",
              "| room | words | offsets | " + " | ".join(f"{m}: false stops" for m in MODES) + " | " +
              " | ".join(f"{m}: marked" for m in MODES) + " |",
              "| --- | --- | --- |" + " --- |" * (2 * len(MODES))]
    for room in rooms:
        for label, pick in GROUPS:
            sub = [t for t in trials if t.room == room and pick(t.offset_s)]
            other = [t for t in sub if t.action != "stop"]
            lines.append(f"| {room} | all | {label} | " +
                         " | ".join(cell([t for t in other if t.mode == m], "stopped") for m in MODES) + " | " +
                         " | ".join(cell([t for t in sub if t.mode == m], "marked") for m in MODES) + " |")
    lines += ["", "Marked as begun over the bridge's sound, by how far (dB) the first 64 ms of the word, from 0.3 s before "
              "the edge and less the bridge's echo, must be above the quiet (the room before the bridge spoke, or the "
              "quietest the microphone less the echo was while it spoke) (`MARK_ABOVE_DB` in "
              f"gcs_voice/audio/microphone.py; the shipped value is {MARK_ABOVE_DB:g}): every word (stops too), of the "
              "segmenter's utterances of it:", "",
              "| room | words | " + " | ".join(f"{g:g} dB" for g in MARK_GRID) + " |",
              "| --- | --- |" + " --- |" * len(MARK_GRID)]
    for room in rooms:
        for label, pick in GROUPS:
            sub = [t for t in trials if t.room == room and t.mode == "lookback" and pick(t.offset_s)
                   and t.marked is not None]
            lines.append(f"| {room} | {label} | " + " | ".join(
                f"{sum(t.gap_db is not None and t.gap_db >= g for t in sub)}/{len(sub)}" for g in MARK_GRID) + " |")
    if decide:
        lines += ["", "What the session decided on the segmenter's utterances of each word (Whisper base, the shipped "
                  "matcher; a marked utterance acts only if it is a stop): right / wrong action / no action:", "",
                  "| room | words | offsets | " + " | ".join(MODES) + " |", "| --- | --- | --- |" + " --- |" * len(MODES)]
        for room in rooms:
            for label, pick in GROUPS:
                for kind, which in (("stops", lambda a: a == "stop"), ("other commands", lambda a: a != "stop")):
                    cells = []
                    for m in MODES:
                        sub = [t for t in trials if t.room == room and t.mode == m and pick(t.offset_s)
                               and which(t.action)]
                        cells.append(f"{sum(t.decided == 'right' for t in sub)} / "
                                     f"{sum(t.decided == 'wrong' for t in sub)} / "
                                     f"{sum(t.decided == 'none' for t in sub)} of {len(sub)}")
                    lines.append(f"| {room} | {kind} | {label} | " + " | ".join(cells) + " |")
    alone = [t for t in trials if t.mode == "none"]
    lines += ["", "Stops and false stops are counted where the same recording without the word fired no stop (the "
              f"cue's remains alone did in {sum(t.remains_fired for t in alone)} of {len(alone)} recordings)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="dev", choices=("dev", "test"))
    parser.add_argument("--limit", type=int, default=20, help="stops, and other commands, at most")
    parser.add_argument("--rooms", default="silent,kitchen20", help="silent, kitchenSNR (the pilot's SNR, dB)")
    parser.add_argument("--decide", action="store_true", help="also decide the utterances (Whisper base)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    rooms = args.rooms.split(",")
    text = report(run(args.split, args.limit, rooms, args.decide), args.split, rooms, args.decide)
    if args.out:
        args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
