"""Speed (and, on the side, command accuracy) of the three recognisers on this machine.

    nice -n 10 python -m tools.speech.bench_asr_speed --out asr.md   # prints the table; --out writes it too

Corpora: ../shared/speech (95 real English recordings: 75 commands, 20 other words; labels.tsv) for
Sphinx and Whisper; espeak-ng Korean for Vosk (the only Vosk model here is Korean). Decisions use the
default matcher. "ms/utt" is the wall time of start_stream + accept + finish, model already loaded.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

from gcs_voice.asr import settings as asr_settings
from gcs_voice.asr.registry import load_recognizer
from gcs_voice.audio.sources import read_wav
from gcs_voice.domain.dictionary import load_language
from gcs_voice.understanding import DEFAULT_MATCHER, get_matcher

NOTES = """
Notes (what the rows show):

- Sphinx's garbage branch (short common words competing with the commands) is what makes it reject:
  without it most of the 20 non-command words become commands (table). It costs some recall (real speakers'
  commands absorbed by garbage words) and time; the narrower beams in `engines.toml` keep it fast.
- Whisper is the most accurate here but the slowest: each utterance is encoded as a 30 s window.
  The dictionary prompt (mode `grammar`) helps on commands but, on silence or noise, makes Whisper say
  dictionary words (they must be rejected by `no_speech_prob`, which stays high: tests/test_asr_whisper.py).
  Seen by hand: espeak-ng Spanish "derecha" was heard as "detenerse" (a stop phrase) with the prompt.
- Vosk: only the small Korean model exists here; espeak-ng's Korean voice gives 뒤로 -> 위로 and
  앞으로 -> 아래 뒤로 (synthetic-voice limits). English and Spanish Vosk models are what users download.
"""

KO_SAID = ["위로", "위", "아래로", "아래", "오른쪽", "왼쪽", "앞으로", "뒤로", "멈춰", "정지"]


def real_corpus(speech: Path, every: int) -> list[tuple[bytes, str | None]]:
    rows = list(csv.DictReader(open(speech / "labels.tsv"), delimiter="\t"))[::every]
    return [(read_wav(speech / r["path"]), None if r["class"] == "none" else r["class"]) for r in rows]


def korean_corpus() -> list[tuple[bytes, str | None]]:
    ko = load_language("ko")
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, text in enumerate(KO_SAID):
            raw, wav = Path(tmp) / f"{i}.raw.wav", Path(tmp) / f"{i}.wav"
            subprocess.run(["espeak-ng", "-v", "ko", "-w", str(raw), text], check=True)
            subprocess.run(["sox", "-R", str(raw), "-r", "16000", "-c", "1", "-b", "16", str(wav)], check=True)
            out.append((read_wav(wav), ko.by_key[text].action))
    return out


def run(label, engine, lang, corpus, model=None, mode="grammar") -> dict:
    dictionary = load_language(lang)
    started = time.perf_counter()
    recognizer = load_recognizer(engine, [dictionary], model=model, mode=mode)
    load_s = time.perf_counter() - started
    matcher = get_matcher(DEFAULT_MATCHER)
    ms, audio_s, right, commands, accepted, others = [], 0.0, 0, 0, 0, 0
    for pcm, want in corpus:
        t0 = time.perf_counter()
        stream = recognizer.start_stream(lang)
        stream.accept(pcm)
        result = stream.finish()
        ms.append((time.perf_counter() - t0) * 1000)
        audio_s += len(pcm) / 32000
        action = matcher.decide(result, [dictionary]).action
        if want is None:
            others += 1
            accepted += action is not None
        else:
            commands += 1
            right += action == want
    return {"label": label, "n": len(corpus), "load_s": load_s, "median_ms": statistics.median(ms),
            "p90_ms": sorted(ms)[int(0.9 * (len(ms) - 1))], "rtf": sum(ms) / 1000 / audio_s,
            "right": f"{right}/{commands}", "accepted": f"{accepted}/{others}" if others else "-"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speech", type=Path, default=REPO.parent / "shared" / "speech")
    parser.add_argument("--whisper-model", default=str(REPO.parent / "shared" / "models" / "faster-whisper-base"))
    parser.add_argument("--whisper-every", type=int, default=3, help="use every Nth recording for Whisper (slow)")
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    args = parser.parse_args()

    real = real_corpus(args.speech, 1)
    rows = [run("sphinx grammar + garbage (default)", "sphinx", "en", real)]
    sphinx = asr_settings._load()["sphinx"]  # the cached engines.toml table: switch the garbage branch off
    garbage, sphinx["garbage_words"] = sphinx["garbage_words"], []
    rows.append(run("sphinx grammar, no garbage branch", "sphinx", "en", real))
    sphinx["garbage_words"] = garbage
    rows.append(run("sphinx free (n-gram LM)", "sphinx", "en", real, mode="free"))
    some = real_corpus(args.speech, args.whisper_every)
    rows.append(run(f"whisper base int8, en, dictionary prompt (1 file in {args.whisper_every})", "whisper", "en",
                    some, model=args.whisper_model))
    rows.append(run(f"whisper base int8, en, no prompt (mode free; 1 file in {args.whisper_every})", "whisper",
                    "en", some, model=args.whisper_model, mode="free"))
    rows.append(run("vosk small-ko grammar (espeak-ng Korean)", "vosk", "ko", korean_corpus()))

    lines = [
        "# Recogniser speed on this machine",
        "",
        f"Command: `nice -n 10 python -m tools.speech.bench_asr_speed` (matcher: `{DEFAULT_MATCHER}`; 2 shared cores,",
        "other jobs running, so absolute times are pessimistic). Corpus: `../shared/speech` (75 commands of",
        "5 classes + 20 other words, real speakers) unless said; Vosk on espeak-ng Korean dictionary words.",
        "",
        "| engine / setting | utterances | load s | median ms/utt | p90 ms/utt | real-time factor | commands right | others accepted |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['label']} | {r['n']} | {r['load_s']:.1f} | {r['median_ms']:.0f} | {r['p90_ms']:.0f} | "
                     f"{r['rtf']:.2f} | {r['right']} | {r['accepted']} |")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n" + NOTES, encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
