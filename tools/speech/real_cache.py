"""The recognise stage of ``python -m tools.speech.bench_real`` and its scoring: the cache of recognitions of the
real recordings under every condition (out/bench/real/<engine>.jsonl) and the counts of decisions made on them.

tools/speech/real_tune.py, real_report.py and real_timing.py build on it; tools/speech/bench_real.py is the command.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import Hypothesis, Recognition
from gcs_voice.domain.dictionary import load_language
from gcs_voice.domain.text import normalize_text
from tools.speech.real_speech import NOISE_SEED, SHARED, Recording, condition_audio, load_recordings

REPO = Path(__file__).resolve().parents[2]
CACHE_DIR = REPO / "out" / "bench" / "real"
CHUNK_S = 0.1
#: engine label -> (registry engine, mode)
ENGINES = {"whisper-score": ("whisper", "score"), "whisper": ("whisper", "grammar"), "sphinx": ("sphinx", "grammar")}
MATCHER = "phonetic"


# -- recognise ----------------------------------------------------------------------------------------
def _digest(path: Path) -> str:
    return hashlib.sha1(path.read_bytes()).hexdigest()[:16]


def _key(rec: Recording, condition: str) -> str:
    return f"{rec.path.relative_to(SHARED / 'speech')}|{condition}"


def cache_path(engine: str) -> Path:
    return CACHE_DIR / f"{engine}{_TAG}.jsonl"


#: a label for a variant's cache (``--tag``), so settings can be compared without losing a run
_TAG = ""


def read_rows(path: Path) -> dict[str, dict]:
    """A cache of JSON lines by their "key" (the last line of a key wins); {} when there is none."""
    out: dict[str, dict] = {}
    if path.is_file():
        for line in path.read_text(encoding="utf-8").splitlines():
            if line.strip():
                row = json.loads(line)
                out[row["key"]] = row
    return out


def load_cache(engine: str) -> dict[str, dict]:
    return read_rows(cache_path(engine))


def recognise_one(recognizer, audio: np.ndarray, lang: str = "en") -> tuple[Recognition, float]:
    """Stream 100 ms chunks as a file source does; the time counted is from the end of the audio to the result."""
    pcm = (np.clip(audio, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
    chunk = int(CHUNK_S * 16_000) * 2
    stream = recognizer.start_stream(lang)
    for i in range(0, len(pcm), chunk):
        stream.accept(pcm[i:i + chunk])
    t0 = time.perf_counter()
    result = stream.finish()
    return result, time.perf_counter() - t0


#: the Whisper model the shipped figures and thresholds come from; another model is a variant (``--tag``)
DEFAULT_MODEL = SHARED / "models" / "faster-whisper-base"


def model_identity(model: str | None) -> str:
    """What tells one model folder from another without reading it whole: the name and size of each file."""
    if model is None:
        return ""
    folder = Path(model)
    if not folder.is_dir():
        return str(model)
    return ";".join(f"{f.name}:{f.stat().st_size}" for f in sorted(folder.iterdir()) if f.is_file())


def recognise(engine: str, model: str | None, conditions: list[str], split: str | None,
              overrides: dict[str, float | str] | None = None, noise_seed: int = NOISE_SEED) -> None:
    from gcs_voice.asr.registry import load_recognizer

    name, mode = ENGINES[engine]
    recognizer = load_recognizer(name, [load_language("en")], model=model, mode=mode)
    recognizer.settings.update(overrides or {})  # a variant of asr/engines.toml, cached under --tag
    # the model, the engine's settings and the dictionary it scores (its phrases and not-commands) make one
    # configuration: a cached recognition of another one is made again
    dictionary = load_language("en")
    config = hashlib.sha1((model_identity(model) + json.dumps(recognizer.settings, sort_keys=True, default=str)
                           + dictionary.path.read_text(encoding="utf-8")).encode()).hexdigest()[:12]
    cache = {k: row for k, row in load_cache(engine).items() if row.get("config") == config}
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    recs = load_recordings(split=split)
    todo = [(r, c) for c in conditions for r in recs
            if _key(r, c) not in cache or cache[_key(r, c)]["sha1"] != _digest(r.path)]
    print(f"{engine}: {len(todo)} recognitions to do ({len(recs)} files x {len(conditions)} conditions)", file=sys.stderr)
    with open(cache_path(engine), "a", encoding="utf-8") as out:
        for i, (rec, cond) in enumerate(todo):
            result, dt = recognise_one(recognizer, condition_audio(rec, cond, noise_seed))
            row = {"key": _key(rec, cond), "sha1": _digest(rec.path), "config": config,
                   "engine": result.engine, "lang": result.lang,
                   "hypotheses": [[h.text, h.confidence, h.score] for h in result.hypotheses],
                   "extra": dict(result.extra), "transcript": result.transcript, "audio_s": result.audio_s,
                   "decision_s": dt}
            out.write(json.dumps(row) + "\n")
            out.flush()
            if i % 50 == 0:
                print(f"  {i}/{len(todo)} {row['key']} {dt * 1000:.0f} ms", file=sys.stderr)


def _recognition(row: dict) -> Recognition:
    return Recognition(tuple(Hypothesis(t, c, s) for t, c, s in row["hypotheses"]), row["engine"], row["lang"],
                       row["audio_s"], row["extra"], transcript=row["transcript"])


# -- scoring ------------------------------------------------------------------------------------------
@dataclass
class Counts:
    """Decisions on one set of files: commands right / wrong / rejected, non-commands acted on."""

    commands: int = 0
    right: int = 0
    wrong: int = 0
    words: int = 0
    words_acted: int = 0
    sentences: int = 0
    sentences_acted: int = 0
    #: commands whose best-scored phrase, before any rejection, was of the right class
    ranked_first: int = 0

    def add(self, kind: str, expected: str | None, action: str | None, top: str | None = None) -> None:
        """Count one decision: ``kind`` command, word or sentence; ``expected`` the command's class;
        ``top`` the class of the engine's best hypothesis, whether or not it was acted on."""
        if kind == "command":
            self.commands += 1
            self.ranked_first += top is not None and top == expected
            self.right += action == expected
            self.wrong += action is not None and action != expected
        elif kind == "word":
            self.words += 1
            self.words_acted += action is not None
        else:
            self.sentences += 1
            self.sentences_acted += action is not None

    @property
    def others(self) -> int:
        return self.words + self.sentences

    @property
    def others_acted(self) -> int:
        return self.words_acted + self.sentences_acted


def count(recs: list[Recording], condition: str, cache: dict[str, dict], matcher) -> Counts:
    en = [load_language("en")]
    c = Counts()
    for rec in recs:
        row = cache.get(_key(rec, condition))
        if row is None:
            continue
        recognition = _recognition(row)
        top = en[0].by_key.get(normalize_text(recognition.best.text)) if recognition.best else None
        c.add(rec.kind, rec.action, matcher.decide(recognition, en).action, top.action if top else None)
    return c


def pct(n: int, d: int) -> str:
    return f"{100.0 * n / d:.1f} % ({n}/{d})" if d else "–"
