"""Dictionary loading and validation: bundled files are complete, bad files give one clear error."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_voice.domain.dictionary import ACTIONS, MOTION_ACTIONS, available_languages, load_dictionary, load_language
from gcs_voice.errors import DictionaryError
from gcs_voice.domain.text import normalize_text


@pytest.mark.parametrize("lang", ["en", "es"])
def test_bundled_dictionary_covers_every_class(lang: str) -> None:
    d = load_language(lang)
    assert d.language == lang
    assert set(d.actions()) == set(ACTIONS)
    for action in MOTION_ACTIONS:
        assert len(d.phrases_for(action)) >= 3, action


def test_paper_phrases_present() -> None:
    en, es = load_language("en"), load_language("es")
    assert en.by_key["increase altitude"].action == "up"
    assert en.by_key["turn counterclockwise"].action == "turn_left"
    # accents are folded for matching but kept as written for grammars
    assert es.by_key["elevate"].action == "up"
    assert es.by_key["atras"].text == "atrás"
    assert "muévete" in es.vocabulary()


#: the nearest two phrases of different classes may sound: the English pair "increase altitude" / "decrease
#: altitude" (0.154), which shipped from the start; a new form nearer than that to another class is a mishearing
#: waiting to happen ("asciende" / "desciende": 0.22, kept out of es.toml for being opposite motions at one sound)
NEAREST_RIVALS = 0.15


@pytest.mark.parametrize("lang", ["en", "es"])
def test_no_phrase_sounds_almost_like_a_phrase_of_another_class(lang: str) -> None:
    from gcs_voice.understanding.phonemes import ESPEAK_VOICE, phoneme_tokens
    from gcs_voice.understanding.phonetic import phonetic_distance

    d = load_language(lang)
    sounds = {p.match_key: phoneme_tokens(p.match_key, ESPEAK_VOICE[lang]) for p in d.phrases}
    near = [(a.text, b.text, round(phonetic_distance(sounds[a.match_key], sounds[b.match_key]), 2))
            for i, a in enumerate(d.phrases) for b in d.phrases[i + 1:]
            if a.action != b.action and phonetic_distance(sounds[a.match_key], sounds[b.match_key]) < NEAREST_RIVALS]
    assert not near, near


@pytest.mark.parametrize(("lang", "said", "action"), [
    ("es", "detener", "stop"), ("es", "pare", "stop"), ("es", "parar", "stop"), ("es", "deténgase", "stop"),
    ("es", "avanzar", "go_forward"), ("es", "avance", "go_forward"), ("es", "retroceder", "go_back"),
    ("es", "suba", "up"), ("es", "bajar", "down"), ("es", "gire a la derecha", "turn_right"),
    ("es", "girar a la izquierda", "turn_left"), ("es", "vaya a la derecha", None),
    ("en", "halt", "stop"), ("en", "freeze", "stop"), ("en", "move ahead", "go_forward"),
    ("en", "go backwards", "go_back"), ("en", "rotate right", "turn_right"),
])
def test_the_forms_people_use_are_phrases(lang: str, said: str, action: str | None) -> None:
    """Infinitives, tú and usted imperatives (issue 31: "detener" was missing, and 110 of 120 real "detener" did
    nothing); a form left out on purpose (es.toml says why) stays out."""
    phrase = load_language(lang).by_key.get(normalize_text(said))
    assert (phrase.action if phrase else None) == action


def test_languages_listed() -> None:
    assert {"en", "es"} <= set(available_languages())


def test_normalisation() -> None:
    assert normalize_text("  Go  RIGHT! ") == "go right"
    assert normalize_text("¡Elévate!") == "elevate"
    assert normalize_text("Elévate", fold=False) == "elévate"
    assert normalize_text("counter-clockwise.") == "counter clockwise"


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "xx.toml"
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize(
    "body, message",
    [
        ("", "empty dictionary"),
        ('language = "xx"\n[phrases]\nup = ["rise"]\ndown = ["Rise!"]\n', "phrase 'Rise!' is listed under 'up' and 'down'"),
        ('language = "xx"\n[phrases]\nup = ["rise", "rise"]\n', "listed twice under 'up'"),
        ('language = "xx"\n[phrases]\nsideways = ["slide"]\n', "unknown action class 'sideways'"),
        ('language = "xx"\n[phrases]\nup = []\n', "non-empty list"),
        ('language = "xx"\n[phrases]\nup = [3]\n', "phrase 3 is not a string"),
        ('[phrases]\nup = ["rise"]\n', "missing 'language'"),
        ('language = "xx"\nphrases = [\n', "invalid TOML"),
        ('language = "xx"\n[phrases]\nup = ["?!"]\n', "empty after normalisation"),
        ('language = "xx"\nnot_commands = ["four", 4]\n[phrases]\nup = ["rise"]\n', "'not_commands' must be a list"),
        ('language = "xx"\nnot_commands = ["Rise"]\n[phrases]\nup = ["rise"]\n', "not_commands 'Rise' are also phrases"),
        ('language = "xx"\nnot_commands = ["go"]\n[phrases]\nup = ["go up"]\n', "not_commands 'go' begins the phrase 'go up'"),
        ('language = "xx"\nnegations = ["no", 0]\n[phrases]\nup = ["rise"]\n', "'negations' must be a list of single words"),
        ('language = "xx"\nnegations = ["do not"]\n[phrases]\nup = ["rise"]\n', "'negations' must be a list of single words"),
        ('language = "xx"\nnegations = ["no"]\n[phrases]\nup = ["rise"]\nstop = ["no more"]\n',
         "negations 'no' is a word of the phrase 'no more'"),
        ('language = "xx"\nskip_words = ["now"]\n[phrases]\nup = ["rise"]\ndown = ["rise now"]\n',
         "phrase 'rise now' ('down') is 'rise' ('up') once its skip words are removed"),
    ],
)
def test_malformed_dictionary_names_file_and_phrase(tmp_path: Path, body: str, message: str) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(DictionaryError) as err:
        load_dictionary(path)
    assert message in str(err.value)
    assert str(path) in str(err.value)


def test_missing_file_and_unknown_language(tmp_path: Path) -> None:
    with pytest.raises(DictionaryError, match="cannot read"):
        load_dictionary(tmp_path / "nope.toml")
    with pytest.raises(DictionaryError, match="no dictionary for language 'zz'"):
        load_language("zz")
