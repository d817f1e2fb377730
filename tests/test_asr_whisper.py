"""Whisper engine on ../shared/models/faster-whisper-base (few decodes: ~1-5 s each here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_voice.asr.registry import load_recognizer
from gcs_voice.domain.dictionary import load_language
from gcs_voice.errors import ModelError
from gcs_voice.domain.text import normalize_text
from tests.asr_speech import pcm_of

pytest.importorskip("faster_whisper")
EN, ES = load_language("en"), load_language("es")


@pytest.fixture(scope="module")
def whisper(whisper_model_dir):
    return load_recognizer("whisper", [EN, ES], model=str(whisper_model_dir), mode="grammar")


def _recognise(recognizer, pcm, lang):
    stream = recognizer.start_stream(lang)
    stream.accept(pcm)
    return stream.finish()


@pytest.mark.slow
def test_english_command_with_alternatives_and_evidence(whisper, tmp_path):
    result = _recognise(whisper, pcm_of("turn left", tmp_path), "en")
    assert normalize_text(result.text) == "turn left"
    assert result.lang == "en"
    for key in ("no_speech_prob", "avg_logprob", "compression_ratio", "language_probability"):
        assert key in result.extra
    assert result.extra["no_speech_prob"] < 0.5


@pytest.mark.slow
def test_spanish_forced(whisper, tmp_path):
    result = _recognise(whisper, pcm_of("izquierda", tmp_path, "es"), "es")
    assert result.lang == "es"
    assert normalize_text(result.text) == "izquierda"


@pytest.mark.slow
def test_silence_is_flagged_and_output_stays_short(whisper):
    result = _recognise(whisper, bytes(16000 * 2), "en")
    # With the dictionary as prompt, Whisper may still utter a word on silence: the evidence says so.
    assert result.extra["no_speech_prob"] > 0.5
    assert all(len(h.text.split()) <= 4 for h in result.hypotheses), "max_new_tokens bounds the output"


@pytest.mark.slow
def test_auto_language_on_real_english(whisper, real_speech_dir):
    from gcs_voice.audio.sources import read_wav

    result = _recognise(whisper, read_wav(real_speech_dir / "en/stop/stop_c518d1b1_nohash_0.wav"), "auto")
    assert result.lang == "en"
    assert 0.0 < result.extra["language_probability"] <= 1.0
    assert normalize_text(result.text).startswith("stop")


def test_missing_model_is_a_model_error(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        load_recognizer("whisper", [EN], model=str(tmp_path / "nope"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelError, match="not a faster-whisper model"):
        load_recognizer("whisper", [EN], model=str(tmp_path / "empty"))


# -- mode "score": every dictionary phrase teacher-forced, free decoding as rejection evidence ---------
@pytest.fixture(scope="module")
def whisper_score(whisper_model_dir):
    return load_recognizer("whisper", [EN, ES], model=str(whisper_model_dir), mode="score")


def _decide(recognizer, pcm, lang):
    from gcs_voice.understanding import get_matcher

    result = _recognise(recognizer, pcm, lang)
    return result, get_matcher("phonetic").decide(result, [EN, ES] if lang == "auto" else [EN if lang == "en" else ES])


@pytest.mark.slow
@pytest.mark.parametrize(("text", "voice", "lang", "action"), [
    ("turn left", "en-us", "en", "turn_left"),
    ("go backward", "en-us", "en", "go_back"),  # espeak-ng's 175 wpm "go back" is heard as "Domec": no action
    ("baja", "es", "es", "down"),
])
def test_score_mode_classifies_commands(whisper_score, tmp_path, text, voice, lang, action):
    result, decision = _decide(whisper_score, pcm_of(text, tmp_path, voice), lang)
    assert result.engine == "whisper-score"
    assert {h.text for h in result.hypotheses} <= {p.text for p in (EN if lang == "en" else ES).phrases}
    scores = [h.score for h in result.hypotheses]
    assert scores == sorted(scores, reverse=True)
    for key in ("free_logprob", "phrase_score", "margin", "class_gap", "no_speech_prob"):
        assert key in result.extra
    assert result.extra["class_gap"] >= 0.0
    assert result.extra["margin"] == pytest.approx(result.extra["phrase_score"] - result.extra["free_logprob"])
    assert decision.action == action, decision


@pytest.mark.slow
def test_score_mode_rejects_out_of_domain_speech(whisper_score, tmp_path):
    result, decision = _decide(whisper_score, pcm_of("the weather is nice today", tmp_path), "en")
    assert result.hypotheses, "a phrase is always ranked first; the evidence must reject it"
    assert decision.action is None
    assert result.transcript, "the free transcript is kept as evidence"
    assert result.extra["margin"] < -1.0, "the phrase is far less likely than what Whisper heard"
    assert "not a command: heard" in decision.reason, decision.reason


@pytest.mark.slow
def test_score_mode_rejects_silence(whisper_score):
    result, decision = _decide(whisper_score, bytes(16000 * 2), "en")
    assert decision.action is None, decision


def test_score_mode_is_whisper_only():
    from gcs_voice.errors import GcsVoiceError

    with pytest.raises(GcsVoiceError, match="score"):
        load_recognizer("sphinx", [EN], mode="score")


def test_phrases_are_tokenised_as_whisper_emits_them(whisper_model_dir):
    """The shipped tokenizer.json lacks the "space + t" merge: " to the" must still be two tokens."""
    from faster_whisper import WhisperModel
    from faster_whisper.tokenizer import Tokenizer

    from gcs_voice.asr.whisper_score import canonical_tokens

    model = WhisperModel(str(whisper_model_dir), device="cpu", compute_type="int8", local_files_only=True)
    tokenizer = Tokenizer(model.hf_tokenizer, True, task="transcribe", language="en")
    ids = canonical_tokens(tokenizer, " Go to the right.")
    pieces = [tokenizer.decode([i]) for i in ids]
    assert pieces == [" Go", " to", " the", " right", "."]
    assert tokenizer.decode(ids) == " Go to the right."


def test_a_looping_transcript_counts_once():
    """On a short window Whisper loops ("Up Up Up"); only the first unit is compared with the phrases."""
    from gcs_voice.asr.whisper_score import first_unit_length

    assert first_unit_length([" Up", " Up", " Up"]) == 1
    assert first_unit_length([" Go", " to", " the", " right", ".", " Go", " to"]) == 4
    assert first_unit_length([" I", "'m", " going", " home", "."]) == 4
    assert first_unit_length([" Stop", "!"]) == 1


def test_a_loop_says_nothing_new_but_more_words_do():
    """The free pass's words after its first unit: a loop repeats them, anything else says more."""
    from gcs_voice.asr.whisper_score import first_unit_length, only_repeats

    loop = [" Go", " forward", ",", " go", " forward", ",", " go"]
    assert only_repeats(loop, first_unit_length(loop))
    assert only_repeats([" Desarmas", " los", " motores", ".", " Des"], 4)  # out of tokens inside the loop
    more = [" Turn", " left", ",", " turn", " left", ",", " and", " take"]
    assert not only_repeats(more, first_unit_length(more))
    went_on = [" Can", " I", " have", " a", " medium", " roast", " coffee", " with"]
    assert not only_repeats(went_on, first_unit_length(went_on)), "words that simply went on are no loop"


@pytest.mark.slow
@pytest.mark.parametrize(("text", "action"), [("turn left please", "turn_left"), ("please stop", "stop")])
def test_a_command_with_filler_words_acts(whisper_score, tmp_path, text, action):
    """Whisper heard the command and a skip word ("Turn left, please"): the transcript is a way of writing the
    command, not other speech; scored as the bare phrase, the command fell below the margin."""
    result, decision = _decide(whisper_score, pcm_of(text, tmp_path), "en")
    assert decision.action == action, (result.transcript, decision)
    assert result.extra["margin"] >= 0.0


@pytest.mark.slow
def test_speech_longer_than_any_command_scores_no_phrase(whisper_score, tmp_path):
    """The free pass runs out of tokens on a sentence that never repeats itself: it said more than a command,
    so no phrase is teacher-forced (the time is saved) and the decision says the speech went on."""
    result, decision = _decide(whisper_score, pcm_of("can I have a medium roast coffee with milk and sugar please",
                                                     tmp_path), "en")
    assert result.extra["transcript_cut"] == 1.0, result.transcript
    assert not result.hypotheses
    assert decision.action is None and "went on" in decision.reason and decision.went_on, decision


@pytest.mark.slow
def test_a_sentence_that_starts_with_commands_does_nothing(whisper_score, tmp_path):
    """Every word of "go up, go down, go left, go right, go back" is a command word, but the utterance says
    more than one command and goes on past the free pass: no action, while a command alone still acts."""
    result, decision = _decide(whisper_score, pcm_of("go up, go down, go left, go right, go back", tmp_path), "en")
    assert decision.action is None, (result.transcript, decision)
    _, decision = _decide(whisper_score, pcm_of("turn left", tmp_path), "en")
    assert decision.action == "turn_left", decision


@pytest.mark.slow
def test_same_audio_same_scores(whisper_score, tmp_path):
    """Greedy decoding, a stable ranking and a fixed batch: the decision never depends on what came before."""
    pcm = pcm_of("go forward", tmp_path)
    first = _recognise(whisper_score, pcm, "en")
    _recognise(whisper_score, pcm_of("the weather is nice today", tmp_path), "en")
    again = _recognise(whisper_score, pcm, "en")
    assert first == again


def test_default_engine_and_mode_follow_the_benchmark(whisper_model_dir, monkeypatch, tmp_path):
    """A found Whisper model is preferred to PocketSphinx, in its scoring mode (docs/bench/accuracy.md)."""
    from gcs_voice.asr.registry import default_engine, default_mode

    monkeypatch.setenv("VOSK_MODEL_PATH", str(tmp_path))
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.delenv("GCS_VOICE_WHISPER_MODEL", raising=False)
    assert default_engine("en") == "sphinx"  # nothing but pip
    monkeypatch.setenv("GCS_VOICE_WHISPER_MODEL", str(whisper_model_dir))
    assert default_engine("en") == "whisper"
    assert default_engine("es") == "whisper"
    assert default_mode("whisper") == "score"
    assert default_mode("sphinx") == "grammar"
    assert load_recognizer("whisper", [EN], model=str(whisper_model_dir)).name == "whisper-score"


@pytest.mark.slow
def test_score_mode_auto_language_scores_every_language(whisper_score, tmp_path):
    """--lang auto: the best phrase over both dictionaries picks the language, even where Whisper's
    language detection calls espeak-ng's Spanish English (it gives "baja" < 10 % Spanish here)."""
    result, _ = _decide(whisper_score, pcm_of("baja", tmp_path, "es"), "auto")
    assert result.lang == "es" and result.text == "baja"
    result, _ = _decide(whisper_score, pcm_of("turn left", tmp_path, "en-us"), "auto")
    assert result.lang == "en" and result.text == "turn left"


def test_a_not_command_is_a_rival_class_of_every_phrase() -> None:
    """A dictionary's not-commands ("four", "off") count in the class gap: a phrase that does not beat them
    clearly is no action, whatever the phrases of other classes score."""
    from gcs_voice.asr.whisper_score import PhraseScores
    from gcs_voice.domain.dictionary import Phrase

    forward = Phrase("forward", "forward", "go_forward")
    up = Phrase("up", "up", "up")
    alone = PhraseScores(((forward, -0.5), (up, -4.0)), "4", -0.4, 0.0)
    rivalled = PhraseScores(((forward, -0.5), (up, -4.0)), "4", -0.4, 0.0, not_command=-0.3)
    assert alone.class_gap == pytest.approx(3.5)
    assert rivalled.class_gap == pytest.approx(-0.2)
    only = PhraseScores(((forward, -0.5),), "forward", -0.5, 0.0)
    assert only.class_gap == math.inf


@pytest.mark.parametrize("samples,window", [(16000, 128000), (12345, 128000), (127000, 128000), (40000, 44800)])
def test_log_mel_of_the_utterance_alone_is_that_of_the_padded_window(samples, window):
    """Scoring mode computes the log-mel on the utterance and fills in the silent rest of the window: the
    encoder must see what Whisper's own extractor gives for the zero-padded window. Bit for bit on some
    machines; elsewhere the FFT of a shorter frame count rounds a few values differently, by a float32 ulp."""
    from faster_whisper.feature_extractor import FeatureExtractor

    from gcs_voice.asr.whisper_engine import _log_mel_padded

    extractor = FeatureExtractor()
    audio = (np.random.default_rng(samples).standard_normal(samples) * 0.1).astype(np.float32)
    padded = np.zeros(window, np.float32)
    padded[:samples] = audio
    ours, whisper = _log_mel_padded(extractor, audio, window), extractor(padded)[:, :-1]
    assert ours.shape == whisper.shape
    assert float(np.max(np.abs(ours - whisper))) <= 2.5e-7


def test_one_blas_thread_gives_the_same_features() -> None:
    """The one-BLAS-thread features (``WhisperRecognizer.log_mel``) are what the extractor gives with the
    process's own BLAS threads, so the decisions measured before that change still stand (a float32 ulp is
    allowed: a BLAS may split the sums differently by thread)."""
    from faster_whisper.feature_extractor import FeatureExtractor
    from threadpoolctl import threadpool_limits

    from gcs_voice.asr.whisper_engine import _log_mel_padded

    extractor = FeatureExtractor()
    audio = (np.random.default_rng(7).standard_normal(20000) * 0.1).astype(np.float32)
    shared = _log_mel_padded(extractor, audio, 128000)
    with threadpool_limits(limits=1, user_api="blas"):
        alone = _log_mel_padded(extractor, audio, 128000)
    assert float(np.max(np.abs(shared - alone))) <= 2.5e-7


def _spanish_preselect_case(whisper_model_dir, heard: str):
    """Spanish phrase forms and a greedy pass that wrote ``heard`` with every step flat (no evidence)."""
    import tokenizers
    from faster_whisper.tokenizer import Tokenizer

    from gcs_voice.asr.whisper_score import phrase_forms

    hf = tokenizers.Tokenizer.from_file(str(whisper_model_dir / "tokenizer.json"))
    tokenizer = Tokenizer(hf, True, task="transcribe", language="es")
    forms = phrase_forms(tokenizer, load_language("es"))
    greedy = list(tokenizer.encode(heard))
    flat = np.full(hf.get_vocab_size(), -math.log(hf.get_vocab_size()))
    return forms, greedy, flat, [flat.copy() for _ in greedy]


def test_forms_that_tie_on_the_greedy_path_are_chosen_by_what_whisper_wrote(whisper_model_dir) -> None:
    """When Whisper's transcript leaves every form at its first token ("¡Wenete a la izquier" for "muévete a
    la izquierda"), all forms sharing that token tie; dictionary order (derecha before izquierda) must not
    decide which class gets scored. A form the greedy pass knows better still comes first."""
    from gcs_voice.asr.whisper_score import preselect

    heard = " ¡Wenete a la izquier"
    forms, greedy, flat, steps = _spanish_preselect_case(whisper_model_dir, heard)
    chosen = preselect(forms, greedy, steps, heard, top_k=2)
    assert forms.phrases[chosen[0]].text == "muévete a la izquierda", [forms.phrases[i].text for i in chosen]
    assert "muévete a la derecha" not in {forms.phrases[i].text for i in chosen}
    # the greedy pass's own evidence outranks nearness of words
    firsts = [toks[0] for toks in forms.tokens]
    alone = next(i for i, p in enumerate(forms.phrases) if p.action == "up" and firsts.count(firsts[i]) == 1)
    steps[0] = flat.copy()
    steps[0][firsts[alone]] = -0.1
    assert preselect(forms, greedy, steps, heard, top_k=2)[0] == alone


def test_a_command_is_scored_when_whisper_heard_something_near_the_not_commands(whisper_model_dir) -> None:
    """A real "up" heard as "Um" put four not-commands ("on", "off", "of", "all") first on the greedy path:
    no phrase was judged and the command read as nothing heard. One command form must always be scored,
    with the not-commands beside it as its rivals."""
    import tokenizers
    from faster_whisper.tokenizer import Tokenizer

    from gcs_voice.asr.whisper_score import NOT_A_COMMAND, phrase_forms, preselect

    hf = tokenizers.Tokenizer.from_file(str(whisper_model_dir / "tokenizer.json"))
    tokenizer = Tokenizer(hf, True, task="transcribe", language="en")
    forms = phrase_forms(tokenizer, load_language("en"))
    heard = " Um"
    greedy = list(tokenizer.encode(heard))
    flat = np.full(hf.get_vocab_size(), -math.log(hf.get_vocab_size()))
    steps = [flat.copy() for _ in greedy]
    for toks, phrase in zip(forms.tokens, forms.phrases):
        if phrase.action == NOT_A_COMMAND:
            steps[0][toks[0]] = -0.1  # the greedy pass knows every not-command better than any command
    chosen = preselect(forms, greedy, steps, heard, top_k=4)
    kinds = [forms.phrases[i].action for i in chosen]
    assert len(chosen) == 4
    assert sum(k != NOT_A_COMMAND for k in kinds) == 1, kinds
    assert sum(k == NOT_A_COMMAND for k in kinds) == 3, kinds


def test_another_class_is_always_scored_beside_the_best(whisper_model_dir) -> None:
    """A real "left" heard "Black." in a kitchen put four forms of go_back first on the greedy path: no other
    class was judged, the class gap read as infinite and the vehicle went back. One form of another class (or a
    not-command) must always be scored beside them, and the transcript's own command keeps its place."""
    import tokenizers
    from faster_whisper.tokenizer import Tokenizer

    from gcs_voice.asr.whisper_score import phrase_forms, preselect

    hf = tokenizers.Tokenizer.from_file(str(whisper_model_dir / "tokenizer.json"))
    tokenizer = Tokenizer(hf, True, task="transcribe", language="en")
    forms = phrase_forms(tokenizer, load_language("en"))
    for heard in (" Black.", " Backward"):
        greedy = list(tokenizer.encode(heard))
        flat = np.full(hf.get_vocab_size(), -math.log(hf.get_vocab_size()))
        steps = [flat.copy() for _ in greedy]
        for toks, phrase in zip(forms.tokens, forms.phrases):
            if phrase.action == "go_back":
                steps[0][toks[0]] = -0.1  # the greedy pass knows every go_back form better than anything else
        chosen = preselect(forms, greedy, steps, heard, top_k=4)
        actions = [forms.phrases[i].action for i in chosen]
        assert len(chosen) == 4 and actions.count("go_back") == 3, actions
        if heard == " Backward":
            assert "backward" in {forms.phrases[i].text for i in chosen}


def test_a_command_whisper_wrote_word_for_word_is_always_scored(whisper_model_dir) -> None:
    """When the greedy pass knows other forms better (here: their first tokens are near-certain), the form
    whose words ARE the transcript must still be scored: espeak-ng "desarma los motores" was heard word for
    word and then judged against "desarmar motores" only."""
    from gcs_voice.asr.whisper_score import preselect

    heard = " Desarma los motores"
    forms, greedy, flat, steps = _spanish_preselect_case(whisper_model_dir, heard)
    exact_firsts = {toks[0] for toks, phrase in zip(forms.tokens, forms.phrases) if phrase.text == "desarma los motores"}
    for toks in forms.tokens:
        if toks[0] not in exact_firsts:
            steps[0][toks[0]] = -0.1
    chosen = preselect(forms, greedy, steps, heard, top_k=2)
    assert "desarma los motores" in {forms.phrases[i].text for i in chosen}, [forms.phrases[i].text for i in chosen]
    assert len(chosen) == 2
    # the same evidence with a transcript that is no phrase leaves it out: the guarantee did it, not the ranking
    others = preselect(forms, greedy, steps, " Muestra la memoria", top_k=2)
    assert "desarma los motores" not in {forms.phrases[i].text for i in others}


@pytest.mark.parametrize("mode", ["score", "grammar"])
def test_features_are_computed_with_one_blas_thread(whisper_score, whisper, monkeypatch, mode) -> None:
    """OpenBLAS's workers spin after the mel filter product and take the cores from the encoder that runs
    next: the features are computed with one BLAS thread, and the process's own setting is left as it was."""
    from threadpoolctl import threadpool_info

    recognizer = whisper_score if mode == "score" else whisper
    blas_threads = lambda: {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}
    before = blas_threads()
    seen: list[set[int]] = []

    class Watched:  # the model's own extractor, noting the BLAS threads it runs with
        def __init__(self, real):
            self.real = real

        def __call__(self, audio, *args, **kwargs):
            seen.append(blas_threads())
            return self.real(audio, *args, **kwargs)

        def __getattr__(self, name):
            return getattr(self.real, name)

    monkeypatch.setattr(recognizer.model, "feature_extractor", Watched(recognizer.model.feature_extractor))
    pcm = (np.sin(np.linspace(0, 2000, 16000)) * 8000).astype("<i2").tobytes()
    recognizer.decode(pcm, "en")
    assert seen and all(threads == {1} for threads in seen)
    assert blas_threads() == before


@pytest.mark.slow
def test_a_clatter_of_dishes_does_not_fly(whisper_score):
    """Noise alone never acts. On a dev-part stream the segmenter cut this clatter of the real kitchen
    recording (../shared/noise, 12 dB below the speech level); Whisper wrote "The" for it, far below its own
    confidence for anything, while the phrase "ahead" scored above that and flew go_forward. What Whisper
    could not write down is no action."""
    from conftest import shared_path
    from tools.listen.streams import read_wav

    noise = read_wav(shared_path("noise", "doing_the_dishes.wav"))
    pcm = (noise[196153:196153 + 6656] * 0.3365 * 32767).astype("<i2").tobytes()
    result, decision = _decide(whisper_score, pcm, "en")
    assert decision.action is None, decision
    assert result.extra["free_logprob"] < -5.0, result  # the case this guards: Whisper unsure of its own words
    assert "nothing clear" in decision.reason, decision.reason


def _english_tokenizer_and_forms(whisper_model_dir):
    import tokenizers
    from faster_whisper.tokenizer import Tokenizer

    from gcs_voice.asr.whisper_score import phrase_forms

    hf = tokenizers.Tokenizer.from_file(str(whisper_model_dir / "tokenizer.json"))
    tokenizer = Tokenizer(hf, True, task="transcribe", language="en")
    return tokenizer, phrase_forms(tokenizer, EN)


@pytest.mark.parametrize(("written", "more"), [
    (" Left. Left. Left. Left.", False),          # a loop on a plain command: judged on "Left."
    (" Up Up Up Up Up Up Up Up", False),
    (" 7 7 7 7 7 7 7 7", False),                   # a loop of a number alone is no command
    (" Move up 5 meters. Move up 5", False),      # an amount, and its loop begun: read alone
    (" Decrease altitude, 13 meters.", True),     # an amount: what follows it decides how it is read
    (" Turn left one hundred and", True),         # a number begun and not ended
    (" I'm going to go to the other", False),     # no number: the speech went on, nothing to wait for
    (" May I have a 16-ounce dark", False),       # a number and other words after it: no command's amount
])
def test_the_free_pass_reads_on_only_where_more_words_could_change_the_judgement(whisper_model_dir, written, more):
    from gcs_voice.asr.whisper_score import _may_say_more

    tokenizer, forms = _english_tokenizer_and_forms(whisper_model_dir)
    assert _may_say_more(tokenizer, forms, tokenizer.encode(written)) is more


class _CountingModel:
    """The CTranslate2 Whisper model, with the ``max_length`` of each free pass it was asked for."""

    def __init__(self, model) -> None:
        self.model, self.passes = model, []

    def generate(self, *args, **kwargs):
        self.passes.append(kwargs["max_length"])
        return self.model.generate(*args, **kwargs)

    def align(self, *args, **kwargs):
        return self.model.align(*args, **kwargs)


def _one_pass(model, tokenizer, forms, encoder_output, prompt, max_new_tokens, room):
    """The free pass as it was before it could stop early: one greedy pass with room for an amount."""
    from gcs_voice.asr.whisper_score import generation_length

    free = model.generate(encoder_output, [prompt], max_length=generation_length(len(prompt), room), beam_size=1,
                          return_scores=True, return_no_speech_prob=True, return_logits_vocab=True,
                          suppress_blank=True, suppress_tokens=[-1])[0]
    return list(free.sequences_ids[0])[:room], list(free.logits[0]), float(free.no_speech_prob)


def _score(recognizer, audio: np.ndarray):
    from gcs_voice.asr.whisper_score import score_utterance

    encoded, frames, _ = recognizer.encode_short(audio)
    model = _CountingModel(recognizer.model.model)
    s = recognizer.settings
    scores = score_utterance(model, recognizer.tokenizer("en"), recognizer.phrase_forms("en"), encoded, frames,
                             int(s.get("score_extra_tokens", 3)), int(s.get("score_top_k", 8)),
                             str(s.get("score_rank_by", "mean")))
    return scores, model.passes


@pytest.mark.slow
@pytest.mark.parametrize(("clip", "passes"), [
    ("real:en/go_left/left_8c7f81df_nohash_0.wav", 1),           # "Left. Left. Left. Left.": stopped
    ("say:decrease altitude thirteen meters", 2),               # an amount, read on
])
def test_a_free_pass_that_stops_early_judges_as_one_that_ran_on(whisper_score, real_speech_dir, tmp_path,
                                                                 monkeypatch, clip, passes):
    """Stopped where nothing more could change the judgement, or read on from what Whisper wrote, the free pass
    gives the same scores as one pass with room for an amount: the loops of short commands took a 180 ms pass
    for a 50 ms one, and were the tail of the decision time (tools.speech.bench_real timing)."""
    from gcs_voice.asr import whisper_score as ws
    from gcs_voice.audio.sources import read_wav

    kind, _, what = clip.partition(":")
    pcm = read_wav(real_speech_dir / what) if kind == "real" else pcm_of(what, tmp_path)
    audio = np.frombuffer(pcm, "<i2").astype(np.float32) / 32768
    staged_pass = ws._free_pass
    staged, used = _score(whisper_score, audio)
    monkeypatch.setattr(ws, "_free_pass", _one_pass)
    one, [room] = _score(whisper_score, audio)
    assert staged == one
    assert len(used) == passes
    assert used[0] < room  # the first pass had room for a command, not for an amount
    if passes == 2:  # read on: the same tokens, and logits bit for bit, as one pass
        rec, tokenizer, forms = whisper_score, whisper_score.tokenizer("en"), whisper_score.phrase_forms("en")
        encoded, _, _ = rec.encode_short(audio)
        prompt = list(tokenizer.sot_sequence) + [tokenizer.no_timestamps]
        short = max(len(t) for t in forms.tokens) + int(rec.settings.get("score_extra_tokens", 3))
        args = (rec.model.model, tokenizer, forms, encoded, prompt, short, short + ws.AMOUNT_TOKENS)
        (tokens, logits, _), (one_tokens, one_logits, _) = staged_pass(*args), _one_pass(*args)
        assert tokens == one_tokens and len(logits) == len(one_logits)
        assert all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(logits, one_logits))
