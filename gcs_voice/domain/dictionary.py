"""Domain dictionaries: which spoken phrases mean which action class, one TOML file per language.

A new language is a new file in ``dictionaries/`` (or any path given by the user); no code change.
Loading validates the file completely and names the file and the phrase in every error, because a
dictionary mistake silently turns one command into another.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from gcs_voice.errors import DictionaryError
from gcs_voice.domain.text import normalize_text

__all__ = [
    "MOTION_ACTIONS",
    "FLIGHT_ACTIONS",
    "HOME_ACTIONS",
    "ACTIONS",
    "AUTO_LANGUAGES",
    "Dictionary",
    "Phrase",
    "load_dictionary",
    "load_language",
    "available_languages",
    "dictionaries_dir",
]

#: The paper's nine action classes, in the paper's order.
MOTION_ACTIONS: tuple[str, ...] = (
    "up", "down", "go_right", "go_left", "go_forward", "go_back", "turn_right", "turn_left", "stop",
)
#: Flight management a real flight needs beyond the nine (not part of the paper's benchmark).
FLIGHT_ACTIONS: tuple[str, ...] = ("take_off", "land", "arm", "disarm")
#: Back to where the flight started (issue 33): a motion to home that ends by itself and holds there, or the
#: autopilot's own RTL (settings: return_home_lands)
HOME_ACTIONS: tuple[str, ...] = ("return_home",)
ACTIONS: tuple[str, ...] = MOTION_ACTIONS + FLIGHT_ACTIONS + HOME_ACTIONS
#: What ``--lang auto`` listens for: the product's two languages (the paper's users mixed them).
#: Other bundled dictionaries (``ko``, for the Vosk test) are used only when asked for by name.
AUTO_LANGUAGES: tuple[str, ...] = ("en", "es")


@dataclass(frozen=True)
class Phrase:
    """One dictionary phrase: as written (for grammars and display) and normalised (for matching).

    ``match_key`` is ``key`` without the dictionary's skip words: a heard transcript loses them before it
    is matched, so the phrase must too ("land the drone", heard exactly, is "land the" on both sides)."""

    text: str
    key: str
    action: str
    match_key: str = ""

    def __post_init__(self) -> None:
        if not self.match_key:
            object.__setattr__(self, "match_key", self.key)


@dataclass(frozen=True)
class Dictionary:
    """All phrases of one language. ``phrases`` keeps file order; ``by_key`` maps normalised text to a phrase."""

    language: str
    name: str
    path: Path
    phrases: tuple[Phrase, ...]
    skip_words: tuple[str, ...] = ()
    #: (also under its ``match_key``, the text a heard transcript is looked up with once its skip words are gone)
    by_key: dict[str, Phrase] = field(default_factory=dict, compare=False, repr=False)
    #: words people say near a drone that sound like commands ("four", "off"): a recogniser that weighs
    #: alternatives scores them as rivals of the phrases, and no action follows when one is as likely
    not_commands: tuple[str, ...] = ()
    #: words that turn a command into its refusal ("don't", "no", "nunca"), normalised: a transcript with one
    #: in it is not acted on ("Don't go left" is no "go left"), whatever else it scores
    negations: tuple[str, ...] = ()

    def actions(self) -> tuple[str, ...]:
        """Action classes this dictionary covers, in canonical order."""
        present = {p.action for p in self.phrases}
        return tuple(a for a in ACTIONS if a in present)

    def phrases_for(self, action: str) -> tuple[Phrase, ...]:
        return tuple(p for p in self.phrases if p.action == action)

    def vocabulary(self) -> tuple[str, ...]:
        """Distinct words of all phrases as written (accents kept), for recogniser grammars."""
        words: dict[str, None] = {}
        for p in self.phrases:
            for w in normalize_text(p.text, fold=False).split():
                words.setdefault(w, None)
        return tuple(words)

    def strip_skip_words(self, normalised_text: str) -> str:
        """Drop filler words ("please", "drone") from an already-normalised transcript."""
        return _strip(normalised_text, self.skip_words)


def dictionaries_dir() -> Path:
    """Where the bundled dictionaries are: the source tree's ``dictionaries/`` or the wheel's copy."""
    here = Path(__file__).resolve().parent
    for candidate in (here.parents[1] / "dictionaries", here.parent / "_data" / "dictionaries"):
        if candidate.is_dir():
            return candidate
    raise DictionaryError(f"bundled dictionaries not found next to {here}")


def available_languages() -> tuple[str, ...]:
    """Language codes of the bundled dictionaries (file stems), sorted."""
    return tuple(sorted(p.stem for p in dictionaries_dir().glob("*.toml")))


def load_language(lang: str) -> Dictionary:
    """Load the bundled dictionary for a language code such as ``en`` or ``es``."""
    path = dictionaries_dir() / f"{lang}.toml"
    if not path.is_file():
        langs = ", ".join(available_languages()) or "none"
        raise DictionaryError(f"no dictionary for language {lang!r} (bundled: {langs})")
    return load_dictionary(path)


def load_dictionary(path: str | Path) -> Dictionary:
    """Read and validate one dictionary file; every problem raises DictionaryError naming file and phrase."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DictionaryError(f"{path}: cannot read dictionary: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise DictionaryError(f"{path}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise DictionaryError(f"{path}: invalid TOML: {exc}") from None
    if not data:
        raise DictionaryError(f"{path}: empty dictionary")

    language = data.get("language")
    if not isinstance(language, str) or not language.strip():
        raise DictionaryError(f"{path}: missing 'language' (a code such as \"en\")")
    name = data.get("name", language)
    if not isinstance(name, str):
        raise DictionaryError(f"{path}: 'name' must be a string")
    skip = data.get("skip_words", [])
    if not isinstance(skip, list) or not all(isinstance(w, str) for w in skip):
        raise DictionaryError(f"{path}: 'skip_words' must be a list of strings")
    others = data.get("not_commands", [])
    if not isinstance(others, list) or not all(isinstance(w, str) and normalize_text(w) for w in others):
        raise DictionaryError(f"{path}: 'not_commands' must be a list of non-empty strings")
    negations = data.get("negations", [])
    if not isinstance(negations, list) or not all(isinstance(w, str) and len(normalize_text(w).split()) == 1
                                                  for w in negations):
        raise DictionaryError(f"{path}: 'negations' must be a list of single words")
    unknown_keys = set(data) - {"language", "name", "skip_words", "phrases", "not_commands", "negations"}
    if unknown_keys:
        raise DictionaryError(f"{path}: unknown key(s) {', '.join(sorted(unknown_keys))}")
    table = data.get("phrases")
    if not isinstance(table, dict) or not table:
        raise DictionaryError(f"{path}: no [phrases] table, or it is empty")

    phrases: list[Phrase] = []
    by_key: dict[str, Phrase] = {}
    skip_keys = tuple(normalize_text(w) for w in skip)
    for action, items in table.items():
        if action not in ACTIONS:
            raise DictionaryError(
                f"{path}: unknown action class {action!r} (known: {', '.join(ACTIONS)})"
            )
        if not isinstance(items, list) or not items:
            raise DictionaryError(f"{path}: class {action!r} needs a non-empty list of phrases")
        for text in items:
            if not isinstance(text, str):
                raise DictionaryError(f"{path}: class {action!r}: phrase {text!r} is not a string")
            key = normalize_text(text)
            if not key:
                raise DictionaryError(f"{path}: class {action!r}: phrase {text!r} is empty after normalisation")
            if key in by_key:
                other = by_key[key]
                where = "twice under" if other.action == action else f"under {other.action!r} and"
                raise DictionaryError(f"{path}: phrase {text!r} is listed {where} {action!r}")
            phrase = Phrase(text=text, key=key, action=action, match_key=_strip(key, skip_keys) or key)
            by_key[key] = phrase
            phrases.append(phrase)

    # a heard transcript is matched without its skip words: two classes must not become one text then
    for phrase in phrases:
        other = by_key.setdefault(phrase.match_key, phrase)
        if other.action != phrase.action:
            raise DictionaryError(f"{path}: phrase {phrase.text!r} ({phrase.action!r}) is {other.text!r} "
                                  f"({other.action!r}) once its skip words are removed")

    clash = [w for w in others if normalize_text(w) in by_key]
    if clash:
        raise DictionaryError(f"{path}: not_commands {', '.join(map(repr, clash))} are also phrases")
    # a rival that a phrase starts with wins whenever only the phrase's first word is heard ("go" / "go up")
    starts = [(w, p.text) for w in others for p in phrases if p.key.startswith(normalize_text(w) + " ")]
    if starts:
        word, text = starts[0]
        raise DictionaryError(f"{path}: not_commands {word!r} begins the phrase {text!r}")
    # a negation inside a phrase would refuse that phrase whenever it is heard
    negation_keys = tuple(dict.fromkeys(normalize_text(w) for w in negations))
    said = [(w, p.text) for w in negation_keys for p in phrases if w in p.key.split()]
    if said:
        word, text = said[0]
        raise DictionaryError(f"{path}: negations {word!r} is a word of the phrase {text!r}")
    return Dictionary(
        language=language.strip(),
        name=name,
        path=path,
        phrases=tuple(phrases),
        skip_words=skip_keys,
        by_key=by_key,
        not_commands=tuple(others),
        negations=negation_keys,
    )


def _strip(normalised_text: str, skip_words: tuple[str, ...]) -> str:
    text = f" {normalised_text} "
    for w in skip_words:
        text = text.replace(f" {w} ", " ")
    return " ".join(text.split())
