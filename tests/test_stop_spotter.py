"""The stop spotter on real recordings: it hears real "stop", not real "go", the same way every time."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_voice.asr.stop_spotter import load_stop_spotter
from gcs_voice.audio.sources import read_wav

pytest.importorskip("pocketsphinx")


def _held_out(real_speech_dir: Path, truth_or_word: str) -> list[Path]:
    """Test-split recordings (tools.speech.real_speech's speaker split) of one class, or of one non-command word."""
    from tools.speech.real_speech import load_recordings

    return [r.path for r in load_recordings(real_speech_dir, split="test")
            if r.action == truth_or_word or (r.action is None and r.path.name.startswith(truth_or_word + "_"))]


@pytest.fixture(scope="module")
def spotter():
    return load_stop_spotter(["en"])


def test_hears_real_stops_and_not_real_gos(spotter, real_speech_dir):
    stops = _held_out(real_speech_dir, "stop")
    gos = _held_out(real_speech_dir, "go")
    assert len(stops) >= 8 and len(gos) >= 3, (len(stops), len(gos))
    stop_hits = [spotter.spot(read_wav(p)).fired for p in stops]
    go_hits = [spotter.spot(read_wav(p)).fired for p in gos]
    # docs/bench/stop.md has the rates on the whole corpus; here: it tells the two words apart
    assert sum(stop_hits) / len(stops) >= sum(go_hits) / len(gos) + 0.25, (stop_hits, go_hits)
    assert any(stop_hits) and not all(go_hits)


def test_streamed_answer_is_the_whole_utterance_answer_and_does_not_depend_on_the_one_before(
        spotter, real_speech_dir):
    stop = next(p for p in _held_out(real_speech_dir, "stop") if spotter.spot(read_wav(p)).fired)
    pcm = read_wav(stop)
    first = spotter.spot(pcm)
    stream = spotter.start_stream()
    fired_at = None
    for n, i in enumerate(range(0, len(pcm), 3200)):
        if stream.accept(pcm[i:i + 3200]) and fired_at is None:
            fired_at = n
    streamed = stream.finish()
    assert streamed.word == first.word
    # other speech in between (cepstral mean reset per utterance): the same answer again
    spotter.spot(read_wav(_held_out(real_speech_dir, "go_left")[0]))
    assert spotter.spot(pcm).word == first.word


def test_spanish_stop_words_get_their_own_pronunciations():
    spotter = load_stop_spotter(["es"])
    assert sorted(spotter.words) == sorted(["para_es", "alto_es", "detente_es", "quieto_es"])
    # the English dictionary's "para" (P EH R AH) is not the one spotted
    assert spotter.decoder.lookup_word("para_es") == "P AA R AA"


def test_over_the_bridge_voice_its_own_threshold_applies_and_the_usual_search_comes_back(real_speech_dir):
    """Audio heard while the bridge speaks is spotted with ``over_voice_threshold``; the next utterance, with the
    usual threshold again. The stop words fire at the usual threshold's 1e-15 and mostly not at 1e-3."""
    strict = load_stop_spotter(["en"], over_voice_thresholds={"en": 1e-3})
    stops = [read_wav(p) for p in _held_out(real_speech_dir, "stop")]
    usual = [strict.spot(pcm).fired for pcm in stops]
    over = [strict.spot(pcm, over_voice=True).fired for pcm in stops]
    again = [strict.spot(pcm).fired for pcm in stops]
    assert sum(over) < sum(usual) - 3, (usual, over)
    assert again == usual  # one search per stream: the stricter one does not stay on
    import tomllib

    from gcs_voice.asr.stop_spotter import SETTINGS_PATH

    shipped = tomllib.loads(SETTINGS_PATH.read_text(encoding="utf-8"))
    for lang in ("en", "es"):  # never more lenient over the bridge's voice, in any language
        assert shipped[lang]["over_voice_threshold"] >= shipped[lang]["threshold"], lang


def test_a_word_on_the_bridge_own_echo_is_dismissed_and_a_stop_after_it_still_counts(spotter, real_speech_dir):
    """Over the bridge's voice a stop word heard when the canceller says all it gave out was its own echo's
    remains is dismissed; the stream listens on afresh, so a real stop said after those remains still stops."""
    stops = [read_wav(p) for p in _held_out(real_speech_dir, "stop")]
    pcm = next(s for s in stops if spotter.spot(s, over_voice=True).fired)
    remains = [True]  # what the canceller says while the first "stop" is heard; then a voice comes through
    stream = spotter.start_stream(True, own_echo=lambda: remains[0])
    for i in range(0, len(pcm), 1024):
        stream.accept(pcm[i:i + 1024])
    assert stream.word is None and stream.dismissed, "a stop word heard on the bridge's own remains stopped"
    remains[0] = False
    for i in range(0, 16_000, 1024):  # half a second of silence: the dismissed word does not come back
        stream.accept(bytes(1024))
    assert stream.word is None, "the dismissed word came back once the canceller heard a voice"
    for i in range(0, len(pcm), 1024):
        stream.accept(pcm[i:i + 1024])
    hit = stream.finish()
    assert hit.fired, "after dismissed remains, the pilot's stop was not heard"
    # and without the canceller's word (the usual search, or no echo canceller) nothing is dismissed
    plain = spotter.start_stream(True)
    plain.accept(pcm)
    assert plain.finish().fired and plain.dismissed == []
