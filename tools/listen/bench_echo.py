#!/usr/bin/env python3
"""A stop said over the bridge's own voice: how often the stop spotter still hears it, by how loud that voice is.

While the bridge speaks (``--feedback speech``) the segmenter is deaf and only the stop spotter listens
(gcs_voice/audio/microphone.py). The spotter then hears the pilot's "stop" mixed with the bridge's words
as a speaker beside the microphone returns them. For every real held-out "stop" of ../shared/speech
(``tools.speech.real_speech.load_recordings(split="test")``) that the spotter hears alone, this mixes the
bridge's longest decision cue (the doing tone, then espeak-ng's "going forward, turning right"; the
pilot's stop starting ``--stop-at`` seconds into it) at several levels of its voiced parts relative to
the stop's voiced parts, delayed as ``--delay-ms`` and reverberated by a statistical room (``--rt60``,
``--drr-db``; ``--rt60 0``: the direct path only), and spots the mix as the spotter's stream would take it
(from the start of the bridge's sound): the raw microphone, and the microphone less the echo canceller's
estimate of the cue (``gcs_voice.audio.echo_cancel``), cold and after one earlier cue. No noise.

    python -m tools.listen.bench_echo --split dev --cancel 'min_step=0.05,min_step=0.2,min_step=0.35'   # choose
    python -m tools.listen.bench_echo --out docs/bench/echo.md                                          # report
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tools.listen.streams import voiced_level
from tools.speech.real_speech import SHARED, load_recordings

if TYPE_CHECKING:
    from gcs_voice.asr.stop_spotter import StopSpotter
    from gcs_voice.audio.echo_cancel import EchoCanceller

RATE = 16_000


def voiced_dbfs(x: np.ndarray) -> float:
    """Level of the voiced frames (tools.listen.streams.voiced_level), in dBFS, of int16-scaled samples."""
    return float(20 * np.log10(voiced_level(x / 32768.0)[0] + 1e-12))


class Cancelled:
    """What the canceller gives the spotter of ``mic``, fed chunk by chunk as the microphone path feeds it, and
    after each chunk whether it says all it gave out of late is its own echo's remains
    (``EchoCanceller.only_remains``: a stop word heard then is dismissed, as ``StopPath`` does)."""

    CHUNK = 512  # the microphone's block (gcs_voice.audio.sources.MICROPHONE_BLOCK_S)

    def __init__(self, canceller: EchoCanceller, mic: np.ndarray, reference: np.ndarray) -> None:
        self.chunks, self.remains = [], []
        for i in range(0, mic.size, self.CHUNK):
            out = canceller.process(mic[i:i + self.CHUNK], reference[i:i + self.CHUNK])
            self.chunks.append(np.clip(np.round(out), -32768, 32767).astype("<i2").tobytes())
            self.remains.append(canceller.only_remains())

    def spotted(self, over: StopSpotter) -> bool:
        """Whether the spotter ``over`` fires over the bridge's voice."""
        now = [0]
        stream = over.start_stream(True, lambda: self.remains[now[0]])
        for now[0], pcm in enumerate(self.chunks):
            stream.accept(pcm)
        return stream.finish().fired


def spotted_remains(cue: np.ndarray, canceller_settings: dict, spotter: StopSpotter, trials: int, seed: int,
                    dismiss: bool = True, delay_s: float = 0.06, tail_s: float = 0.4, plays: int = 4
                    ) -> list[tuple[int, int, int, str]]:
    """The bridge's ``cue`` (float samples) played ``plays`` times into a silent room, at a pilot's level (-26 dBFS
    voiced), ``delay_s`` late on the direct path, its first sample anywhere in a microphone block and the
    player's clock up to 10 ms off (as a busy machine leaves them), one canceller per session; the stop spotter
    over the bridge's voice fed chunk by chunk as the session feeds it (``dismiss``: with the canceller's word
    on its own echo's remains, as ``StopPath`` has it). (trial, play, phase, word) for each stop it fired."""
    from gcs_voice.audio.echo_cancel import EchoCanceller

    echo = (cue * 10 ** ((-26.0 - voiced_dbfs(cue)) / 20)).astype(np.float32)
    block, delay, tail = Cancelled.CHUNK, int(delay_s * RATE), int(tail_s * RATE)
    rng = np.random.default_rng(seed)
    fired = []
    for trial in range(trials):
        canceller = EchoCanceller(**canceller_settings)
        phase, late = int(rng.integers(0, block)), int(rng.integers(0, 160))
        n = -(-(phase + delay + late + cue.size + tail) // block) * block
        mic, reference = np.zeros(n), np.zeros(n)
        reference[phase:phase + cue.size] = cue
        mic[phase + delay + late:phase + delay + late + cue.size] = echo
        mic = np.trunc(mic)  # what the sound card gives: 16-bit samples
        for k in range(plays):
            canceller.drop_pending()  # a new stretch of deaf time
            stream = spotter.start_stream(True, canceller.only_remains if dismiss else None)
            for i in range(0, n, block):  # chunk by chunk, as the microphone gives them
                out = canceller.process(mic[i:i + block], reference[i:i + block])
                stream.accept(np.clip(np.round(out), -32768, 32767).astype("<i2").tobytes())
            hit = stream.finish()
            if hit.fired:
                fired.append((trial, k, phase, hit.word))
    return fired


def room_response(rt60_s: float, direct_to_reverb_db: float, seed: int = 0, length_s: float = 0.5) -> np.ndarray:
    """A speaker-to-microphone impulse response: the direct path (1.0 at 0), then a diffuse tail of
    exponentially decaying noise (-60 dB at ``rt60_s``) from 2 ms on, ``direct_to_reverb_db`` below the direct
    path in energy. None of the shape is tuned: it is the textbook statistical room (Schroeder)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(length_s * RATE)) / RATE
    tail = rng.standard_normal(t.size) * np.exp(-6.9 * t / rt60_s)
    tail[: int(0.002 * RATE)] = 0.0
    tail *= 10 ** (-direct_to_reverb_db / 20) / np.sqrt(np.sum(tail ** 2))
    tail[0] += 1.0
    return tail


def every_cue(lang: str = "en") -> list[tuple[str, str]]:
    """(tone, words) for every cue the bridge can play in ``lang``: each action's words after the doing tone, each
    warning and reason after the warning tone, each refusal after the refused tone."""
    from gcs_voice.session.feedback import load_phrases

    p = load_phrases(lang)
    cues = [("doing", words) for words in p.actions.values()]
    # a motion with an amount is said back with it (issue 33): one of each kind, numbers short and long
    said = {"go_forward": (3, "m", False), "go_back": (12, "m", False), "go_right": (20, "m", False),
            "go_left": (7, "m", False), "up": (5, "m", True), "down": (2, "m", False), "turn_right": (45, "deg", False),
            "turn_left": (180, "deg", False)}
    cues += [("doing", f"{p.actions[a]}, {p.amount({'value': n, 'unit': u, 'height': h})}")
             for a, (n, u, h) in said.items() if p.amount({"value": n, "unit": u, "height": h})]
    warnings = [p.said[k] for k in ("link_lost", "link_restored", "takeover", "battery", "take_off_failed", "error",
                                    "collision")]
    warnings += [p.mode(m) for m in ("RTL", "LAND", "BRAKE", "LOITER")] + list(p.reasons.values())
    warnings += [p.said["waiting"].format(what=w) for w in p.waiting.values()]
    cues += [("warning", words) for words in dict.fromkeys(warnings)]
    cues += [("refused", f"{p.said['refused']}, {r}") for r in dict.fromkeys(p.reasons.values())]
    return cues + [("not_understood", ""), ("not_understood", p.said["loud_room"])]


def main(argv: list[str] | None = None) -> int:
    from gcs_voice.asr.stop_spotter import StopSpotter, load_stop_spotter
    from gcs_voice.audio.echo_cancel import EchoCanceller
    from gcs_voice.audio.sounds import Speech, tone
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.session.feedback import load_sound_settings

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default="-20,-10,-6,0,6", help="the bridge's voice relative to the pilot's, dB")
    parser.add_argument("--delay-ms", type=float, default=60.0, help="the echo's delay (default 60 ms)")
    parser.add_argument("--stop-at", type=float, default=0.5, help="seconds into the bridge's sound the stop starts")
    parser.add_argument("--rt60", type=float, default=0.3,
                        help="the room's reverberation time, s (default 0.3: a furnished room; 0: the direct path only)")
    parser.add_argument("--drr-db", type=float, default=6.0,
                        help="direct-to-reverberant energy of the speaker-to-microphone path (default 6 dB: side by side)")
    parser.add_argument("--split", choices=("dev", "test"), default="test",
                        help="whose stops: dev (choose the canceller's settings on) or test (report)")
    parser.add_argument("--cancel", default="", help="canceller settings to compare, KEY=VALUE[;KEY=VALUE...] "
                        "separated by commas, each over the shipped [echo] of sounds.toml (default: as shipped)")
    parser.add_argument("--over-voice-thresholds", default="",
                        help="the spotter's thresholds while the bridge speaks to compare, comma-separated "
                             "(default: the shipped over_voice_threshold of stop_spotter.toml)")
    parser.add_argument("--speech", type=Path, default=SHARED / "speech")
    parser.add_argument("--rounds", type=int, default=3, help="times every cue is played, in a new order each")
    parser.add_argument("--alignments", type=int, default=0,
                        help="also play each of --alignment-cues in this many sessions (4 plays each), the cue "
                             "anywhere in the microphone's blocks: stops fired with and without the canceller's "
                             "word on its own echo's remains")
    parser.add_argument("--alignment-cues", default="going left;going down;fence reached")
    parser.add_argument("--langs", default="en",
                        help="the session's languages: the stop spotter's words and the cues said alone (en,es: a "
                             "--lang auto session, whose Spanish cues the English stop words hear too)")
    parser.add_argument("--out", type=Path, help="write the markdown report here")
    args = parser.parse_args(argv)

    langs = [lang for lang in args.langs.split(",") if lang]
    spotter = load_stop_spotter(langs)
    strict = [float(v) for v in args.over_voice_thresholds.split(",")] if args.over_voice_thresholds else [None]
    over_voice = [load_stop_spotter(langs, over_voice_thresholds=None if t is None else {lang: t for lang in langs})
                  for t in strict]
    s = load_sound_settings()
    shipped = dict(s.echo_cancel or {})
    settings = ([{**shipped, **{k: float(v) for k, v in (kv.split("=") for kv in group.split(";"))}}
                 for group in args.cancel.split(",")] if args.cancel else [shipped])

    def cue(words: str) -> np.ndarray:
        return np.frombuffer(tone(s.tones["doing"], s.amplitude, s.fade_s) + Speech("en-us", s.speed_wpm).say(words),
                             "<i2").astype(np.float64)

    words, earlier = "going forward, turning right", ["going left", "refused, not armed", "going back"]
    voice, earlier_voices = cue(words), [cue(w) for w in earlier]
    # a session some minutes in: the canceller has heard each cue the bridge can say once (settled)
    from gcs_voice.session.feedback import load_phrases

    voices = {lang: Speech(load_phrases(lang).voice, s.speed_wpm) for lang in langs}

    def rendered_cue(lang: str, tone_name: str, cue_words: str) -> np.ndarray:
        pcm = tone(s.tones[tone_name], s.amplitude, s.fade_s)
        if cue_words:
            pcm += bytes(int(0.05 * RATE) * 2) + voices[lang].say(cue_words)
        return np.frombuffer(pcm, "<i2").astype(np.float64)

    cues = [(lang, tone_name, cue_words) for lang in langs for tone_name, cue_words in every_cue(lang)]
    session_voices = earlier_voices + [rendered_cue(*c) for c in cues]
    response = room_response(args.rt60, args.drr_db) if args.rt60 > 0 else np.ones(1)
    delay = int(args.delay_ms / 1000 * RATE)

    def room(y: np.ndarray) -> np.ndarray:
        """What the microphone picks up of what the speaker plays: late, reverberated."""
        return np.concatenate([np.zeros(delay), np.convolve(y, response)])

    def spotted(x: np.ndarray | Cancelled, over: StopSpotter | None = None) -> bool:
        """Whether the spotter fires: on a stop alone (the usual threshold), or over the bridge's voice (on
        what the canceller gave out, chunk by chunk, with its word on its own echo's remains, as a session)."""
        if isinstance(x, Cancelled):
            return x.spotted(over)
        pcm = np.clip(np.round(x), -32768, 32767).astype("<i2").tobytes()
        return spotter.spot(pcm).fired if over is None else over.spot(pcm, over_voice=True).fired

    stops = [(r.path.name, np.frombuffer(read_wav(r.path), "<i2").astype(np.float64))
             for r in load_recordings(args.speech, split=args.split) if r.action == "stop"]
    alone = [x for _name, x in stops if spotted(x)]
    levels = [float(v) for v in args.levels.split(",")]
    def named(label: str, t: float | None) -> str:
        return label if len(strict) == 1 else f"{label}, over-voice threshold {t:g}"

    def changed(c: dict) -> str:
        """The settings that differ from the shipped ones, for a column's name."""
        return " " + ", ".join(f"{k} {v:g}" for k, v in c.items() if shipped.get(k) != v) if args.cancel else ""

    per = ["raw microphone"] + [f"cancelled{changed(c)} ({how})" for c in settings
                                for how in ("cold", "warm", "learned", "settled")]
    labels = [named(label, t) for t in strict for label in per]
    rows = []
    for level in levels:
        hits = [0] * len(labels)
        for x in alone:
            gain = 10 ** ((voiced_dbfs(x) - voiced_dbfs(voice) + level) / 20)
            at = int(args.stop_at * RATE)
            echo = room(voice * gain)
            n = max(at + x.size, echo.size) + RATE // 2
            mic, reference = np.zeros(n), np.zeros(n)
            mic[:echo.size] += echo
            mic[at:at + x.size] += x
            reference[:voice.size] = voice * gain
            outs = [mic]
            for c in settings:
                for heard_before in (0, 1, len(earlier_voices), len(session_voices)):
                    canceller = EchoCanceller(**c)
                    for before in session_voices[:heard_before]:  # earlier cues of the session: the room heard
                        e = room(before * gain)
                        m, r = np.zeros(e.size + RATE // 2), np.zeros(e.size + RATE // 2)
                        m[:e.size], r[:before.size] = e, before * gain
                        canceller.process(m, r)
                        canceller.drop_pending()  # the cue is a clip of its own, not the earlier one's continuation
                    outs.append(Cancelled(canceller, mic, reference))
            for k, over in enumerate(over_voice):
                for i, out in enumerate(outs):
                    hits[k * len(outs) + i] += spotted(out, over)
        rows.append(f"| {level:+g} dB | " + " | ".join(f"{h}/{len(alone)}" for h in hits) + " |")
        print(rows[-1], flush=True)
    # The bridge's own cues alone (no pilot): a stop the spotter fires on them stops the vehicle for nothing.
    # Every cue, played in a new order each round into the same room (one canceller for the whole session, as
    # live), over a quiet room's floor (-64 dBFS of white noise); the cue's voiced level is the pilot's.
    rng = np.random.default_rng(1)
    pilot_dbfs = float(np.median([voiced_dbfs(x) for x in alone])) if alone else -26.0
    rendered = [x * 10 ** ((pilot_dbfs - voiced_dbfs(x)) / 20) for x in session_voices[len(earlier_voices):]]
    false_stops = [0] * ((1 + len(settings)) * len(over_voice))
    fired_on: dict[str, int] = {}  # the cues the spotter fired on over the bridge's voice (cancelled, first threshold)
    cancellers = [EchoCanceller(**c) for c in settings]
    for _round in range(args.rounds):
        for i in rng.permutation(len(rendered)):
            x = rendered[i]
            echo = room(x)
            n = echo.size + RATE // 2
            mic, reference = rng.normal(0.0, 20.0, n), np.zeros(n)
            mic[:echo.size] += echo
            reference[:x.size] = x
            outs = [mic]
            for canceller in cancellers:
                canceller.drop_pending()
                outs.append(Cancelled(canceller, mic, reference))
            for k, over in enumerate(over_voice):
                for j, out in enumerate(outs):
                    fired = spotted(out, over)
                    false_stops[k * len(outs) + j] += fired
                    if fired and k == 0 and j == 1:
                        said = f"{cues[i][0]}: {cues[i][2] or '(' + cues[i][1] + ' tone)'}"
                        fired_on[said] = fired_on.get(said, 0) + 1
    played = args.rounds * len(rendered)
    aligned: list[str] = []
    if args.alignments:
        # Where the cue falls within the microphone's blocks changes what the canceller leaves of it: each cue
        # in many sessions, the first sample anywhere in a block and the clock up to 10 ms off
        cancelled = [f"cancelled{changed(c)}" for c in settings]
        heads = [f"{named(label, t)}, {how}" for t in strict for label in cancelled
                 for how in ("every stop word heard", "those on its own echo's remains dismissed")]
        aligned = [f"The same cues in {args.alignments} sessions of 4 plays each, the cue's first sample anywhere in "
                   "the microphone's 32 ms block and the player's clock up to 10 ms off (as a busy machine leaves "
                   "them), the direct path 60 ms late at -26 dBFS voiced, chunk by chunk as a session feeds the "
                   "spotter (tools.listen.bench_echo.spotted_remains): stops fired over the bridge's voice, of the plays "
                   "(first: of the sessions' first plays, the canceller cold).",
                   "", "| cue | " + " | ".join(heads) + " |", "| --- | " + " | ".join("---" for _ in heads) + " |"]
        for said in args.alignment_cues.split(";"):
            fired = [spotted_remains(cue(said), c, over, args.alignments, seed=2, dismiss=d, tail_s=s.tail_s)
                     for over in over_voice for c in settings for d in (False, True)]
            aligned.append(f"| {said} | " + " | ".join(
                f"{len(f)}/{4 * args.alignments} (first {sum(k == 0 for _t, k, _p, _w in f)}/{args.alignments})"
                for f in fired) + " |")
            print(aligned[-1], flush=True)
        aligned.append("")
    false_labels = [named(label, t) for t in strict for label in
                    ["raw microphone"] + [f"cancelled{changed(c)}" for c in settings]]
    false_row = "| stops fired | " + " | ".join(f"{n}/{played}" for n in false_stops) + " |"
    print(false_row, flush=True)
    corpus = "../shared/speech" if args.speech == SHARED / "speech" else str(args.speech)
    command = (f"python -m tools.listen.bench_echo --levels={args.levels} --delay-ms {args.delay_ms:g} --stop-at {args.stop_at:g} "
               f"--rt60 {args.rt60:g} --drr-db {args.drr_db:g} --split {args.split}"
               + (f" --cancel '{args.cancel}'" if args.cancel else "")
               + (f" --over-voice-thresholds {args.over_voice_thresholds}" if args.over_voice_thresholds else "")
               + (f" --alignments {args.alignments} --alignment-cues '{args.alignment_cues}'" if args.alignments
                  else "")
               + (f" --langs {args.langs}" if langs != ["en"] else "")
               + (f" --out {args.out}" if args.out else ""))
    path = (f"reverberated by a statistical room (RT60 {args.rt60:g} s, direct-to-reverberant {args.drr_db:g} dB, "
            "`room_response` in the tool)" if args.rt60 > 0 else "the direct path only, no room")
    report = "\n".join([
        "# A stop said over the bridge's own voice",
        "",
        f"Command: `{command}`",
        "",
        f"Corpus: the real \"stop\" recordings of the {'held-out test' if args.split == 'test' else 'dev'} speakers of "
        f"`{corpus}` that the stop spotter hears alone ({len(alone)} of {len(stops)}). Each is mixed with the bridge's "
        f"cue for a decision (the doing tone, then espeak-ng saying \"{words}\", {voice.size / RATE:.1f} s), the stop "
        f"starting {args.stop_at:g} s into it; the cue reaches the microphone {args.delay_ms:g} ms late, {path}, at a "
        "level of its voiced parts relative to the stop's. No noise. The spotter decodes the mix from the start of "
        "the cue, as its stream does while the microphone is deaf, at its threshold over the bridge's voice ("
        f"{'the shipped over_voice_threshold of gcs_voice/asr/stop_spotter.toml' if strict == [None] else 'each named'}"
        "; a stop alone is judged at the usual one): the raw microphone, or the microphone less the echo "
        "canceller's estimate of the cue (gcs_voice/audio/echo_cancel.py, given what was played, with its comfort "
        "noise: the shipped [echo] of sounds.toml, with the settings named changed), from a "
        f"fresh filter (cold: the session's first cue), one that has heard one earlier cue (warm: \"{earlier[0]}\", "
        f"{earlier_voices[0].size / RATE:.1f} s), or {len(earlier)} (learned: \"" + '", "'.join(earlier) + "\", "
        f"{sum(v.size for v in earlier_voices) / RATE:.1f} s; a canceller that has heard less than its learn_s of the "
        "bridge's sound assumes the worst of the echo, gcs_voice/audio/echo_cancel.py), or those and every cue of the "
        f"session once (settled: {len(session_voices)} cues, {sum(v.size for v in session_voices) / RATE:.0f} s, a "
        "session some minutes in).",
        "",
        "| the bridge's voice vs the pilot's | " + " | ".join(labels) + " |",
        "| --- | " + " | ".join("---" for _ in labels) + " |",
        *rows,
        "",
        f"The bridge's own cues alone, no pilot: every cue it can play in {' and '.join(langs)} ({len(rendered)}: the "
        f"actions, warnings, reasons and refusals of gcs_voice/data/feedback/<lang>.toml, each after its tone, in the "
        f"language's espeak-ng voice; the stop spotter with the words of {' and '.join(langs)}), {args.rounds} "
        "rounds in a new order each, through the same room at the pilot's voiced level over a quiet room's floor, "
        "one canceller for the whole run as in a session: how often the stop spotter fires on them (a stop for "
        "nothing).",
        "",
        "| | " + " | ".join(false_labels) + " |",
        "| --- | " + " | ".join("---" for _ in false_labels) + " |",
        false_row,
        "",
        *([f"Cues the spotter fired on (cancelled): " + "; ".join(f"{k} ({v})" for k, v in sorted(fired_on.items())), ""]
          if fired_on else []),
        *aligned,
    ])
    print(report)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
