"""The timing stage of ``python -m tools.speech.bench_real``: decision time on clean held-out files, from a file
(idle or beside busy loops) or on the microphone path in real time (docs/bench/real_timing.md).
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import get_matcher
from tools.cpu_steal import CpuSample, busy_loops
from tools.speech.real_cache import ENGINES, MATCHER, recognise_one
from tools.speech.real_speech import condition_audio, load_recordings


def timing(engine: str, model: str | None, n: int, hogs: int = 0) -> str:
    """Decision time (end of audio to recognition) of ``n`` clean test-split files, alternating commands
    and non-commands; run it on an idle machine, or with ``hogs`` busy-loop processes beside it (a ground
    station that also runs a simulator or a browser). Returns a markdown section."""
    import os

    from gcs_voice.asr.registry import load_recognizer

    name, mode = ENGINES[engine]
    recognizer = load_recognizer(name, [load_language("en")], model=model, mode=mode)
    recs = load_recordings(split="test")
    commands = [r for r in recs if r.kind == "command"]
    others = [r for r in recs if r.kind != "command"]
    picked = [x for pair in zip(commands[::2], others[::2]) for x in pair][:n]
    recognise_one(recognizer, condition_audio(picked[0], "clean"))  # warm-up, not counted
    times, cpu_ms, audio_s = [], [], 0.0
    with busy_loops(hogs), CpuSample() as cpu:
        for rec in picked:
            audio = condition_audio(rec, "clean")
            used = time.process_time()
            _, dt = recognise_one(recognizer, audio)
            # CPU time of all our threads: what the code costs, whatever the host took from the wall time
            cpu_ms.append((time.process_time() - used) * 1000)
            times.append(dt * 1000)
            audio_s += audio.size / 16_000
    load = os.getloadavg()[0]
    p50, p95 = statistics.median(times), float(np.percentile(times, 95))
    loaded = f", {hogs} busy-loop processes beside it" if hogs else ""
    return (f"## Decision time, {engine}{loaded}\n\n`python -m tools.speech.bench_real timing --engine {engine} --n {n}"
            f"{f' --hogs {hogs}' if hogs else ''}`: {len(times)} "
            f"clean test-split files (commands and non-commands alternating), streamed in 100 ms chunks; time from "
            f"the end of the audio to the recognition{loaded}. Load average at the end: {load:.2f} (2 cores); {cpu.describe()}.\n\n"
            f"| p50 | p95 | max | real-time factor (decision time / audio) | CPU time per utterance p50 / p95 "
            f"(both threads) |\n| --- | --- | --- | --- | --- |\n"
            f"| {p50:.0f} ms | {p95:.0f} ms | {max(times):.0f} ms | {sum(times) / 1000 / audio_s:.3f} | "
            f"{statistics.median(cpu_ms):.0f} / {np.percentile(cpu_ms, 95):.0f} ms |\n")


def live_timing(engine: str, model: str | None, n: int, speculate: bool = True, vad_settings: Path | None = None) -> str:
    """Time to a decision on the microphone path: ``n`` clean test-split files, 1.5 s apart, fed in real
    time (in the microphone's blocks, gcs_voice.audio.sources.MICROPHONE_BLOCK_S) through the Silero segmenter and ``listen.run_microphone`` exactly as a live
    session runs them (no flight). Timed from the end of speech (the last window Silero called speech)
    and from the close of the utterance (after the closing silence) to the decision. Returns markdown."""
    import os
    import threading

    from gcs_voice.asr.registry import load_recognizer
    from gcs_voice.audio.sources import MICROPHONE_BLOCK_S, pcm_to_chunks
    from gcs_voice.audio.vad import load_vad_settings, segment_utterances
    from gcs_voice.session import listen
    from gcs_voice.session.events import EventBus

    name, mode = ENGINES[engine]
    en = load_language("en")
    recognizer = load_recognizer(name, [en], model=model, mode=mode)
    recs = load_recordings(split="test")
    commands = [r for r in recs if r.kind == "command"]
    others = [r for r in recs if r.kind != "command"]
    picked = [x for pair in zip(commands[::2], others[::2]) for x in pair][:n]
    gap = np.zeros(int(1.5 * 16_000), np.float32)
    clips = [condition_audio(r, "clean") for r in picked]
    audio = np.concatenate([gap] + [x for clip in clips for x in (clip, gap)])
    pcm = (np.clip(audio, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
    bus = EventBus()
    pipeline = listen.VoicePipeline(recognizer, get_matcher(MATCHER), [en], "en", bus)
    pipeline.hear(pcm[:32_000], "warm-up")  # model loading is not a decision
    bus.history.clear()
    settings = load_vad_settings(vad_settings) if vad_settings else load_vad_settings()
    post_pad_s = settings.silero.post_pad_s
    closed: dict[float, float] = {}  # utterance end time -> wall time the segmenter closed it
    tentatives = listen.TentativeUtterances() if speculate else None

    class Sink:  # the bridge's side of run_microphone: nothing is flown
        finished = False

        def submit(self, request):
            request.done.set()  # served at once, as the bridge does once it has sent the setpoint (a pause waits for it)
            return request

    stream_end_s: dict[float, float] = {}  # utterance end time -> where in the stream it ended (s)

    def utterances():
        t0 = time.time() + 0.05

        def realtime():
            for chunk in pcm_to_chunks(pcm, MICROPHONE_BLOCK_S):  # blocks as the microphone gives them
                wait = t0 + chunk.start_s + MICROPHONE_BLOCK_S - time.time()  # a block exists once it was spoken
                if wait > 0:
                    time.sleep(wait)
                yield chunk

        for utt in segment_utterances(realtime(), settings,
                                      on_tentative=(lambda u: tentatives(u.pcm)) if tentatives else None):
            closed[t0 + utt.end_s] = time.time()
            stream_end_s[t0 + utt.end_s] = utt.end_s
            yield utt.pcm, t0 + utt.end_s

    voice = threading.Thread(target=listen.run_microphone, args=(pipeline, Sink(), utterances(), False, tentatives))
    with CpuSample() as cpu:
        voice.start()
        voice.join()
    heard = [e for e in bus.history if e.kind == "heard"]
    from_speech = [(e.t - (e.data["utterance_end_t"] - post_pad_s)) * 1000 for e in heard]
    from_close = [(e.t - closed[e.data["utterance_end_t"]]) * 1000 for e in heard]
    # which file each decision was of: the one whose audio ends nearest the utterance's end
    ends = np.cumsum([gap.size + clip.size for clip in clips]) / 16_000
    kinds = [picked[int(np.argmin(np.abs(ends - stream_end_s[e.data["utterance_end_t"]])))].kind for e in heard]

    def row(label: str, values: list[float]) -> str:
        if not values:
            return ""
        return (f"| {label} ({len(values)}) | {statistics.median(values):.0f} ms | "
                f"{np.percentile(values, 95):.0f} ms | {max(values):.0f} ms |\n")
    by_kind = "".join(row(f"the end of speech, {label}", [v for v, k in zip(from_speech, kinds) if k in group])
                      for label, group in (("commands", ("command",)), ("other speech", ("word", "sentence"))))
    used = sum(1 for e in heard if e.data.get("speculated"))
    load = os.getloadavg()[0]
    label = "decided while the closing silence ran out (speculation)" if speculate else "no speculation"
    return (f"## Decision time on the microphone path, {engine}, {label}\n\n"
            f"`python -m tools.speech.bench_real timing --live{'' if speculate else ' --no-speculate'} --engine {engine} "
            f"--n {n}{f' --vad-settings {vad_settings}' if vad_settings else ''}`: {len(picked)} clean test-split files 1.5 s apart, fed in real time in the microphone's "
            f"{MICROPHONE_BLOCK_S * 1000:.0f} ms blocks through the Silero segmenter "
            f"and `listen.run_microphone`; {len(heard)} utterances decided, {used} of them from the speculation"
            f"{f' ({pipeline.abandoned} stale speculations given up half-way)' if speculate else ''}. "
            f"Load average at the end: {load:.2f} (2 cores); {cpu.describe()}.\n\n"
            f"| measured from | p50 | p95 | max |\n| --- | --- | --- | --- |\n"
            f"| the end of speech (last window Silero called speech) | {statistics.median(from_speech):.0f} ms | "
            f"{np.percentile(from_speech, 95):.0f} ms | {max(from_speech):.0f} ms |\n{by_kind}"
            f"| the close of the utterance (after {settings.silero.min_silence_s:g} s of non-speech) | "
            f"{statistics.median(from_close):.0f} ms | {np.percentile(from_close, 95):.0f} ms | {max(from_close):.0f} ms |\n")
