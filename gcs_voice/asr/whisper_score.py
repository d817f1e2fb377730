"""Whisper as a closed-set judge: is *this* dictionary phrase what was said, compared with what Whisper hears?

For one utterance, on ONE short encoder pass (the trimmed utterance plus a little silence, not a 30 s
window):

1. Whisper transcribes freely, greedily, a few tokens at most (its own opinion of the audio);
2. every dictionary phrase (written as Whisper writes it, " Go up." and " go up.") is ranked by what
   that greedy pass already knows of it (the log-probabilities of its tokens along the greedy path up to
   where it leaves the path; forms that tie, having left it at the same token, by how near their words
   are to the transcript); only the ``top_k`` most promising are scored, since each costs a decoder
   pass over the encoder output;
3. those phrases AND the free transcript are teacher-forced in ONE batched decoder call
   (CTranslate2 ``Whisper.align``), so all are scored by the same decoder on the same audio; unless
   the greedy pass ran out of tokens on words that were no loop ("Can I get a medium roast with..."):
   that speech said more than any command, and no phrase is scored.

Phrases are ranked by their mean token log-probability (``rank_by = "mean"``; ``"sum"``, the probability
Whisper gives the whole phrase, ranks the right class first more often on real speech but made no better
decisions once its thresholds were re-chosen: docs/bench/real.md). The evidence for a decision is the
**margin**: the best phrase's mean log-probability per token minus that of Whisper's own transcript
(means, so a transcript longer than a command is not favoured by its length). It is 0 when Whisper
itself heard a dictionary phrase, slightly negative when a phrase is nearly what it heard, and far below when the speech was something else ("muestra la
memoria" heard perfectly does not become "derecha"). One threshold on it (``min_margin`` in
``gcs_voice/understanding/thresholds.toml``) was chosen on real speakers (``python -m tools.speech.bench_real tune``).

An amount after the command ("Go forward 3 meters.", read by ``gcs_voice.domain.amounts``) is weighed against
the amounts that sound like it, in the transcript as Whisper wrote it. When the words before it are no phrase
("defend 13 meters." for "descend thirteen metres"), each phrase is scored with Whisper's own amount after it
and judged on its words and the first token after them, as a plain command on its words and its period.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from rapidfuzz import fuzz

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.domain.dictionary import Dictionary, Phrase
from gcs_voice.domain.text import normalize_text
from gcs_voice.domain.amounts import alike, ends_in_number, number_words, split_amount, vocabulary

__all__ = ["PhraseForms", "PhraseScores", "canonical_tokens", "phrase_forms", "trim_silence", "first_unit_length",
           "generation_length", "only_repeats", "preselect", "score_utterance"]

_SPACE = "\u0120"  # byte-level BPE's space marker ("Ġ")
#: the class of a dictionary's ``not_commands``: scored like phrases, never acted on
NOT_A_COMMAND = ""


def canonical_tokens(tokenizer, text: str) -> list[int]:
    """Token ids of ``text`` as Whisper itself would emit them.

    faster-whisper-base's ``tokenizer.json`` lacks the BPE merge of a space with "t", so " to" and
    " the" encode as [" ", "to"] and [" ", "the"]: token pairs the model never produces, scored far
    too low. A lone space token is joined to the next token whenever the joined token exists.
    """
    hf = tokenizer.tokenizer
    ids = list(tokenizer.encode(text))
    space = hf.token_to_id(_SPACE)
    out: list[int] = []
    i = 0
    while i < len(ids):
        if ids[i] == space and i + 1 < len(ids):
            joined = hf.token_to_id(_SPACE + hf.id_to_token(ids[i + 1]))
            if joined is not None:
                out.append(joined)
                i += 2
                continue
        out.append(ids[i])
        i += 1
    return out


@dataclass(frozen=True)
class PhraseForms:
    """Every phrase of one dictionary in the written forms Whisper uses, tokenised once per language.

    A phrase is written " Go up." (capital, final period: ``align`` masks end-of-text, and the period
    is what stops " Go." from beating " Go up.") and " go up." (Whisper often writes a lone command
    word in lower case); a phrase scores as its best form.
    """

    dictionary: Dictionary
    phrases: tuple[Phrase, ...]        # one entry per form; a not-command has action NOT_A_COMMAND
    tokens: tuple[tuple[int, ...], ...]


def phrase_forms(tokenizer, dictionary: Dictionary) -> PhraseForms:
    """The forms of every phrase of ``dictionary`` (see :class:`PhraseForms`)."""
    phrases: list[Phrase] = []
    tokens: list[tuple[int, ...]] = []
    rivals = [Phrase(text, text, NOT_A_COMMAND) for text in dictionary.not_commands]
    for phrase in (*dictionary.phrases, *rivals):
        written = {phrase.text[:1].upper() + phrase.text[1:], phrase.text[:1].lower() + phrase.text[1:]}
        for text in sorted(written):
            phrases.append(phrase)
            tokens.append(tuple(canonical_tokens(tokenizer, " " + text + ".")))
    return PhraseForms(dictionary, tuple(phrases), tuple(tokens))


def _frame_power_db(audio: np.ndarray, frame: int = 400, hop: int = 160) -> np.ndarray:
    if audio.size < frame:
        audio = np.pad(audio, (0, frame - audio.size))
    n = 1 + (audio.size - frame) // hop
    idx = np.arange(frame)[None, :] + hop * np.arange(n)[:, None]
    return 10.0 * np.log10(np.mean(audio[idx].astype(np.float64) ** 2, axis=1) + 1e-12)


def trim_silence(audio: np.ndarray, rel_db: float = 35.0, floor_db: float = -60.0, margin_s: float = 0.1) -> np.ndarray:
    """Cut the leading and trailing audio that is ``rel_db`` below the loudest 25 ms frame (or under ``floor_db``).

    Keeps ``margin_s`` either side of the first and last loud frame. On noisy audio it keeps almost
    everything, which is safe: it only saves encoder time where there is silence to cut.
    """
    db = _frame_power_db(audio)
    loud = np.flatnonzero(db > max(float(db.max()) - rel_db, floor_db))
    if loud.size == 0:
        return audio
    margin = int(margin_s * SAMPLE_RATE)
    return audio[max(0, loud[0] * 160 - margin): min(audio.size, loud[-1] * 160 + 400 + margin)]


def _word(piece: str) -> str:
    """A token's text as a bare lower-case word ("" for punctuation)."""
    return "".join(ch for ch in piece.lower() if ch.isalnum())


def first_unit_length(pieces: Sequence[str]) -> int:
    """How many leading tokens of a free transcript form its first unit, given each token's text.

    On a short window Whisper loops ("Up Up Up Up", "Right, right, right"); the repeats get
    near-certain probabilities and would inflate the transcript's mean. The unit ends before the
    first token whose word repeats the first word; trailing punctuation is dropped.
    """
    words = [_word(p) for p in pieces]
    n = len(words)
    first = next((w for w in words if w), "")
    seen = False
    for i, w in enumerate(words):
        if w and w == first:
            if seen:
                n = i
                break
            seen = True
    while n > 1 and not words[n - 1]:
        n -= 1
    return n


def only_repeats(pieces: Sequence[str], unit: int) -> bool:
    """Whether every word after the first ``unit`` tokens repeats a word of that unit ("Up, up, up", not
    "Turn left, turn left and take a picture"): a loop says nothing new, anything else says more. The
    last word may be the start of one ("Desarmas los motores. Des": the pass ran out inside the loop).
    With no word after the unit there is no loop ("Can I get a medium": the words simply went on)."""
    words = [w for w in map(_word, pieces[unit:]) if w]
    if not words:
        return False
    said = {w for w in map(_word, pieces[:unit]) if w}
    if words[-1] not in said and any(w.startswith(words[-1]) for w in said):
        words = words[:-1]
    return all(w in said for w in words)


@dataclass(frozen=True)
class PhraseScores:
    """One utterance judged against one dictionary.

    ``ranked``: (phrase, rank score: its log-probability, summed or per token as ``rank_by`` says) for
    the teacher-forced phrases, best first (a phrase appears once, with its best form); ``best_mean``:
    the best phrase's mean token log-probability; ``free_text`` / ``free_logprob``: Whisper's own
    transcript and its teacher-forced mean log-probability (-inf when it wrote nothing);
    ``margin``: best phrase minus free transcript, per token; ``class_gap``: best phrase minus the best
    phrase of another class (or not-command), in rank scores. ``heard_text``: the whole greedy transcript,
    or its first unit when the rest only loops over it (``free_text`` is always that first unit); ``cut``:
    the greedy pass ran out of tokens on speech that was not a loop of its first unit, so the speech went on
    past anything a command says (then no phrase is scored: ``ranked`` is empty, ``free_logprob`` -inf).
    """

    ranked: tuple[tuple[Phrase, float], ...]
    free_text: str
    free_logprob: float
    no_speech_prob: float
    #: the best not-command's rank score (-inf when none was scored): a rival class of every phrase
    not_command: float = -math.inf
    #: the best phrase's mean token log-probability (None: its rank score is that mean)
    best_mean: float | None = None
    heard_text: str = ""
    cut: bool = False
    #: an amount said after the command ("Go forward three meters."): how much more likely (summed token
    #: log-probability) the transcript is with the amount heard than with the likeliest amount that sounds
    #: alike ("fifty" for "fifteen"; +inf when none does), and that rival amount (0: none; -N: N with the height
    #: word put in or taken out, "a ocho metros" against "ocho metros"). None: no amount.
    amount_gap: float | None = None
    amount_rival: int = 0
    #: where Whisper's own transcript was said in the audio it scored, (start, end) seconds (its alignment)
    spoken_s: tuple[float, float] | None = None

    @property
    def best(self) -> tuple[Phrase, float] | None:
        return self.ranked[0] if self.ranked else None

    @property
    def best_per_token(self) -> float:
        """The best phrase's mean token log-probability (-inf when none was scored)."""
        if not self.ranked:
            return -math.inf
        return self.ranked[0][1] if self.best_mean is None else self.best_mean

    @property
    def margin(self) -> float:
        if not self.ranked:
            return -math.inf
        return self.best_per_token - self.free_logprob if math.isfinite(self.free_logprob) else 0.0

    @property
    def class_gap(self) -> float:
        if not self.ranked:
            return 0.0
        winner, best = self.ranked[0][0].action, self.ranked[0][1]
        rival = max(max((lp for p, lp in self.ranked if p.action != winner), default=-math.inf), self.not_command)
        return math.inf if rival == -math.inf else best - rival


def _log_softmax(logits: np.ndarray) -> np.ndarray:
    """Log-probabilities from one step's logits (a vectorised log-sum-exp: ``np.logaddexp.reduce`` is a
    sequential loop over the 51,865 entries of Whisper's vocabulary)."""
    top = float(np.max(logits))
    return logits - (top + math.log(float(np.sum(np.exp(logits - top)))))


def _mean(logprobs: np.ndarray) -> float:
    return float(np.mean(logprobs)) if logprobs.size else -math.inf


#: how a phrase's token log-probabilities make its rank score (``rank_by``)
RANK_BY = {"sum": lambda lp: float(np.sum(lp)) if lp.size else -math.inf, "mean": lambda lp: _mean(lp)}


def _text_nearness(forms: PhraseForms, heard: str) -> list[float]:
    """How near each form's words are to the greedy transcript (rapidfuzz ratio, 0-100): a tie-break only."""
    heard = normalize_text(heard, fold=False)
    return [fuzz.ratio(normalize_text(phrase.text, fold=False), heard) for phrase in forms.phrases]


def preselect(forms: PhraseForms, greedy: Sequence[int], steps: Sequence[np.ndarray], heard: str,
              top_k: int) -> list[int]:
    """The indices of the ``top_k`` forms worth teacher-forcing, best first.

    What the greedy pass already knows of each form ranks it: the log-probs (``steps``, one log-softmax
    per greedy step) of its tokens along the greedy path up to and including the first token where it
    leaves the path, averaged. Forms that leave the path at the same token tie exactly ("muévete a la
    derecha" and "muévete a la izquierda" when the transcript already differs at "muévete"), and
    dictionary order would then decide which class is scored at all; so ties go to the form whose words
    are nearest what Whisper wrote (``heard``: "¡Wenete a la izquier"), then to dictionary order (same
    audio, same phrases scored). A command whose words are exactly what Whisper wrote is always among them,
    and so is at least one command.
    """
    known_mean = np.full(len(forms.tokens), -np.inf)
    for i, toks in enumerate(forms.tokens):
        known: list[float] = []
        for t, tok in enumerate(toks):
            if t >= len(steps):
                break
            known.append(float(steps[t][tok]))
            if t >= len(greedy) or tok != greedy[t]:
                break
        if known:
            known_mean[i] = sum(known) / len(known)
    nearness = _text_nearness(forms, heard)
    order = sorted(range(len(forms.tokens)), key=lambda i: (-known_mean[i], -nearness[i], i))
    chosen = order[:max(1, top_k)]
    # A command Whisper wrote word for word is always scored: when its tokens differ from the greedy
    # pass's ("Desarma los motores" written with other pieces), the path evidence ranks it low, and
    # with few forms scored it was left out (espeak-ng "desarma los motores", python -m tools.speech.bench_spanish).
    said = normalize_text(heard)
    exact = [i for i in order
             if forms.phrases[i].action != NOT_A_COMMAND and normalize_text(forms.phrases[i].text) == said]
    if exact and not set(exact) & set(chosen):
        chosen[-1] = exact[0]
    # At least one command is scored: when the greedy pass heard something near the not-commands ("Um",
    # "Oh." for "up"), all the forms chosen were not-commands, no phrase was judged and the utterance read
    # as nothing heard. The not-commands scored beside it still stand as its rivals (the class gap).
    if all(forms.phrases[i].action == NOT_A_COMMAND for i in chosen):
        command = next((i for i in order if forms.phrases[i].action != NOT_A_COMMAND), None)
        if command is not None:
            chosen[-1] = command
    # At least one rival is scored: when every form chosen says one class ("Black." for a "left" said in a
    # kitchen: "back", "go back", "move back", "backwards"), no other class was judged, the class gap read as
    # infinite and the weakest evidence acted (python -m tools.listen.bench_stream --room --split dev: go_back for
    # "left", twice). The best-ranked form of another class (or a not-command) takes the last place that is
    # not the command Whisper wrote.
    classes = {forms.phrases[i].action for i in chosen}
    if len(classes) == 1 and len(chosen) > 1:
        rival = next((i for i in order if forms.phrases[i].action not in classes), None)
        if rival is not None:
            # the last place, unless it holds the command Whisper wrote word for word: that one stays
            chosen[-2 if exact and chosen[-1] == exact[0] else -1] = rival
    return chosen


def generation_length(prompt_length: int, new_tokens: int) -> int:
    """The ``max_length`` with which CTranslate2's ``Whisper.generate`` may write ``new_tokens`` after a prompt.

    It does not allow ``max_length - prompt_length`` new tokens but min(max_length // 2, max_length -
    prompt_length + 1) (whisper.cc, CTranslate2 4.x: half of the text context, Whisper's own sampling
    limit): asked for a 4-token prompt plus 8, it stopped after 6, so the free pass was shorter than meant
    and never looked cut. A later version that allows more is cut back to ``new_tokens`` by the caller.
    """
    return max(2 * new_tokens, new_tokens + prompt_length - 1)


#: tokens the free pass may write beyond a command for its amount ("one hundred and eighty degrees")
AMOUNT_TOKENS = 8


def amount_transcript(forms: PhraseForms, text: str, loose: bool = False):
    """The split of a free transcript that is a dictionary command followed by an amount, else None.

    ``loose``: also when the words before a clear amount are no phrase of the dictionary ("Descent 13
    meters."): the phrases are then scored with that amount after them (:func:`_amount_start`)."""
    lang = forms.dictionary.language
    if vocabulary(lang) is None:
        return None
    split = split_amount(forms.dictionary.strip_skip_words(normalize_text(text)), lang)
    if not split.words:
        return None
    if split.command in forms.dictionary.by_key:
        return split
    if loose and split.amount is not None and split.command and not split.amount_alone:
        return split
    return None


def _to_last_word(tokenizer, tokens: Sequence[int]) -> list[int]:
    """``tokens`` without the punctuation after their last word."""
    out = list(tokens)
    while out and not _word(tokenizer.decode(out[-1:])):
        out.pop()
    return out


def _amount_start(tokenizer, tokens: Sequence[int], said: str) -> int | None:
    """Where the amount begins among Whisper's own ``tokens`` (its transcript without the final period): the
    last word boundary from which the rest reads as ``said`` (the amount's words); None when none does."""
    target = said.replace(" ", "")
    for j in range(len(tokens) - 1, 0, -1):
        if not tokenizer.decode(tokens[j:j + 1]).startswith(" "):
            continue
        if normalize_text(tokenizer.decode(tokens[j:])).replace(" ", "") == target:
            return j
    return None


def _amount_rivals(tokenizer, text: str, split, lang: str) -> list[tuple[int, list[int] | None]]:
    """The transcript with its amount replaced by each amount that sounds alike, as Whisper would write it
    (None: the heard number could not be found in the transcript to replace, so that rival cannot be weighed);
    and with the height word ("to", "a") taken out or put in, as rival -value: "baja a ocho metros" (to 8 m)
    and "baja ocho metros" (8 m down) differ by one short word."""
    if split.amount is None:
        return []
    value, rivals = split.amount.value, []
    digits = any(ch.isdigit() for ch in text)
    heard = str(value) if digits and str(value) in text else None
    if heard is None:  # the words of the heard number as written, case kept ("forty five", "100 and 35")
        words = normalize_text(text, fold=False).split()
        spoken = split.number.split() or number_words(value, lang).split()
        for i in range(len(words) - len(spoken) + 1):
            if [normalize_text(w) for w in words[i:i + len(spoken)]] == spoken:
                heard = " ".join(text.split()[i:i + len(spoken)])
                break
    if heard is None or heard not in text:
        return [(other, None) for other in (*alike(value, lang), -value)]
    before, _, after = text.rpartition(heard)

    def written(head: str, number: str) -> list[int]:
        if heard[:1].isupper():
            number = number[:1].upper() + number[1:]
        return list(canonical_tokens(tokenizer, " " + (head + number + after).strip()))

    def as_heard(other: int) -> str:
        """``other`` written as the heard number was: "100 and 18" against a heard "100 and 80"."""
        parts = heard.split()
        if digits and len(parts) > 1 and parts[-1].isdigit() and other // 100 == value // 100 and other % 100:
            return " ".join([*parts[:-1], str(other % 100)])
        return str(other) if digits else number_words(other, lang)

    for other in alike(value, lang):
        rivals.append((other, written(before, as_heard(other))))
    to_words = sorted(vocabulary(lang).to)
    head = before.rstrip()
    last = head.split()[-1] if head.split() else ""
    if split.amount.height and normalize_text(last) in to_words:   # "to 5 meters" against "5 meters"
        rivals.append((-value, written(head[: len(head) - len(last)], heard)))
    elif not split.amount.height and to_words:                      # "8 metros" against "a 8 metros"
        rivals.append((-value, written(f"{head} {to_words[0]} ", heard)))
    return rivals


def _aligned_span(result, words: int) -> tuple[float, float] | None:
    """(start, end) seconds of the first ``words`` tokens of an aligned sequence (CTranslate2's ``align``:
    pairs of token index and encoder frame, 20 ms each): where Whisper's own transcript was said."""
    frames = [t for i, t in getattr(result, "alignments", []) if i < words]
    if not frames:
        return None
    return min(frames) * 0.02, (max(frames) + 1) * 0.02


def _free_pass(model, tokenizer, forms: PhraseForms, encoder_output, prompt: list[int], max_new_tokens: int,
               room: int) -> tuple[list[int], list, float]:
    """Whisper's greedy transcript: its tokens, the logits of each step and the no-speech probability.

    An amount may take the transcript up to ``room`` tokens, but what Whisper writes after the first
    ``max_new_tokens`` changes the judgement only when its first sentence holds an amount, or has not ended
    there and has begun one (:func:`_may_say_more`); otherwise the pass stops there. A loop on a short
    command ("Left. Left. Left. ...", "Up Up Up ...", "Move up 5 meters. Move up 5 ...") ran on to ``room``:
    a 180 ms pass for a 50 ms one, the tail of the decision time. Continued, it is one greedy path: Whisper
    is given what it wrote as a prefix, and the tokens and logits are those of one pass to ``room``, bit for
    bit (``suppress_blank`` acts on the first token generated, which one pass did not suppress there).
    """
    options = dict(beam_size=1, return_scores=True, return_no_speech_prob=True, return_logits_vocab=True,
                   suppress_tokens=[-1])
    first = model.generate(encoder_output, [prompt], max_length=generation_length(len(prompt), max_new_tokens),
                           suppress_blank=True, **options)[0]
    tokens = list(first.sequences_ids[0])[:max_new_tokens]
    logits = list(first.logits[0])
    if room > max_new_tokens and len(tokens) == max_new_tokens and _may_say_more(tokenizer, forms, tokens):
        more = model.generate(encoder_output, [prompt + tokens], max_length=generation_length(len(prompt), room),
                              suppress_blank=False, **options)[0]
        logits = logits[:len(tokens)] + list(more.logits[0])[len(tokens):]
        tokens = list(more.sequences_ids[0])[:room]
    return tokens, logits, float(first.no_speech_prob)


def _first_sentence_end(pieces: Sequence[str]) -> int | None:
    """How many leading tokens make the first sentence of a transcript (None: it has not ended)."""
    return next((i + 1 for i, piece in enumerate(pieces) if piece.strip() in (".", "!", "?")), None)


def _may_say_more(tokenizer, forms: PhraseForms, tokens: Sequence[int]) -> bool:
    """Whether what Whisper writes after ``tokens`` could change the judgement, which reads an amount in the
    first sentence only. It could when that sentence holds an amount and has ended, with no loop of it begun
    after it (a loop is taken to run on: Whisper's loops do, and the sentence is then read alone), or has not
    ended, is no loop, and ends in a number being said ("Turn left one hundred and"). An amount that begins
    after ``tokens`` (filler words before a command) is not waited for: the speech went on, and nothing is
    done."""
    said = [tokenizer.decode([t]) for t in tokens]
    end = _first_sentence_end(said)
    if end is not None:
        holds_amount = amount_transcript(forms, tokenizer.decode(tokens[:end]), loose=True) is not None
        return holds_amount and not only_repeats(said, end)
    unit = first_unit_length(said)
    if only_repeats(said, unit):  # "7 7 7 7", "A A A A": a loop is read on its first unit
        return amount_transcript(forms, tokenizer.decode(tokens[:unit]), loose=True) is not None
    heard = forms.dictionary.strip_skip_words(normalize_text(tokenizer.decode(tokens)))
    return ends_in_number(heard, forms.dictionary.language)


def score_utterance(model, tokenizer, forms: PhraseForms, encoder_output, num_frames: int,
                    extra_tokens: int = 3, top_k: int = 8, rank_by: str = "mean",
                    context: str = "", between_stages: Callable[[], None] | None = None) -> PhraseScores:
    """Judge one encoded utterance against one dictionary (see the module docstring).

    ``model`` is the ``ctranslate2.models.Whisper``; ``num_frames`` the mel frames that were encoded;
    ``rank_by`` "sum" or "mean" (see the module docstring); ``context``, when given, is the text Whisper is
    told came before (its "previous text" prompt), for the free pass and the phrases alike;
    ``between_stages`` is called after the free pass, before the phrases are scored (it may raise to give up).
    Greedy decoding and the fixed batch keep it deterministic: the same audio gives the same scores.
    """
    import ctranslate2

    prompt = list(tokenizer.sot_sequence) + [tokenizer.no_timestamps]
    if context.strip():
        prompt = [tokenizer.sot_prev] + tokenizer.encode(" " + context.strip()) + prompt
    # The free pass has room for the longest phrase (or not-command) of the dictionary, its period and
    # ``extra_tokens`` more ("Okay, go to the right."): a transcript that runs out of it said more than a command.
    max_new_tokens = max((len(t) for t in forms.tokens), default=0) + extra_tokens
    # A command with an amount may run past that; anything else is judged on the first max_new_tokens only,
    # exactly as without amounts (Whisper's greedy path does not depend on how far it may go).
    room = max_new_tokens + (AMOUNT_TOKENS if vocabulary(forms.dictionary.language) is not None else 0)
    whole, logits, no_speech_prob = _free_pass(model, tokenizer, forms, encoder_output, prompt, max_new_tokens, room)
    greedy = whole[:max_new_tokens]
    amount = None
    amount_at = None  # where the amount begins in Whisper's tokens, when the words before it are no phrase
    if room > max_new_tokens:
        # its first sentence, when what follows only loops over it ("Turn left 45 degrees. Turn left 45 ...")
        # (_may_say_more foresees this reading to stop the free pass early: change the two together)
        said = [tokenizer.decode([t]) for t in whole]
        end = _first_sentence_end(said) or len(whole)
        if (end < len(whole) and only_repeats(said, end)) or len(whole) < room:
            amount = amount_transcript(forms, tokenizer.decode(whole[:end]), loose=True)
            if amount is not None and amount.command not in forms.dictionary.by_key:
                amount_at = _amount_start(tokenizer, _to_last_word(tokenizer, whole[:end]), amount.words)
                if amount_at is None:
                    amount = None   # the amount is not where Whisper's tokens can show it: judged as without one
            if amount is not None:
                greedy, max_new_tokens = whole[:end], room
    steps = [_log_softmax(np.asarray(lg, np.float64).ravel()) for lg in logits[:max_new_tokens]]
    pieces = [tokenizer.decode([t]) for t in greedy]
    if between_stages is not None:
        between_stages()
    # Whisper's own transcript, written like the phrases: its first unit (no loop), then a period.
    unit = greedy[:first_unit_length(pieces)] if greedy else []
    if amount is not None:  # the whole transcript is the unit: "Up two meters" is no loop of "Up"
        unit = _to_last_word(tokenizer, greedy)
    # Out of tokens on speech that is not a loop: it said more than the longest command, and no phrase
    # score could make it one, so the batched decoder pass over the phrases is skipped.
    loop = only_repeats(pieces, len(unit))
    cut = len(greedy) >= max_new_tokens and not loop
    if cut:
        return PhraseScores((), tokenizer.decode(unit).strip(), -math.inf, no_speech_prob,
                            heard_text=tokenizer.decode(greedy).strip(), cut=True)
    chosen = preselect(forms, greedy, steps, "".join(pieces), top_k)
    if unit and any(ch.isalnum() for ch in tokenizer.decode(unit)):
        unit = unit + list(tokenizer.encode("."))
    else:
        unit = []
    free_written = tokenizer.decode(unit[:-1]).strip() if unit else ""
    # An amount after words that are no phrase ("Descent 13 meters."): each phrase is scored with Whisper's own
    # amount after it, and judged like a plain one, on its words and the token after them (the first of the
    # amount, as the period is for a plain command: what tells "Go" from "Go up"). Without the amount, every
    # phrase would end where the speech goes on, and none could be heard.
    phrase_tokens = [list(forms.tokens[i]) for i in chosen]
    judged = [len(t) for t in phrase_tokens]            # how many leading tokens make each score
    free_judged = len(unit)
    if amount_at is not None and unit:
        period = list(tokenizer.encode("."))
        tail = unit[amount_at:]                           # " 13 meters." as Whisper wrote it
        core = [t[:-len(period)] if t[-len(period):] == period else t for t in phrase_tokens]
        phrase_tokens = [c + tail for c in core]
        judged = [len(c) + 1 for c in core]
        free_judged = amount_at + 1
    rivals = _amount_rivals(tokenizer, free_written + ".", amount, forms.dictionary.language) if amount else []
    sequences = (phrase_tokens + [toks for _, toks in rivals if toks is not None]
                 + ([unit] if unit else []))
    encoded = np.asarray(encoder_output)
    batch = ctranslate2.StorageView.from_array(np.ascontiguousarray(np.repeat(encoded, len(sequences), axis=0)))
    results = model.align(batch, prompt, sequences, [num_frames] * len(sequences))
    logprobs = [np.log(np.maximum(np.asarray(r.text_token_probs, np.float64), 1e-12)) for r in results]
    spoken = _aligned_span(results[-1], len(unit) - 1) if unit else None
    free_lp = logprobs.pop() if unit else np.empty(0)
    free_logprob = _mean(free_lp[:free_judged])
    rival_lps = [logprobs.pop() for _, toks in rivals if toks is not None][::-1]
    amount_gap, amount_rival = None, 0
    if amount is not None and unit:
        amount_gap = math.inf
        scored = iter(rival_lps)
        for value, toks in rivals:   # a rival that could not be written is not ruled out: unsure
            gap = -math.inf if toks is None else float(np.sum(free_lp)) - float(np.sum(next(scored)))
            if gap < amount_gap:
                amount_gap, amount_rival = gap, value
    if rank_by not in RANK_BY:
        raise ValueError(f"score_rank_by must be one of {', '.join(RANK_BY)}, not {rank_by!r}")
    rank = RANK_BY[rank_by]
    best: dict[int, tuple[Phrase, float, float]] = {}
    not_command = -math.inf
    for i, lp, n in zip(chosen, logprobs, judged):
        lp = lp[:n]
        phrase, score = forms.phrases[i], rank(lp)
        if phrase.action == NOT_A_COMMAND:
            not_command = max(not_command, score)
            continue
        key = id(phrase)
        if key not in best or score > best[key][1]:
            best[key] = (phrase, score, _mean(lp))
    # Whisper wrote a command with filler words around it ("Go up, please."): its transcript is a way of
    # writing that command, and scores as one; "Go up." alone is far less likely than what it heard.
    free_text = tokenizer.decode(unit[:-1]).strip()
    written = forms.dictionary.by_key.get(forms.dictionary.strip_skip_words(normalize_text(free_text)))
    if amount is not None:  # "Go forward three meters." is a way of writing "go forward" with its amount
        written = forms.dictionary.by_key.get(amount.command)
    if written is not None and (id(written) not in best or rank(free_lp) > best[id(written)][1]):
        best[id(written)] = (written, rank(free_lp), free_logprob)
    ordered = sorted(best.values(), key=lambda item: item[1], reverse=True)
    ranked = tuple((phrase, score) for phrase, score, _ in ordered)
    return PhraseScores(ranked, free_text, free_logprob, no_speech_prob,
                        not_command, ordered[0][2] if ordered else None,
                        tokenizer.decode(unit[:-1] if loop else greedy).strip(), cut, amount_gap, amount_rival,
                        spoken)
