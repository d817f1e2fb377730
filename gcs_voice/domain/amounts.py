"""How far: the amount said after a command ("go forward three metres", "gira a la derecha noventa grados").

The words are data (``amounts.toml`` beside this module). An amount is read from the END of a normalised
transcript: ``[to] NUMBER [UNIT] [HEIGHT]``, the words before it being the command. Anything that looks like
an amount but is not a clear one (words in a wrong order, a unit that does not fit the motion, a number out of
range) is a reason to do nothing, never a guess and never clipped: a wrong amount is a wrong action.
Which amounts sound alike (``alike``) is data too; Whisper scoring weighs them (``gcs_voice.asr.whisper_score``).
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from gcs_voice.domain.text import normalize_text
from gcs_voice.errors import GcsVoiceError

__all__ = ["AMOUNTS_PATH", "Amount", "AmountsError", "Split", "alike", "amount_reason", "judge", "min_amount_gap",
           "number_words", "split_amount", "vocabulary"]

AMOUNTS_PATH = Path(__file__).resolve().parent / "amounts.toml"
#: which motion classes take which amount kind
TURNS = frozenset({"turn_left", "turn_right"})
DISTANCE_MOTIONS = frozenset({"go_forward", "go_back", "go_left", "go_right", "up", "down"})
HEIGHT_MOTIONS = frozenset({"up", "down"})
_DIGITS_UNIT = re.compile(r"^(\d+)([a-z]+)$")


class AmountsError(GcsVoiceError):
    """The amounts vocabulary is missing or malformed."""


@dataclass(frozen=True)
class Amount:
    """An amount as said: ``value`` in ``unit`` ("m" or "deg"); ``height`` True for "to 5 metres" (a height
    to reach above home, not a distance to move); ``words`` what was heard."""

    value: int
    unit: str
    height: bool = False
    words: str = ""

    @property
    def label(self) -> str:
        """Short human form for the view, the log and the plot: "3 m", "45°", "to 5 m"."""
        text = f"{self.value}°" if self.unit == "deg" else f"{self.value} m"
        return f"to {text}" if self.height else text

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "unit": self.unit, "height": self.height, "label": self.label}


@dataclass(frozen=True)
class Split:
    """A transcript cut into its command words and its amount. ``amount`` None and ``reason`` "" = no amount
    was said; ``reason`` set = amount words were said but are not a clear amount (then ``amount`` is None)."""

    command: str
    amount: Amount | None = None
    reason: str = ""
    #: the amount's words as heard (the number, its unit, the height words), "" when none
    words: str = ""
    #: the transcript is an amount and nothing else ("7", "three metres"): no command was heard
    amount_alone: bool = False
    #: the number's words as heard ("100 and 35", "forty five"), "" when none
    number: str = ""


@dataclass(frozen=True)
class Vocabulary:
    numbers: dict[str, int]
    joins: frozenset[str]
    to: frozenset[str]
    height: tuple[tuple[str, ...], ...]
    units: dict[str, str]
    say_hundred: str
    to_elided_after: tuple[str, ...]
    alike: tuple[frozenset[int], ...]
    ranges: dict[str, tuple[int, int]]
    #: words Whisper writes for a number said just before a unit word ("for meters"): read as that number there
    before_unit: dict[str, int] = field(default_factory=dict)

    @property
    def words(self) -> frozenset[str]:
        """Every word an amount may use (numbers, joins, units, height and 'to' words)."""
        return frozenset(self.numbers) | self.joins | self.to | frozenset(self.units) | frozenset(
            w for h in self.height for w in h)


@lru_cache(maxsize=8)
def vocabulary(lang: str, path: Path = AMOUNTS_PATH) -> Vocabulary | None:
    """The amount words of one language (None: that language has no amounts)."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise AmountsError(f"{path}: cannot read the amounts vocabulary: {exc}") from None
    table = data.get(lang)
    if table is None:
        return None
    try:
        ranges = {unit: (int(lo), int(hi)) for unit, (lo, hi) in data["ranges"].items()}
        return Vocabulary(
            numbers={str(k): int(v) for k, v in table["numbers"].items()},
            joins=frozenset(table.get("joins", [])),
            to=frozenset(table.get("to", [])),
            height=tuple(tuple(h.split()) for h in table.get("height", [])),
            units={str(k): str(v) for k, v in table["units"].items()},
            say_hundred=str(table.get("say_hundred", "")),
            to_elided_after=tuple(str(w) for w in table.get("to_elided_after", [])),
            alike=tuple(frozenset(int(v) for v in group) for group in table.get("alike", [])),
            ranges=ranges,
            before_unit={str(k): int(v) for k, v in table.get("before_unit", {}).items()},
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise AmountsError(f"{path}: [{lang}] is malformed ({exc})") from None


def _words(text: str) -> list[str]:
    """Normalised words with "3m" split into "3", "m"."""
    out: list[str] = []
    for word in text.split():
        m = _DIGITS_UNIT.match(word)
        out.extend(m.groups() if m else (word,))
    return out


def _number(words: list[str], vocab: Vocabulary) -> int | None:
    """The value of a run of number words, or None when they are no number ("five forty")."""
    if len(words) == 1 and words[0].isdigit():
        return int(words[0])
    values: list[int] = []
    for i, word in enumerate(words):
        if word in vocab.joins:
            if i == 0 or i == len(words) - 1 or words[i - 1] in vocab.joins:
                return None
            continue
        # Whisper writes a number in parts as digits ("100 and 35" for "one hundred and thirty five"): each
        # part reads as its word would, and the same rules of order apply
        if word.isdigit() and 0 < int(word) <= 100:
            values.append(int(word))
            continue
        if word not in vocab.numbers:
            return None
        values.append(vocab.numbers[word])
    total = 0
    if 100 in values:
        k = values.index(100)
        if k > 1 or (k == 1 and not 1 <= values[0] <= 9):
            return None
        total, values = 100 * (values[0] if k else 1), values[k + 1:]
    if 100 in values:
        return None
    if not values:
        return total or None
    if len(values) == 1:
        return total + values[0]
    if len(values) == 2 and values[0] >= 20 and values[0] % 10 == 0 and 1 <= values[1] <= 9:
        return total + values[0] + values[1]
    return None


def split_amount(text: str, lang: str) -> Split:
    """Cut a normalised transcript (skip words removed) into command words and an amount said after them."""
    vocab = vocabulary(lang)
    if vocab is None:
        return Split(text)
    words = _words(text)
    end = len(words)
    height = False
    for tail in sorted(vocab.height, key=len, reverse=True):
        if len(tail) < end and tuple(words[end - len(tail):]) == tail:
            end -= len(tail)
            height = True
            break
    unit = None
    if end and words[end - 1] in vocab.units:
        unit = vocab.units[words[end - 1]]
        end -= 1
    if (unit is not None and end and words[end - 1] in vocab.before_unit
            and (end < 2 or not (words[end - 2] in vocab.numbers or words[end - 2].isdigit()))):
        # "go to the right for meters": the one word before the unit is the number Whisper wrote as another word
        number = words[end - 1]
        words = [*words[:end - 1], str(vocab.before_unit[number]), *words[end:]]
    else:
        number = ""
    start = end
    while start and (words[start - 1] in vocab.numbers or words[start - 1].isdigit()
                     or (words[start - 1] in vocab.joins and start < end)):
        start -= 1
    while start < end and words[start] in vocab.joins:   # "... y" is no number: the join belongs to the command
        start += 1
    if start == end or (unit is None and not height and words[start:end] == ["a"]):
        return Split(text)  # no number: a plain command (a unit word alone is left to the matcher)
    if start and words[start - 1] in vocab.to:
        height = True
        start -= 1
        number_at = start + 1
    else:
        number_at = start
    said = " ".join(words[start:]) if not number else " ".join([*words[start:end - 1], number, *words[end:]])
    command = " ".join(words[:start])
    if not command:
        return Split(text, reason=f"'{text}' is an amount with no command", amount_alone=True)
    number = number or " ".join(words[number_at:end])
    value = _number(words[number_at:end], vocab)
    if value is None:
        return Split(command, reason=f"unclear amount '{said}': say again", words=said, number=number)
    unit = unit or ""
    if unit and unit not in vocab.ranges:
        return Split(command, reason=f"unknown unit in '{said}'", words=said)
    if unit:
        lo, hi = vocab.ranges[unit]
        if not lo <= value <= hi:
            return Split(command, reason=f"{value} {_unit_name(unit)} is out of range ({lo}-{hi}): not done",
                         words=said, number=number)
    return Split(command, Amount(value, unit, height, said), words=said, number=number)


def ends_in_number(text: str, lang: str) -> bool:
    """Whether a normalised transcript (skip words removed) ends in an amount being said: a number (words or
    digits, or a word Whisper writes for one before a unit, "for meters") and after it only words an amount
    may use ("one hundred and", "3 meters"). A number followed by other words ("a 16-ounce dark roast") is
    not the amount of a command: that would end the transcript."""
    vocab = vocabulary(lang)
    if vocab is None:
        return False
    words = _words(text)
    last = max((i for i, w in enumerate(words) if w.isdigit() or w in vocab.numbers or w in vocab.before_unit),
               default=None)
    return last is not None and all(w in vocab.words or w.isdigit() for w in words[last + 1:])


def amount_reason(amount: Amount, action: str, lang: str) -> tuple[Amount | None, str]:
    """The amount made definite for ``action`` (a unit given where none was said), or the reason it does
    not fit (a turn in metres, a move in degrees, a height for a sideways move, out of range)."""
    vocab = vocabulary(lang)
    assert vocab is not None
    wanted = "deg" if action in TURNS else "m" if action in DISTANCE_MOTIONS else None
    if wanted is None:
        return None, f"'{action}' takes no amount"
    if amount.unit and amount.unit != wanted:
        return None, f"'{action}' is not measured in {_unit_name(amount.unit)}"
    if amount.height and action not in HEIGHT_MOTIONS:
        return None, f"a height goes with up or down, not '{action}'"
    lo, hi = vocab.ranges[wanted]
    if not lo <= amount.value <= hi:
        return None, f"{amount.value} {_unit_name(wanted)} is out of range ({lo}-{hi}): not done"
    return Amount(amount.value, wanted, amount.height, amount.words), ""


@lru_cache(maxsize=4)
def min_amount_gap(path: Path = AMOUNTS_PATH) -> float:
    """How much more likely the heard amount must be than each that sounds alike (``[decision]``)."""
    try:
        return float(tomllib.loads(Path(path).read_text(encoding="utf-8"))["decision"]["min_amount_gap"])
    except (OSError, tomllib.TOMLDecodeError, KeyError, TypeError, ValueError) as exc:
        raise AmountsError(f"{path}: [decision] min_amount_gap missing or malformed ({exc})") from None


def judge(transcript: str, extra: dict[str, float], engine: str, dictionary: Any,
          action: str) -> tuple[Amount | None, str]:
    """The amount said with ``action`` in the engine's own ``transcript`` (None, "" when none was said), or the
    reason to do nothing: unclear, out of range, not fitting the motion, or not clearly more likely than an
    amount that sounds alike (``extra["amount_gap"]``, Whisper scoring); an engine that cannot weigh amounts
    never acts on one."""
    lang = dictionary.language
    if not transcript or vocabulary(lang) is None:
        return None, ""
    split = split_amount(dictionary.strip_skip_words(normalize_text(transcript)), lang)
    if not split.words:
        return None, ""
    if split.reason:
        return None, f"heard '{transcript}': {split.reason}"
    assert split.amount is not None
    gap = extra.get("amount_gap")
    if gap is None:
        return None, f"heard an amount ('{split.words}'), but {engine} cannot weigh amounts: say the command alone"
    if gap < min_amount_gap():
        rival = int(extra.get("amount_rival", 0))
        other = (f"'{abs(rival)}' as a {'distance' if split.amount.height else 'height'}" if rival < 0
                 else f"{rival}")
        return None, (f"unsure of the amount: heard '{split.words}', but nearly as much {other} "
                      f"(amount_gap {gap:.2f} < {min_amount_gap():.2f}): say again")
    amount, why = amount_reason(split.amount, action, lang)
    if amount is not None and action in HEIGHT_MOTIONS and not amount.height:
        last = split.command.split()[-1] if split.command else ""
        vocab = vocabulary(lang)
        if vocab is not None and vocab.to and any(last.endswith(end) for end in vocab.to_elided_after):
            return None, (f"unsure of the amount: '{split.command} {split.words}' sounds like '{split.command} "
                          f"{sorted(vocab.to)[0]} {split.words}' (a height): say it with another word")
    return amount, (f"heard '{transcript}': {why}" if why else "")


def alike(value: int, lang: str) -> tuple[int, ...]:
    """The amounts that sound like ``value`` (its groups in ``alike``), without itself."""
    vocab = vocabulary(lang)
    if vocab is None:
        return ()
    groups = {v for group in vocab.alike if value in group for v in group}
    # "one hundred and eighty" sounds like "one hundred and eighteen" as "eighty" does like "eighteen"
    hundreds, rest = value - value % 100, value % 100
    if hundreds and rest:
        groups |= {hundreds + v for group in vocab.alike if rest in group for v in group}
    return tuple(sorted(groups - {value}))


def number_words(value: int, lang: str) -> str:
    """One way to say ``value`` in words (for rivals and the corpus): the shortest spelling the vocabulary reads."""
    vocab = vocabulary(lang)
    assert vocab is not None
    names: dict[int, str] = {}
    for word, v in vocab.numbers.items():   # the first word of the file for each value ("one", not "a")
        names.setdefault(v, word)
    if value in names:
        return names[value]
    hundreds, rest = divmod(value, 100)
    parts = [vocab.say_hundred or names[100]] if hundreds else []
    if rest in names:
        parts.append(names[rest])
    elif rest:
        tens, units = rest - rest % 10, rest % 10
        join = sorted(vocab.joins)[0] if lang == "es" and vocab.joins else ""
        parts += [names[tens], *([join] if join else []), names[units]]
    return " ".join(parts)


def _unit_name(unit: str) -> str:
    return {"m": "metres", "deg": "degrees"}.get(unit, unit)
