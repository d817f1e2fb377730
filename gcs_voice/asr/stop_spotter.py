"""A stop that is never late: spot the stop class (stop, halt, hold, ...; para, alto, ...) cheaply, first.

Stopping is always safe, so a stop must not wait for the main recogniser, which can take seconds on a
busy machine. This runs PocketSphinx keyword spotting (the English model in the pocketsphinx wheel;
the Spanish words get phone strings in ``stop_spotter.toml``) on each utterance before the main
recogniser: a few tens of milliseconds. When it fires the session stops the vehicle at once; the main
decision follows and may command something else. A false stop costs a pause, a late stop a wall.

Every utterance starts from freshly initialised features (``reinit_feat``: the cepstral mean and the
rest), so the answer does not depend on what was heard before.
"""

from __future__ import annotations

import tempfile
import threading
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gcs_voice.errors import ModelError

__all__ = ["StopSpotter", "StopHit", "SpotStream", "load_stop_spotter", "SETTINGS_PATH"]

SETTINGS_PATH = Path(__file__).resolve().parent / "stop_spotter.toml"
SEARCH, OVER_VOICE_SEARCH = "stop", "stop_over_voice"


@dataclass(frozen=True)
class StopHit:
    """What the spotter heard: the word, or None; and how long it took."""

    word: str | None
    ms: float

    @property
    def fired(self) -> bool:
        return self.word is not None


class StopSpotter:
    """Keyword spotting over one utterance of 16 kHz mono s16le PCM; thread-safe (one decoder, a lock)."""

    def __init__(self, languages: list[str], settings_path: Path = SETTINGS_PATH,
                 thresholds: dict[str, float] | None = None, words: list[str] | None = None,
                 over_voice_thresholds: dict[str, float] | None = None) -> None:
        from pocketsphinx import Decoder

        with open(settings_path, "rb") as f:
            data = tomllib.load(f)
        lines, over_voice, phones = [], [], {}
        for lang in languages:
            if lang not in data:
                continue
            section = data[lang]
            threshold = (thresholds or {}).get(lang, float(section["threshold"]))
            strict = (over_voice_thresholds or {}).get(lang, float(section.get("over_voice_threshold", threshold)))
            for word in (words if words is not None else section["words"]):
                token = f"{word}_{lang}" if word in section.get("phones", {}) else word
                if token != word:
                    phones[token] = section["phones"][word]
                lines.append(f"{token} /{threshold:g}/")
                over_voice.append(f"{token} /{strict:g}/")
        if not lines:
            raise ModelError(f"the stop spotter has no words for {', '.join(languages) or 'no language'}")
        try:
            self.decoder = Decoder(lm=None, loglevel="FATAL")
        except Exception as exc:  # pocketsphinx raises RuntimeError with no detail
            raise ModelError(f"cannot load the PocketSphinx model for the stop spotter: {exc}") from None
        for token, ph in phones.items():
            self.decoder.add_word(token, ph, True)
        missing = [line.split()[0] for line in lines if self.decoder.lookup_word(line.split()[0]) is None]
        if missing:
            raise ModelError(f"stop spotter words without pronunciation: {', '.join(missing)}")
        # Two searches over the same words: the usual one, and one (over_voice_threshold) for what the microphone
        # hears while the bridge itself speaks (what the echo canceller leaves of its words can sound like "stay")
        for search, search_lines in ((SEARCH, lines), (OVER_VOICE_SEARCH, over_voice)):
            with tempfile.NamedTemporaryFile("w", suffix=".kws", delete=False) as f:
                f.write("\n".join(search_lines) + "\n")
                kws_file = f.name
            try:
                self.decoder.add_kws(search, kws_file)
            finally:
                Path(kws_file).unlink(missing_ok=True)
        self.decoder.activate_search(SEARCH)
        self.words = [line.split()[0] for line in lines]
        self._lock = threading.Lock()

    def spot(self, pcm: bytes, over_voice: bool = False) -> StopHit:
        """Whether a stop word is anywhere in this utterance (decoded whole); ``over_voice``: heard while the
        bridge itself was speaking (over_voice_threshold)."""
        stream = self.start_stream(over_voice)
        stream.accept(pcm)
        return stream.finish()

    def start_stream(self, over_voice: bool = False, own_echo: Callable[[], bool] | None = None) -> SpotStream:
        """Spot while the utterance is still arriving: ``accept`` says as soon as a stop word is heard.

        ``own_echo`` (over the bridge's voice): whether what was heard of late is only what the echo canceller
        left of the bridge's own sound (``PlayedEcho.only_remains``); a word heard then is dismissed."""
        return SpotStream(self, over_voice, own_echo)


def _word(hyp: object) -> str | None:
    text = getattr(hyp, "hypstr", "") if hyp is not None else ""
    return text.split()[0].rsplit("_", 1)[0] if text and text.split() else None


class SpotStream:
    """One utterance fed in pieces; the decoder is held (a lock) from the first piece to ``finish``.

    ``finish`` decodes the same whole utterance as ``spot`` does: the stream only decides earlier. A word
    ``own_echo`` dismisses is kept in ``dismissed``, and the stream listens on afresh from there.
    """

    def __init__(self, spotter: StopSpotter, over_voice: bool = False, own_echo: Callable[[], bool] | None = None
                 ) -> None:
        self.spotter = spotter
        self.over_voice = over_voice
        self.own_echo = own_echo
        self.dismissed: list[str] = []
        self.word: str | None = None
        self.ms = 0.0
        self._open = False
        self._done = False

    def accept(self, pcm: bytes) -> str | None:
        """Feed more audio; the stop word once heard (then on every later call), else None."""
        if self._done or not pcm:
            return self.word
        started = time.perf_counter()
        d = self.spotter.decoder
        if not self._open:
            self.spotter._lock.acquire()
            self._open = True
            d.activate_search(OVER_VOICE_SEARCH if self.over_voice else SEARCH)
            d.reinit_feat()  # fresh features: set_cmn alone left state behind (same audio, other words)
            d.start_utt()
        d.process_raw(pcm, False, False)
        if self.word is None:
            word = _word(d.hyp())
            if word is not None and self._own(word):
                d.end_utt()  # our own echo's remains: listen on afresh, a stop said after them still counts
                d.reinit_feat()
                d.start_utt()
            else:
                self.word = word
        self.ms += (time.perf_counter() - started) * 1000.0
        return self.word

    def _own(self, word: str) -> bool:
        """Whether ``word`` was heard in nothing but the bridge's own echo's remains (then it is dismissed)."""
        if self.own_echo is not None and self.own_echo():
            self.dismissed.append(word)
            return True
        return False

    def finish(self) -> StopHit:
        """End the utterance (idempotent): whether a stop word was anywhere in it, and the decoding time."""
        if not self._done:
            self._done = True
            if self._open:
                started = time.perf_counter()
                d = self.spotter.decoder
                try:
                    d.end_utt()
                    word = _word(d.hyp()) if self.word is None else None
                    if word is not None and not self._own(word):
                        self.word = word
                finally:
                    self.spotter._lock.release()
                self.ms += (time.perf_counter() - started) * 1000.0
        return StopHit(self.word, self.ms)


def load_stop_spotter(languages: list[str], thresholds: dict[str, float] | None = None,
                      words: list[str] | None = None,
                      over_voice_thresholds: dict[str, float] | None = None) -> StopSpotter:
    """The stop spotter for these dictionary languages (English and Spanish words; others are ignored).

    ``thresholds`` (per language) and ``words`` override ``stop_spotter.toml`` (for the benchmark's sweep).
    """
    return StopSpotter(languages, thresholds=thresholds, words=words, over_voice_thresholds=over_voice_thresholds)
