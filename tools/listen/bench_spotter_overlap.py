"""What comes before or under a real "stop" changes whether the stop spotter hears it.

Over the bridge's voice the spotter misses stops even when that voice is far quieter than the pilot
(tools.listen.bench_echo: a stop under the bridge's words 20 dB down is lost where the same stop alone is heard).
This separates the causes with no echo canceller at all: the stop alone, after half a second of silence,
of faint white noise or of the bridge's voice at the pilot's level (nothing overlapping), with faint noise
under it all, and with the bridge's words 10 to 40 dB below the stop overlapping it. Spotted at the usual
threshold and at the one over the bridge's voice (gcs_voice/asr/stop_spotter.toml).

    python -m tools.listen.bench_spotter_overlap --split dev
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator

import numpy as np

from tools.listen.bench_echo import voiced_dbfs
from tools.speech.real_speech import load_recordings

RATE = 16_000
#: what the bridge says over the stop (the cue tools.listen.bench_echo mixes under it)
WORDS = "going forward, turning right"
#: how far below the stop the overlapping words are (what an echo canceller might leave of them)
BELOW_DB = (10, 20, 30, 40)


def variants(stop: np.ndarray, voice: np.ndarray, rng: np.random.Generator) -> Iterator[tuple[str, np.ndarray]]:
    """The stop as heard in each setting (float samples at 16-bit scale)."""
    half = RATE // 2
    faint = 32768 * 10 ** (-60 / 20)
    yield "the stop alone", stop
    yield "after 0.5 s of digital silence", np.concatenate([np.zeros(half), stop])
    yield "after 0.5 s of white noise at -60 dBFS", np.concatenate([rng.normal(0, faint, half), stop])
    yield "white noise at -60 dBFS under it all", (np.concatenate([np.zeros(half), stop])
                                                   + rng.normal(0, faint, half + stop.size))
    level = 10 ** ((voiced_dbfs(stop) - voiced_dbfs(voice)) / 20)
    yield "after 0.5 s of the bridge's voice at the stop's level", np.concatenate([voice[:half] * level, stop])
    yield "after 0.5 s of the bridge's voice 20 dB below the stop", np.concatenate([voice[:half] * level / 10, stop])
    for below in BELOW_DB:
        under = voice * level * 10 ** (-below / 20)
        mix = np.zeros(max(under.size, half + stop.size))
        mix[:under.size] += under
        mix[half:half + stop.size] += stop
        yield f"the bridge's words {below} dB below it, from 0.5 s before", mix


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.listen.bench_spotter_overlap", description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("dev", "test"), default="dev")
    args = parser.parse_args(argv)
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.audio.sounds import Speech
    from gcs_voice.audio.sources import read_wav

    spotter = load_stop_spotter(["en"])
    stops = [np.frombuffer(read_wav(r.path), "<i2").astype(np.float64)
             for r in load_recordings(split=args.split) if r.action == "stop"]
    voice = np.frombuffer(Speech("en-us", 175).say(WORDS), "<i2").astype(np.float64)
    rng = np.random.default_rng(0)
    usual: dict[str, int] = {}
    over: dict[str, int] = {}
    for stop in stops:
        for name, x in variants(stop, voice, rng):
            pcm = np.clip(np.round(x), -32768, 32767).astype("<i2").tobytes()
            usual[name] = usual.get(name, 0) + spotter.spot(pcm).fired
            over[name] = over.get(name, 0) + spotter.spot(pcm, over_voice=True).fired
    print(f"Command: `python -m tools.listen.bench_spotter_overlap --split {args.split}`: the real stops of the "
          f"{args.split} speakers of ../shared/speech ({len(stops)}), the bridge's voice espeak-ng \"{WORDS}\".\n")
    print("| the stop | spotted (usual threshold) | spotted (threshold over the bridge's voice) |")
    print("| --- | --- | --- |")
    for name in usual:
        print(f"| {name} | {usual[name]}/{len(stops)} | {over[name]}/{len(stops)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
