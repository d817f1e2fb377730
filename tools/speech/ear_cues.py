"""The bridge's own voice as the domain ear hears it: what the echo canceller leaves of a cue, alone or with a
pilot's word said over it.

A stop spotted over the bridge's voice holds the vehicle, and the ear settles the hold on the audio the spotter
heard (``gcs_voice.session.listen.StopPath``): the canceller's output over the deaf time. So the ear learns that
what is left of the bridge's cues is no command ("none"), and that a word said over them is still that word.

The rules of issue 51 hold here too: half of the cues of each language (by a fixed hash, ``cue_split``) are
trained on, the other half are kept to judge (cues the ear never heard); the pilots are the real speakers of
their split; the room's floor is the first half of a real noise in training, the second half when judged.

A scene is drawn from the clip's key and the seed alone (``scene``): the same clip always sounds the same.
"""

from __future__ import annotations

import hashlib
import zlib
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from gcs_voice.audio import SAMPLE_RATE

__all__ = ["BridgeCue", "Scene", "bridge_cues", "cue_split", "scene", "render_cue", "heard_over_cue",
           "PILOT_DBFS", "BLOCK"]

#: the pilot's voiced level at the microphone (dBFS), as tools.listen.bench_echo sets it
PILOT_DBFS = -26.0
#: the microphone's block, samples (gcs_voice.audio.sources.MICROPHONE_BLOCK_S): the canceller is fed by blocks
BLOCK = 512
#: the speaker's sound reaches the microphone this late on the direct path (s)
DELAY_S = 0.06


@dataclass(frozen=True)
class BridgeCue:
    """One thing the bridge can say: the tone, then the words (tools.listen.bench_echo.every_cue)."""

    lang: str
    tone: str
    words: str

    @property
    def id(self) -> str:
        return f"{self.lang}|{self.tone}|{self.words}"


def cue_split(cue: BridgeCue) -> str:
    """'dev' (trained on) or 'test' (kept to judge), half of each language by a fixed hash."""
    return "dev" if int(hashlib.sha1(f"ear-cue:{cue.id}".encode()).hexdigest(), 16) % 2 == 0 else "test"


@lru_cache(maxsize=None)
def bridge_cues(langs: tuple[str, ...] = ("en", "es")) -> tuple[BridgeCue, ...]:
    """Every cue the bridge can play in ``langs``, once each (read once: every clip over a cue asks)."""
    from tools.listen.bench_echo import every_cue

    return tuple(dict.fromkeys(BridgeCue(lang, t, w) for lang in langs for t, w in every_cue(lang)))


@dataclass(frozen=True)
class Scene:
    """How one cue is heard: its voiced level relative to the pilot's, the room, where its first sample falls in
    the microphone's block, the player's clock error, how many earlier cues the canceller learned from, the room's
    floor (noise name and dBFS), and where in the cue the pilot starts (a fraction of the cue)."""

    level_db: float
    rt60_s: float
    drr_db: float
    phase: int
    late: int
    learned: int
    floor: str
    floor_dbfs: float
    pilot_at: float


def scene(key: str, seed: int, levels_db: tuple[float, float] = (-10.0, 6.0)) -> Scene:
    """The scene of the clip ``key`` (a cue alone or a word over one), drawn from ``seed`` and the key only."""
    from tools.speech.ear_data import NOISES

    rng = np.random.default_rng([seed, zlib.crc32(key.encode())])
    return Scene(level_db=float(rng.uniform(*levels_db)), rt60_s=float(rng.uniform(0.15, 0.6)),
                 drr_db=float(rng.uniform(0.0, 10.0)), phase=int(rng.integers(0, BLOCK)),
                 late=int(rng.integers(0, 160)), learned=int(rng.integers(0, 4)),
                 floor=list(NOISES)[int(rng.integers(len(NOISES)))], floor_dbfs=float(rng.uniform(-65.0, -45.0)),
                 pilot_at=float(rng.uniform(0.0, 1.0)))


@lru_cache(maxsize=None)
def _rendered(lang: str, tone_name: str, words: str) -> bytes:
    from gcs_voice.audio.sounds import Speech, tone
    from gcs_voice.session.feedback import load_phrases, load_sound_settings

    s = load_sound_settings()
    pcm = tone(s.tones[tone_name], s.amplitude, s.fade_s)
    if words:
        pcm += bytes(int(0.05 * SAMPLE_RATE) * 2) + Speech(load_phrases(lang).voice, s.speed_wpm).say(words)
    return pcm


def render_cue(cue: BridgeCue) -> np.ndarray:
    """The cue as the bridge plays it (int16-scaled float samples): the tone, then espeak-ng's words."""
    return np.frombuffer(_rendered(cue.lang, cue.tone, cue.words), "<i2").astype(np.float64)


def heard_over_cue(cue: BridgeCue, where: Scene, pilot: np.ndarray | None, half: str,
                   earlier: list[BridgeCue] = ()) -> np.ndarray:
    """What the stop path hears over the bridge's voice (float samples in [-1, 1]): the microphone (the cue's echo
    in the room, the room's floor from one ``half`` of a real noise, and the ``pilot``'s word if any, float in
    [-1, 1], at ``PILOT_DBFS``) less the shipped echo canceller's estimate, fed block by block, from the cue's start
    to the end of the deaf time (its tail) or of the pilot's word. The canceller first hears ``earlier`` cues (up to
    ``where.learned`` of them) in the same room, as a session some cues in."""
    from gcs_voice.audio.echo_cancel import EchoCanceller
    from gcs_voice.session.feedback import load_sound_settings
    from tools.listen.bench_echo import room_response, voiced_dbfs
    from tools.speech.ear_data import noise_half

    settings = load_sound_settings()
    response = room_response(where.rt60_s, where.drr_db, seed=zlib.crc32(cue.id.encode()))
    delay = int(DELAY_S * SAMPLE_RATE) + where.late
    canceller = EchoCanceller(**settings.echo_cancel)

    def gain(x: np.ndarray) -> float:  # every cue of the session at the same loudness relative to the pilot
        return 10 ** ((PILOT_DBFS + where.level_db - voiced_dbfs(x)) / 20)

    def hear(played: np.ndarray, extra: np.ndarray | None, at: int) -> np.ndarray:
        echo = np.convolve(played, response)
        n = where.phase + delay + max(echo.size, int(settings.tail_s * SAMPLE_RATE) + played.size)
        if extra is not None:
            n = max(n, where.phase + at + extra.size + BLOCK)
        n = -(-n // BLOCK) * BLOCK
        mic, reference = np.zeros(n), np.zeros(n)
        mic[where.phase + delay:where.phase + delay + echo.size] += echo[:n - where.phase - delay]
        reference[where.phase:where.phase + played.size] = played
        if extra is not None:
            mic[where.phase + at:where.phase + at + extra.size] += extra
        floor = noise_half(where.floor, half)
        start = zlib.crc32(f"{cue.id}|{where}".encode()) % max(1, floor.size - n)
        seg = floor[start:start + n].astype(np.float64) * 32768.0
        if seg.size < n:
            seg = np.resize(seg, n)
        mic += seg / (np.sqrt(np.mean(seg ** 2)) + 1e-9) * 32768.0 * 10 ** (where.floor_dbfs / 20)
        mic = np.trunc(np.clip(mic, -32768, 32767))  # what the sound card gives
        canceller.drop_pending()  # a new deaf time
        out = [canceller.process(mic[i:i + BLOCK], reference[i:i + BLOCK]) for i in range(0, n, BLOCK)]
        return np.concatenate(out)

    for before in list(earlier)[:where.learned]:
        x = render_cue(before)
        hear(x * gain(x), None, 0)
    x = render_cue(cue)
    word = None
    at = 0
    if pilot is not None:
        p = np.asarray(pilot, dtype=np.float64) * 32768.0
        word = p * 10 ** ((PILOT_DBFS - voiced_dbfs(p)) / 20)
        at = int(where.pilot_at * max(0, x.size - word.size // 2))  # begun while the bridge still speaks
    out = hear(x * gain(x), word, at)
    return np.clip(out / 32768.0, -1.0, 1.0).astype(np.float32)
