"""What every matcher shares: reading the recognition, the rejection rules, and the reason sentences.

A matcher only has to say how far a heard (normalised) text is from one dictionary phrase, as a
distance in [0, 1]. This base turns distances into a Decision: the nearest phrase over all
dictionaries (several = ``--lang auto``) and the considered n-best alternatives wins, unless the
engine's own evidence, its confidence, the distance or the margin to another class says "unsure",
in which case the drone does nothing and the reason says why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from rapidfuzz.distance import LCSseq, Levenshtein

from gcs_voice.asr.base import Hypothesis, Recognition
from gcs_voice.asr.ear import NONE as EAR_NONE, ear_evidence
from gcs_voice.domain import amounts
from gcs_voice.understanding.decision import Decision
from gcs_voice.domain.dictionary import Dictionary, Phrase
from gcs_voice.errors import GcsVoiceError
from gcs_voice.understanding.thresholds import (THRESHOLDS_PATH, ear_limits, evidence_limits, matcher_thresholds,
                                                transcript_limits)
from gcs_voice.domain.text import normalize_text

__all__ = ["Matcher", "Candidate", "Ranking", "MatcherOptionError"]

#: Options every matcher understands (all numbers; ``reject`` is 0/1 or a bool).
KNOWN_OPTIONS = (
    "max_distance",  # reject when the nearest phrase is farther than this (normalised distance)
    "min_margin",  # reject when another class is within this distance of the winner
    "min_confidence",  # reject when the best hypothesis' engine confidence is below this
    "alternatives",  # how many n-best hypotheses to consider
    "alt_penalty",  # distance added per rank below the best hypothesis
    "reject",  # 0 = the paper's behaviour: always act on the nearest phrase
)


class MatcherOptionError(GcsVoiceError):
    """A matcher was given an option it does not know, or a value that is not a number."""


@dataclass(frozen=True)
class Candidate:
    """One (heard alternative, dictionary phrase) pair and how far apart they are."""

    distance: float
    phrase: Phrase
    dictionary: Dictionary
    heard: str
    rank: int
    text: str


@dataclass(frozen=True)
class Ranking:
    """Nearest phrase, nearest phrase of another class, and an early rejection reason (or "")."""

    best: Candidate | None
    rival: Candidate | None
    reason: str = ""


class Matcher:
    """Base class: subclasses set ``name`` and implement ``distance``."""

    name: str = ""
    #: n-best alternatives considered unless thresholds/options say otherwise.
    default_alternatives: int = 1

    def __init__(self, *, thresholds_path: str | Path = THRESHOLDS_PATH, **options: object) -> None:
        self.thresholds_path = Path(thresholds_path)
        self.options: dict[str, float] = {}
        for key, value in options.items():
            if key not in KNOWN_OPTIONS:
                raise MatcherOptionError(
                    f"matcher {self.name!r} has no option {key!r} (known: {', '.join(KNOWN_OPTIONS)})"
                )
            try:
                self.options[key] = float(value)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                raise MatcherOptionError(f"matcher option {key}={value!r} is not a number") from None

    # -- what subclasses provide -------------------------------------------------------------------
    def distance(self, heard: str, phrase: Phrase, dictionary: Dictionary) -> float:
        """Normalised distance in [0, 1] between a normalised heard text and one phrase."""
        raise NotImplementedError

    def prepare(self, dictionaries: Sequence[Dictionary]) -> None:
        """Hook to precompute per-dictionary data (phoneme strings...); called on every decide."""

    # -- the shared decision -----------------------------------------------------------------------
    def thresholds(self, engine: str | None) -> dict[str, float]:
        """Effective thresholds: file defaults, the engine's overrides, then this matcher's options."""
        merged = {"max_distance": 0.35, "min_margin": 0.0, "min_confidence": 0.0, "alt_penalty": 0.02,
                  "alternatives": float(self.default_alternatives), "reject": 1.0}
        merged.update(matcher_thresholds(self.name, engine, self.thresholds_path))
        merged.update(self.options)
        return merged

    def decide(self, recognition: Recognition, dictionaries: Sequence[Dictionary]) -> Decision:
        """Nearest phrase over all dictionaries and alternatives, or no action with the reason."""
        decision = self._decide(recognition, dictionaries)
        if not decision.accepted and self._speech_went_on(recognition):
            decision = replace(decision, went_on=True)
        return decision

    def _decide(self, recognition: Recognition, dictionaries: Sequence[Dictionary]) -> Decision:
        limits = self.thresholds(recognition.engine)
        rejecting = limits["reject"] != 0.0
        vouched, recognition = self._ear_vouches(recognition, dictionaries) if rejecting else ("", recognition)
        ranked = self.rank(recognition, dictionaries, limits, waived=EAR_WAIVES if vouched else frozenset())
        if vouched and ranked.best is not None and ranked.best.phrase.action != vouched:
            vouched = ""  # the ear spoke for another phrase than the one matched: no waiver
            ranked = self.rank(recognition, dictionaries, limits)
        if ranked.reason and (rejecting or ranked.best is None):
            return self._reject(recognition.text, ranked.reason)
        best, rival = ranked.best, ranked.rival
        assert best is not None
        lang = best.dictionary.language
        score = max(0.0, min(1.0, 1.0 - best.distance))
        if rejecting and best.distance > limits["max_distance"]:
            return self._reject(
                best.text, self.not_a_command_reason(best, limits["max_distance"]), best.phrase.text, lang, score
            )
        if rejecting and rival is not None and rival.distance - best.distance < limits["min_margin"]:
            return self._reject(
                best.text,
                f"'{best.text}' is ambiguous: '{best.phrase.text}' ({best.distance:.2f}) vs "
                f"'{rival.phrase.text}' ({rival.distance:.2f})",
                best.phrase.text,
                lang,
                score,
            )
        reason = (_negation_reason(recognition, best) or _lost_number_reason(recognition, best)
                  or ("" if vouched else self._weak_match_reason(recognition, best))
                  or self._transcript_reason(recognition, best, judge_words=not vouched)
                  or self._ear_veto_reason(recognition, best)) if rejecting else ""
        if reason:
            return self._reject(best.text, reason, best.phrase.text, lang, score)
        amount, reason = amounts.judge(recognition.transcript or recognition.text, recognition.extra,
                                       recognition.engine, best.dictionary, best.phrase.action)
        if not reason and rejecting and amount is None:
            reason = self._unwritten_speech_reason(recognition, best)
        if reason:  # a wrong amount is a wrong action
            return self._reject(best.text, reason, best.phrase.text, lang, score)
        return Decision(
            action=best.phrase.action,
            text=best.text,
            phrase=best.phrase.text,
            lang=lang,
            score=score,
            reason=(f"matched alternative #{best.rank + 1} '{best.text}'" if best.rank else "")
                   + (f"{'; ' if best.rank else ''}the domain ear vouched for {vouched} "
                      f"({ear_evidence(recognition.extra).get(vouched, 0.0):.0%})" if vouched else ""),
            matcher=self.name,
            amount=amount,
        )

    def rank(
        self, recognition: Recognition, dictionaries: Sequence[Dictionary], limits: dict[str, float] | None = None,
        waived: frozenset[str] = frozenset(),
    ) -> Ranking:
        """The nearest phrase and the nearest phrase of another class, before any distance threshold.

        ``reason`` is set when the utterance is rejected before matching (nothing heard, engine
        evidence, low confidence); ``best`` is then still filled when there was text to match.
        """
        if not dictionaries:
            raise ValueError("decide() needs at least one dictionary")
        limits = limits or self.thresholds(recognition.engine)
        heard = [
            (rank, h.text, normalize_text(h.text))
            for rank, h in enumerate(recognition.hypotheses[: max(1, int(limits["alternatives"]))])
        ]
        heard = [item for item in heard if item[2]]
        if not heard:
            if recognition.extra.get("out_of_grammar"):
                return Ranking(None, None, "not a command (the recogniser heard speech outside the dictionary)")
            if recognition.extra.get("transcript_cut"):  # the engine scored no phrase: the speech went on
                return Ranking(None, None, _went_on_reason(recognition))
            return Ranking(None, None, "nothing heard")
        # An alternative the engine itself gives little chance is not evidence for an action.
        floor = limits["min_confidence"]
        hyps = recognition.hypotheses
        heard = [item for item in heard
                 if item[0] == 0 or hyps[item[0]].confidence is None or hyps[item[0]].confidence >= floor]
        reason = self._evidence_reason(recognition, waived)
        conf = recognition.best.confidence if recognition.best else None
        if not reason and conf is not None and conf < limits["min_confidence"]:
            text = recognition.text
            reason = f"unsure of '{text}' (confidence {conf:.2f} < {limits['min_confidence']:.2f})"

        self.prepare(dictionaries)
        candidates: list[Candidate] = []
        for rank, text, norm in heard:
            for dictionary in dictionaries:
                key = dictionary.strip_skip_words(norm)
                if not key:
                    continue
                penalty = rank * limits["alt_penalty"]
                for phrase in dictionary.phrases:
                    d = min(1.0, self.distance(key, phrase, dictionary) + penalty)
                    candidates.append(Candidate(d, phrase, dictionary, key, rank, text))
        if not candidates:
            return Ranking(None, None, reason or f"only filler words heard ('{heard[0][1]}')")

        wanted_lang = recognition.lang
        order = {id(c): i for i, c in enumerate(candidates)}
        candidates.sort(
            key=lambda c: (c.distance, c.dictionary.language != wanted_lang, c.rank, order[id(c)])
        )
        best = candidates[0]
        # Ambiguity is judged within the winning text: a lower-ranked alternative of another class is
        # the engine's doubt, already priced by alt_penalty and min_confidence.
        rival = next(
            (c for c in candidates if c.rank == best.rank and c.phrase.action != best.phrase.action), None
        )
        return Ranking(best, rival, reason)

    # -- reasons ---------------------------------------------------------------------------------
    def not_a_command_reason(self, best: Candidate, max_distance: float) -> str:
        return (
            f"'{best.text}' is not a command (nearest '{best.phrase.text}', "
            f"distance {best.distance:.2f} > {max_distance:.2f})"
        )

    def _transcript_reason(self, recognition: Recognition, best: Candidate, judge_words: bool = True) -> str:
        """The engine's own transcript (Whisper scoring mode) must not say more than the command.

        The margin says the phrase is nearly as likely as what Whisper heard; but a sentence that starts
        with a command ("hacia adelante está el río") makes the phrase likely too. A command is said
        with the command's words, so a heard word that sounds like no word of the winning class
        (``word_max_distance``) and is no word of the dictionary at all means other speech; so does
        speech that went on past the engine's free pass (``transcript_cut``: "Go right and then ..."). A heard
        word that is by itself a command of another class ("Go right, go left") means two commands: neither.
        A transcript no longer than the command is left to the margin, unless ``judge_all_words`` is set
        (Spanish: "Ma Yes, Lien" for "me oyes bien" came within the margin of "a la izquierda").
        """
        limits = transcript_limits(recognition.engine, self.thresholds_path, recognition.lang)
        limit = limits.get("word_max_distance")
        if limit is not None and recognition.extra.get("transcript_cut"):
            return _went_on_reason(recognition)
        heard = best.dictionary.strip_skip_words(normalize_text(recognition.transcript))
        heard = amounts.split_amount(heard, best.dictionary.language).command  # the amount is judged apart
        short = len(heard.split()) <= len(best.phrase.match_key.split())
        if limit is None or (short and not limits.get("judge_all_words")):
            return ""  # no more words than the command itself: the margin has judged them
        words = {w for p in best.dictionary.phrases if p.action == best.phrase.action for w in p.match_key.split()}
        # ... and the class's words run together: Whisper writes connected speech as one word ("Desarmamotores",
        # "Aramelecha" for "a la derecha"), as it splits one in two ("de tener" for "detener", below)
        joined_words = {"".join(run) for p in best.dictionary.phrases if p.action == best.phrase.action
                        for run in _runs(p.match_key.split())}
        # a negation word is judged by its own rule (_negation_reason): it refuses any class but a stop, and
        # "Don't stop!" stops
        vocabulary = {w for p in best.dictionary.phrases for w in p.match_key.split()} | set(best.dictionary.negations)
        commands = {p.match_key: p.action for p in best.dictionary.phrases
                    if " " not in p.match_key and p.action != best.phrase.action}
        self.prepare([best.dictionary])

        def distance(word: str) -> float:  # to the nearest word of the class; 0 for any dictionary word
            return 0.0 if word in vocabulary else class_distance(word)

        def class_distance(word: str) -> float:  # to the nearest word of the class only
            return min((self.word_distance(word, w, best.dictionary) for w in words | joined_words), default=1.0)

        def longer(first: str, second: str) -> float:
            """How near ``first`` + ``second`` is to a longer word of the class that ``first`` is the start of, if it is
            nearer that than ``first`` itself ("back with": "backward"; not "right here": "right"), else 1."""
            pair = first + second
            near = min((self.word_distance(pair, w, best.dictionary) for w in words | joined_words
                        if w != first and w.startswith(first)), default=1.0)
            return near if near < self.word_distance(pair, first, best.dictionary) else 1.0

        heard_words = heard.split()
        second = next((w for w in heard_words if w not in words and w in commands), None)
        if second is not None:
            return f"two commands: heard '{recognition.transcript}', and '{second}' is a {commands[second]} command"
        if not judge_words:
            # The domain ear vouched for the class: words before the command's are forgiven (a filler, "y es
            # izquierda"; a lone word Whisper misspelt, "Paggles"), the words after them are judged as ever (an amount
            # it lost: "Arriba, SMEpos" or "su app sm" for "suba trece metros" is no open-ended climb).
            first = next((k for k, w in enumerate(heard_words) if distance(w) <= limit), None)
            if first is not None:
                heard_words = heard_words[first:]
            elif len(heard_words) == 1:
                heard_words = []  # the one word written, misspelt: what the ear vouched for
        i, taken_alone = 0, False  # whether the word before was taken by itself, not as half of a pair
        while i < len(heard_words):
            word = heard_words[i]
            alone = distance(word)
            joined = distance(word + heard_words[i + 1]) if i + 1 < len(heard_words) else 1.0
            # Whisper split one word in two ("de tenerse" for "detenerse", "clock wise" for "clockwise"): the pair
            # sounds nearer a word of the class than either half; not a stray word before a word of the class
            # ("Y la la izquierda" for "gire a la izquierda": "yla" is near "la", and "la" alone is nearer); a pair that
            # is itself a word of the class is that word, though its second half is a word too ("counter clockwise")
            pair = word + heard_words[i + 1] if i + 1 < len(heard_words) else ""
            if joined <= limit and joined < alone and (joined < distance(heard_words[i + 1]) or pair in words):
                i, taken_alone = i + 2, False
            elif alone <= limit:
                i, taken_alone = i + 1, True
            elif taken_alone and heard_words[i - 1] in words and longer(heard_words[i - 1], word) <= limit:
                # ... or wrote its first half as a word of the class ("Go back with 10 meters" for "go backward ten
                # meters"): the second half belongs to the word before it
                i, taken_alone = i + 1, False
            else:
                return (f"not a command: heard '{recognition.transcript}', and '{word}' is in no "
                        f"{best.phrase.action} phrase")
        return ""

    def _ear_vouches(self, recognition: Recognition, dictionaries: Sequence[Dictionary]) -> tuple[str, Recognition]:
        """The class the domain ear vouches for ("" for none), and the recognition to decide on.

        The ear (gcs_voice/asr/ear.py) is trained here on our commands in noise. It vouches for the class of the
        phrase the engine ranked first when it gives that class at least ``vouch``; or, when it gives one class at
        least ``alone``, for that class, put first among the engine's phrases (its best-scored phrase of the class,
        else the class's phrase nearest to what the engine wrote), unless what the engine wrote says no: nothing
        written, a not-command ("Yes."), more words than any phrase of the class and a filler, or speech that went
        on. A vouched class is not refused for the rules that noise and accents break (the score's margin and class
        gap, the transcript's sounds and words: "y es izquierda" for "izquierda"); negations, numbers, two commands
        and the amounts are still judged."""
        ear = ear_evidence(recognition.extra)
        limits = ear_limits(recognition.engine, self.thresholds_path, recognition.lang)
        if not ear:
            return "", recognition
        phrases = {p.text: (p, d) for d in dictionaries for p in d.phrases}
        heard = normalize_text(recognition.transcript)
        if heard and _says_no_class(heard, dictionaries):
            return "", recognition  # "Go": words every side says; the ear may not pick the side for Whisper
        first = recognition.hypotheses[0].text if recognition.hypotheses else ""
        action = phrases[first][0].action if first in phrases else ""
        if action and ear.get(action, 0.0) >= limits.get("vouch", math.inf):
            return action, recognition
        top = max(ear, key=ear.__getitem__)
        if (top == EAR_NONE or ear[top] < limits.get("alone", math.inf) or not heard
                or recognition.extra.get("transcript_cut")):
            return "", recognition
        of_class = [(p, d) for p, d in phrases.values() if p.action == top]
        if not of_class or any(d.strip_skip_words(heard) in d.not_commands for d in dictionaries):
            return "", recognition
        if len(heard.split()) > max(len(p.match_key.split()) for p, _ in of_class) + 1:
            return "", recognition
        chosen = next((h for h in recognition.hypotheses if h.text in phrases and phrases[h.text][0].action == top),
                      None)
        if chosen is None:
            self.prepare(dictionaries)
            phrase, _ = min(of_class, key=lambda pd: self.distance(pd[1].strip_skip_words(heard) or heard, pd[0], pd[1]))
            chosen = Hypothesis(phrase.text, None, None)
        rest = tuple(h for h in recognition.hypotheses if h is not chosen)
        return top, replace(recognition, hypotheses=(chosen, *rest))

    def _ear_veto_reason(self, recognition: Recognition, best: Candidate) -> str:
        """An action the domain ear gives less than ``veto`` is not taken: it heard something else. Never a stop:
        stopping is always safe, and a stop refused is the one mistake a pilot cannot afford."""
        ear = ear_evidence(recognition.extra)
        limit = ear_limits(recognition.engine, self.thresholds_path, recognition.lang).get("veto")
        if (not ear or limit is None or best.phrase.action == ALWAYS_SAFE
                or ear.get(best.phrase.action, 0.0) >= limit):
            return ""
        top = max(ear, key=ear.__getitem__)
        said = "other speech" if top == EAR_NONE else top
        return (f"unsure: heard '{recognition.transcript or best.text}' as '{best.phrase.text}', but the domain ear "
                f"heard {said} ({ear[top]:.0%}; {best.phrase.action} {ear.get(best.phrase.action, 0.0):.0%})")

    def _weak_match_reason(self, recognition: Recognition, best: Candidate) -> str:
        """What the engine itself heard must share the sounds of the phrase it is matched to (``min_shared``).

        A score near that of the engine's own transcript (the margin) says the phrase is about as likely as
        what was heard, not that it was said: one speaker's "adelante", heard "A" and "Ailan", came within the
        margin and the class gap of "a la derecha" and flew right. A transcript that has less than
        ``min_shared`` of the phrase's sounds in it, in order (:meth:`shared`), is not that phrase, however
        near its score; nothing heard at all shares none.
        """
        limit = transcript_limits(recognition.engine, self.thresholds_path, recognition.lang).get("min_shared")
        if limit is None or not recognition.hypotheses:
            return ""
        heard = best.dictionary.strip_skip_words(normalize_text(recognition.transcript))
        self.prepare([best.dictionary])
        shared = self.shared(heard, best.phrase.match_key, best.dictionary) if heard else 0.0
        if shared >= limit:
            return ""
        return (f"not a command: heard '{recognition.transcript}', which has {shared:.0%} of the sounds of "
                f"'{best.phrase.text}' (< {limit:.0%})")

    def _unwritten_speech_reason(self, recognition: Recognition, best: Candidate) -> str:
        """A motion that could take an amount is not flown open-ended over speech the engine did not write.

        Real "right" and a real "eight" after it came out of Whisper as "Right.": flown, that is a motion that
        runs until "stop" where the pilot asked for 8 m. Speech after the words Whisper wrote (where it aligned
        them: ``speech_after_s``, gcs_voice/audio/voiced.py) longer than ``max_speech_after_s`` means words it
        did not write; the motion is not flown on the rest.
        """
        if best.phrase.action not in amounts.DISTANCE_MOTIONS | amounts.TURNS:
            return ""
        limit = transcript_limits(recognition.engine, self.thresholds_path, recognition.lang).get("max_speech_after_s")
        after = recognition.extra.get("speech_after_s")
        if limit is None or after is None or after <= limit:
            return ""
        return (f"unsure: heard '{recognition.transcript or recognition.text}', and {after:.1f} s more speech "
                f"after it that was not written (a distance or an angle?): say it again")

    def shared(self, heard: str, phrase: str, dictionary: Dictionary) -> float:
        """The fraction of ``phrase`` found in ``heard``, in order (characters; the phonetic matcher: sounds)."""
        return LCSseq.similarity(heard, phrase) / len(phrase) if phrase else 1.0

    def word_distance(self, a: str, b: str, dictionary: Dictionary) -> float:
        """Normalised distance between two single words (characters; the phonetic matcher: sounds)."""
        return Levenshtein.normalized_distance(a, b)

    def _speech_went_on(self, recognition: Recognition) -> bool:
        """Whether the engine heard speech go on past a command's words: Whisper's free pass ran out of room
        (``transcript_cut``), or speech went on after the command it placed (``speech_beyond_s`` over its limit)."""
        if recognition.extra.get("transcript_cut"):
            return True
        limit = evidence_limits(recognition.engine, self.thresholds_path, recognition.lang).get("max_speech_beyond_s")
        beyond = recognition.extra.get("speech_beyond_s")
        return limit is not None and beyond is not None and beyond > limit

    def _evidence_reason(self, recognition: Recognition, waived: frozenset[str] = frozenset()) -> str:
        for key, limit in evidence_limits(recognition.engine, self.thresholds_path, recognition.lang).items():
            kind, _, name = key.partition("_")
            if name in waived:
                continue
            value = recognition.extra.get(name)
            if value is None:
                continue
            if kind == "max" and value > limit:
                if name == "speech_beyond_s":  # the engine placed a command in longer speech
                    return (f"not a command: heard '{recognition.text}', and the speech went on "
                            f"({value:.1f} s more than the command)")
                return f"'{recognition.text}' sounded unsure ({name} {value:.2f} > {limit:.2f})"
            if kind == "min" and value < limit:
                if name == "class_gap":  # the phrase was heard, but another class (or a not-command) nearly as well
                    return (f"unsure: heard '{recognition.transcript or recognition.text}', as '{recognition.text}' "
                            f"but nearly as much as something else ({name} {value:.2f} < {limit:.2f})")
                if name == "free_logprob":  # the engine could not write down what it heard: noise, most often
                    return (f"nothing clear: heard '{recognition.transcript or recognition.text}' too unsurely to "
                            f"be anything ({name} {value:.2f} < {limit:.2f})")
                if recognition.transcript:  # the engine heard something else than the phrase
                    return (f"not a command: heard '{recognition.transcript}', not '{recognition.text}' "
                            f"({name} {value:.2f} < {limit:.2f})")
                return f"'{recognition.text}' sounded unsure ({name} {value:.2f} < {limit:.2f})"
        return ""

    def _reject(
        self, text: str, reason: str, phrase: str | None = None, lang: str | None = None, score: float = 0.0
    ) -> Decision:
        return Decision(action=None, text=text, phrase=phrase, lang=lang, score=score, reason=reason,
                        matcher=self.name)


#: the engine evidence a class vouched for by the domain ear is not refused on (Recognition.extra names)
EAR_WAIVES = frozenset({"margin", "class_gap", "free_logprob"})

#: the one class a negation does not refuse: "don't stop" stopping costs a pause, a refused stop a wall
ALWAYS_SAFE = "stop"


def _says_no_class(heard: str, dictionaries: Sequence[Dictionary]) -> bool:
    """Whether every word written is a word of phrases of several classes ("go", "move", "turn", "a la"), so that
    what was written names no class of its own."""
    for dictionary in dictionaries:
        words = dictionary.strip_skip_words(heard).split()
        classes: dict[str, set[str]] = {}
        for phrase in dictionary.phrases:
            for word in phrase.match_key.split():
                classes.setdefault(word, set()).add(phrase.action)
        if words and all(len(classes.get(w, ())) > 1 for w in words):
            return True
    return False


def _runs(words: Sequence[str]) -> list[tuple[str, ...]]:
    """Every run of two or more consecutive words of a phrase that ends on its last word (the one that says which
    class: "la derecha", not "hacia la", which every side has)."""
    return [tuple(words[i:]) for i in range(len(words) - 1)]


def _lost_number_reason(recognition: Recognition, best: Candidate) -> str:
    """A number heard alone is no command, however well a phrase scores on the audio: Whisper wrote "7" for a
    real "down" and a real "seven" after it, and the scores flew down open-ended; a real "four" said to
    someone else, heard "4", flew forward in a stream (issue 33, issue 30). Nor is a command that ends on the
    word before a height ("Down to", "baja a"): the number after it was lost."""
    if not recognition.transcript:
        return ""
    heard = best.dictionary.strip_skip_words(normalize_text(recognition.transcript))
    if amounts.split_amount(heard, best.dictionary.language).amount_alone:
        return f"heard only a number ('{recognition.transcript}'): say the command with it"
    vocab = amounts.vocabulary(best.dictionary.language)
    words = heard.split()
    if (vocab is not None and len(words) > 1 and words[-1] in vocab.to
            and best.phrase.match_key.split()[-1:] != words[-1:]):
        # "Down to" for a real "down" and a real "two": the height word with no number after it, the number lost
        return f"heard '{recognition.transcript}': '{words[-1]}' what? Say it again with the number"
    return ""


def _negation_reason(recognition: Recognition, best: Candidate) -> str:
    """Speech that says a command with a negation ("Don't go left", "not up") is a refusal, not that command.

    The score of "go left" in "Don't go left" can come near Whisper's own transcript (the margin), and a
    short transcript is otherwise left to the margin alone; one negation word of the dictionary anywhere in
    what was heard refuses it instead. A stop is never refused for it (stopping is always safe).
    """
    if best.phrase.action == ALWAYS_SAFE or not best.dictionary.negations:
        return ""
    said = recognition.transcript or best.text
    word = next((w for w in normalize_text(said).split() if w in best.dictionary.negations), None)
    return f"not a command: heard '{said}', and '{word}' says not to" if word else ""


def _went_on_reason(recognition: Recognition) -> str:
    """Why speech that went on past the engine's free pass is no action."""
    return f"not a command: heard '{recognition.transcript}…', and the speech went on"
