"""The domain ear: a small classifier trained on our commands, over Whisper base's own encoder output.

Whisper base is a general model: it knows nothing of the nine action classes, and in a noisy room it ranks
the right phrase first too rarely for any rule on its scores to fix (issue 51). The domain ear is the
acoustic side that knows the domain: the utterance, trimmed of silence, is encoded ALONE (a 1 s command
is about 60 encoder positions, not a 30 s window: tens of milliseconds), the encoder's frames are pooled
into one vector (mean, spread, maximum and four chunk means over time) and a multinomial logistic
regression gives a probability to each action class and to ``none`` (other speech).

It is evidence, not the decision: the matcher still decides on the dictionary and Whisper's scores, and
the ear only vouches for the class Whisper ranked first (which waives the score rules that noise breaks) or
vetoes an action it is sure was something else (``[ear.whisper-score]`` in thresholds.toml). A phrase added
to a dictionary without retraining still works through scoring.

The weights ship in ``ear_model.npz`` beside this module, made by ``python -m tools.speech.train_ear``
from the dev speakers of ../shared/speech, synthetic voices and one half of each real noise. A second set,
``ear_over_voice.npz``, made by the same command, has also heard what the echo canceller leaves of the bridge's own
cues: it settles a stop spotted while the bridge speaks (gcs_voice.session.listen.StopPath), where the first ear
took the bridge's words for a stop.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import SAMPLE_RATE

__all__ = ["EAR_PATH", "EAR_OVER_VOICE_PATH", "NONE", "DomainEar", "pool_frames", "ear_evidence", "EAR_PREFIX"]

#: the shipped weights (tools/speech/train_ear.py writes them)
EAR_PATH = Path(__file__).resolve().parent / "ear_model.npz"
#: the ear that settles a stop spotted while the bridge speaks: the same recipe, and also what the echo canceller
#: leaves of the bridge's own cues, alone ("none") and under a word said over them (tools/speech/ear_cues.py)
EAR_OVER_VOICE_PATH = Path(__file__).resolve().parent / "ear_over_voice.npz"
#: the class of everything that is not a command
NONE = "none"
#: Recognition.extra keys of the ear's posteriors: "ear:<class>"
EAR_PREFIX = "ear:"
#: how many equal chunks of the utterance get a mean of their own (a coarse order in time: "go left" vs "left go")
CHUNKS = 4
#: silence kept after the trimmed utterance before encoding (as Whisper scoring does)
PAD_S = 0.3
#: fewest encoder frames pooled (a click is not an utterance)
MIN_FRAMES = 4


def pool_frames(frames: np.ndarray) -> np.ndarray:
    """One fixed-length vector from the encoder's frames (T x d): mean, spread, maximum and chunk means.

    Pooling keeps what the classifier needs (which sounds, roughly in which order) and makes an utterance
    of any length one vector, so that a linear model on it trains in seconds on two cores.
    """
    frames = np.asarray(frames, dtype=np.float32)
    if frames.ndim == 3:
        frames = frames[0]
    if frames.shape[0] < CHUNKS:
        frames = np.concatenate([frames, np.repeat(frames[-1:], CHUNKS - frames.shape[0], axis=0)])
    parts = [frames.mean(axis=0), frames.std(axis=0), frames.max(axis=0)]
    parts += [chunk.mean(axis=0) for chunk in np.array_split(frames, CHUNKS, axis=0)]
    return np.concatenate(parts).astype(np.float32)


def encoder_input(audio: np.ndarray, log_mel) -> np.ndarray:
    """The log-mel frames the ear encodes: the utterance trimmed of silence, ``PAD_S`` of silence after it.

    ``log_mel`` is Whisper's feature extractor (WhisperRecognizer.log_mel). An even frame count: the
    encoder's stride-2 convolution halves it.
    """
    from gcs_voice.asr.whisper_score import trim_silence

    audio = trim_silence(np.asarray(audio, dtype=np.float32))[: 28 * SAMPLE_RATE]
    audio = np.concatenate([audio, np.zeros(int(PAD_S * SAMPLE_RATE), np.float32)])
    mel = log_mel(audio)[:, :-1]
    frames = max(2 * MIN_FRAMES, mel.shape[1] - mel.shape[1] % 2)
    if mel.shape[1] < frames:
        mel = np.concatenate([mel, np.repeat(mel[:, -1:], frames - mel.shape[1], axis=1)], axis=1)
    return np.ascontiguousarray(mel[:, :frames])


@dataclass(frozen=True)
class DomainEar:
    """A trained linear head: standardised pooled features -> softmax over ``classes``."""

    classes: tuple[str, ...]
    mean: np.ndarray
    scale: np.ndarray
    weights: np.ndarray  # (features, classes)
    bias: np.ndarray
    #: what it was trained for: the encoder's width and the Whisper model's files (name:size;...)
    meta: dict

    @classmethod
    def load(cls, path: Path = EAR_PATH) -> DomainEar | None:
        """The ear at ``path``, or None when there is none (the matcher then decides without it)."""
        if not Path(path).is_file():
            return None
        with np.load(path, allow_pickle=False) as data:
            return cls(tuple(str(c) for c in data["classes"]), data["mean"].astype(np.float32),
                       data["scale"].astype(np.float32), data["weights"].astype(np.float32),
                       data["bias"].astype(np.float32), json.loads(str(data["meta"])))

    def save(self, path: Path) -> None:
        """Write the ear (float16 weights: about 0.1 MB for 16 classes)."""
        np.savez_compressed(path, classes=np.array(self.classes), mean=self.mean.astype(np.float32),
                            scale=self.scale.astype(np.float32), weights=self.weights.astype(np.float16),
                            bias=self.bias.astype(np.float32), meta=np.array(json.dumps(self.meta, sort_keys=True)))

    @property
    def width(self) -> int:
        """The encoder width it was trained on (512 for Whisper base)."""
        return int(self.mean.size // (3 + CHUNKS))

    def fits(self, encoder_width: int) -> bool:
        """Whether this ear was trained on an encoder of this width (another Whisper size: no ear)."""
        return encoder_width == self.width

    def logits(self, features: np.ndarray) -> np.ndarray:
        x = (np.atleast_2d(features) - self.mean) / self.scale
        return x @ self.weights + self.bias

    def posteriors(self, features: np.ndarray) -> np.ndarray:
        """Class probabilities, one row per feature vector."""
        z = self.logits(features)
        z = z - z.max(axis=1, keepdims=True)
        p = np.exp(z)
        return p / p.sum(axis=1, keepdims=True)

    def evidence(self, features: np.ndarray) -> dict[str, float]:
        """The posteriors of one utterance as Recognition.extra entries ("ear:go_left": 0.93, ...)."""
        return {EAR_PREFIX + c: round(float(p), 5) for c, p in zip(self.classes, self.posteriors(features)[0])}


def ear_evidence(extra: dict[str, float]) -> dict[str, float]:
    """The ear's posteriors found in a Recognition's extra, by class ({} when the ear did not listen)."""
    return {k[len(EAR_PREFIX):]: v for k, v in extra.items() if k.startswith(EAR_PREFIX)}
