"""Accuracy benchmark of the voice front-end: recogniser (voice-asr registry) + matcher, per noise.

Two stages. ``recognise`` streams every WAV of the synthetic corpus (tools/speech/make_corpus.py) and of the
real recordings (../shared/speech) through each engine once and caches the hypotheses, evidence and
timings per file in ``out/bench/recognitions-<engine>.json`` (resumable; Whisper is slow here).
``report`` runs every matcher over the cached recognitions and writes the paper's table layout
(matcher x language x noise), babble/hum at 20/10/5 dB, out-of-domain false accepts, the real
voices, latency and real-time factor, and confusion matrices, into docs/bench/accuracy.md.
``tune`` sweeps the rejection thresholds on the dev split + real voices. ``paired`` compares engines on exactly
the same files: ``report`` scores each engine on the files it has cached, so when one engine was run on every 3rd
file only, its cells are not comparable with the others'; this prints one markdown table of the default matcher's
decisions on the files ALL the named engines have cached (test split + real voices). Its ``--min-confidence`` adds
the LAST engine once per value of the matcher's min_confidence (a trade-off curve on the same files, not a tuned
result).

    nice -n 10 python -m tools.speech.bench_accuracy recognise --engines sphinx,whisper
    python -m tools.speech.bench_accuracy report
    python -m tools.speech.bench_accuracy tune --engine whisper --matcher phonetic
    python -m tools.speech.bench_accuracy paired whisper whisper-score
    python -m tools.speech.bench_accuracy paired whisper whisper-score --min-confidence 0.5,0.9,0.99

The report and tune stages (tables, confusion matrices, threshold sweeps) are below the recognise stage; what every
stage shares (items, engines, cache, scores) is tools/speech/accuracy_data.py.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
import zlib
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from gcs_voice.asr.base import Recognition
from gcs_voice.domain.dictionary import FLIGHT_ACTIONS, MOTION_ACTIONS, load_language
from gcs_voice.understanding import DEFAULT_MATCHER, MATCHERS, get_matcher

from tools.speech import accuracy_data
from tools.speech import make_corpus
from tools.speech.accuracy_data import (
    BEGIN, CACHE_DIR, DOC, END, IMG, MIXED_NOISES, PAPER_NOISES, REPO, SHARED, Item, Score, corpus_items, decide_all,
    file_digest, fresh_cache, is_near, real_items, recognition, save_cache, score, voice_kind,
)

CHUNK_S = 0.1


def recognise_one(recognizer, item: Item) -> dict:
    """Stream one WAV in 100 ms chunks; latency counts from the end of the audio, as if live."""
    samples = make_corpus.read_wav(item.path)
    pcm = (np.clip(samples, -1, 32767 / 32768) * 32768).astype("<i2").tobytes()
    chunk = int(CHUNK_S * 16_000) * 2
    stream = recognizer.start_stream(item.lang)
    clock = 0.0  # simulated time at which the engine is free again (s since audio start)
    busy = 0.0
    n_chunks = max(1, -(-len(pcm) // chunk))
    for i in range(n_chunks):
        available = (i + 1) * CHUNK_S
        t0 = time.perf_counter()
        stream.accept(pcm[i * chunk:(i + 1) * chunk])
        dt = time.perf_counter() - t0
        clock = max(clock, available) + dt
        busy += dt
    t0 = time.perf_counter()
    rec: Recognition = stream.finish()
    dt = time.perf_counter() - t0
    busy += dt
    clock = max(clock, n_chunks * CHUNK_S) + dt
    audio_s = len(pcm) / 2 / 16_000
    return {
        "hypotheses": [[h.text, h.confidence, h.score] for h in rec.hypotheses],
        "engine": rec.engine, "lang": rec.lang, "extra": dict(rec.extra), "transcript": rec.transcript,
        "audio_s": audio_s,
        "latency_s": clock - n_chunks * CHUNK_S, "busy_s": busy, "sha1": file_digest(item.path),
    }


def recognise(engines: Iterable[str], items: list[Item], limit_s: float | None, every: int) -> None:
    for engine in engines:
        cache = fresh_cache(engine, items)
        todo = [it for it in items[::every] if it.key not in cache]
        todo = [it for it in todo if accuracy_data.supports(engine, it.lang)]
        # A fixed pseudo-random order: a run stopped early (--limit-s) still samples every cell evenly.
        todo.sort(key=lambda it: (it.split != "real", zlib.crc32(it.key.encode())))
        print(f"{engine}: {len(cache)} cached, {len(todo)} to recognise", flush=True)
        if not todo:
            continue
        recognizers: dict[str, object] = {}
        config = accuracy_data.config(engine)
        t_start, last_save = time.monotonic(), time.monotonic()
        for n, it in enumerate(todo, 1):
            if it.lang not in recognizers:
                recognizers[it.lang] = accuracy_data.load(engine, it.lang)
            cache[it.key] = recognise_one(recognizers[it.lang], it)
            if time.monotonic() - last_save > 20 or n == len(todo):
                save_cache(engine, cache, config)
                last_save = time.monotonic()
                print(f"  {engine}: {n}/{len(todo)} ({time.monotonic() - t_start:.0f} s)", flush=True)
            if limit_s and time.monotonic() - t_start > limit_s:
                save_cache(engine, cache, config)
                print(f"  {engine}: stopped after --limit-s {limit_s:.0f} s", flush=True)
                break


# -- report and tune stages: tables, confusion matrices and threshold sweeps ------------------------------
LANGS = ("en", "es")
REPORT_SPLITS = ("test", "real")  # thresholds are tuned on "dev" and the real voices


def _cell(s: Score) -> str:
    if not s.n_cmd:
        return "–"
    return f"**{s.pct('right'):.1f}** / {s.pct('wrong'):.1f} / {s.pct('rejected'):.1f} (n={s.n_cmd})"


def _fa(s: Score) -> str:
    return f"{s.pct('false_accept'):.1f} ({s.false_accept}/{s.n_ood})" if s.n_ood else "–"


def _z(x: float) -> float:
    return 0.0 if math.isnan(x) else x


def _pcts(values: Sequence[float]) -> str:
    return f"{np.percentile(values, 50) * 1000:.0f} / {np.percentile(values, 95) * 1000:.0f}" if values else "–"


def confusion_png(path: Path, panels: list[tuple[str, list[Item], dict[str, str]]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seen = {decided[it.key] for _, items, decided in panels for it in items if it.key in decided}
    labels = list(MOTION_ACTIONS) + [a for a in FLIGHT_ACTIONS if a in seen] + ["none"]
    ncols = min(4, len(panels))
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 4.6 * nrows), squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.axis("off")
    for ax, (title, items, decided) in zip(axes.flat, panels):
        m = np.zeros((len(labels), len(labels)), dtype=int)
        for it in items:
            if it.key in decided:
                m[labels.index(it.truth), labels.index(decided[it.key])] += 1
        ax.imshow(m, cmap="Blues")
        for i in range(len(labels)):
            for j in range(len(labels)):
                if m[i, j]:
                    ax.text(j, i, str(m[i, j]), ha="center", va="center", fontsize=7,
                            color="white" if m[i, j] > m.max() / 2 else "black")
        ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=7)
        ax.set_yticks(range(len(labels)), labels, fontsize=7)
        ax.set_xlabel("decided (none = no action)", fontsize=8)
        ax.set_ylabel("said", fontsize=8)
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(engines: list[str], matchers: list[str], items: list[Item]) -> None:
    dictionaries = {lang: load_language(lang) for lang in LANGS}
    lines: list[str] = []
    items = [it for it in items if it.split in REPORT_SPLITS]
    summary: list[str] = []
    previous = _previous_sections()
    for engine in engines:
        cache = fresh_cache(engine, items)
        if not cache:
            if engine in previous:  # measured earlier, caches gone: keep what was written then
                section, timing_row = previous[engine]
                lines += section
                summary += [timing_row] if timing_row else []
            else:
                lines += [f"### {engine}", "", "Not run (no cached recognitions).", ""]
            continue
        cached = [it for it in items if it.key in cache]
        decided = {m: decide_all(engine, m, cached, cache, dictionaries) for m in matchers}
        decided["levenshtein, no rejection (paper)"] = decide_all(
            engine, "levenshtein", cached, cache, dictionaries, reject=0)
        decided[f"{DEFAULT_MATCHER}, --lang auto"] = decide_all(
            engine, DEFAULT_MATCHER, cached, cache, dictionaries, auto=True)
        langs = [lang for lang in LANGS if any(it.lang == lang and it.split == "test" for it in cached)]
        lines += [f"### {engine}", ""]
        lines += ["Commands: **accuracy** / wrong class / rejected, % of commands (test split). "
                  "OOD: out-of-domain sentences acted on; near-commands: everyday phrases built on a "
                  "command word (\"left luggage\", \"sube el volumen\") acted on; % over the table's noises.", ""]
        for noises, title in ((PAPER_NOISES, "paper's noise (uniform on [-1, 1])"),
                              (MIXED_NOISES, "babble and propeller hum, SNR in dB")):
            for lang in langs:
                lines.append(f"{lang}, {title}:")
                lines.append("")
                lines.append("| matcher | " + " | ".join(noises) + " | OOD false accepts | near-commands acted on |")
                lines.append("|---" * (len(noises) + 3) + "|")
                for m, dec in decided.items():
                    cells = [_cell(score(cached, dec, lang=lang, noise=n, split="test")) for n in noises]
                    fa_n, near_n = Score(), Score()
                    for it in cached:
                        if it.lang == lang and it.split == "test" and it.noise in noises and it.key in dec:
                            (near_n if is_near(it) else fa_n).add(it.truth, dec[it.key])
                    lines.append(f"| {m} | " + " | ".join(cells) + f" | {_fa(fa_n)} | {_fa(near_n)} |")
                lines.append("")
        lines += _by_voice(cached, decided[DEFAULT_MATCHER], langs)
        real = [it for it in cached if it.split == "real"]
        if real:
            lines += ["Real voices (../shared/speech, 75 commands of 5 classes + 20 non-command words; "
                      "development set, too small for fine claims):", "",
                      "| matcher | commands right | wrong class | rejected | non-command words acted on |",
                      "|---|---|---|---|---|"]
            for m, dec in decided.items():
                s = score(real, dec)
                lines.append(f"| {m} | {s.right}/{s.n_cmd} ({s.pct('right'):.1f} %) | {s.wrong} | {s.rejected} "
                             f"| {s.false_accept}/{s.n_ood} |")
            lines.append("")
        lat = [cache[it.key]["latency_s"] for it in cached]
        rtf = [cache[it.key]["busy_s"] / cache[it.key]["audio_s"] for it in cached if cache[it.key]["audio_s"]]
        summary.append(f"| {engine} | {len(cached)} | {_pcts(lat)} | {np.mean(rtf) if rtf else math.nan:.2f} |")
        png = IMG / f"accuracy_confusion_{engine}.png"
        panels = []
        for lang in langs:
            for noise in ("raw", "u0.15", "babble10"):
                sel = [it for it in cached if it.lang == lang and it.noise == noise and it.split == "test"]
                panels.append((f"{engine} + {DEFAULT_MATCHER}: {lang} {noise}", sel, decided[DEFAULT_MATCHER]))
        if real:
            panels.append((f"{engine} + {DEFAULT_MATCHER}: real voices", real, decided[DEFAULT_MATCHER]))
        if panels:
            confusion_png(png, panels)
            lines += [f"![confusion {engine}](img/{png.name})", ""]
    lines = ["## Timing", "",
             "Latency = time from the end of the audio to the decision input being ready (WAV streamed in "
             "100 ms chunks, engine backlog simulated as if live; end-of-speech detection not included). "
             "RTF = engine busy time / audio duration. Both measured on this 2-core machine shared with "
             "other jobs, under `nice`.", "",
             "| engine | utterances | latency p50 / p95 (ms) | RTF |", "|---|---|---|---|", *summary, "",
             "## Results per engine", "", *lines]
    text = DOC.read_text(encoding="utf-8") if DOC.is_file() else f"# Accuracy\n\n{BEGIN}\n{END}\n"
    head, _, rest = text.partition(BEGIN)
    _, _, tail = rest.partition(END)
    DOC.parent.mkdir(parents=True, exist_ok=True)
    DOC.write_text(head + BEGIN + "\n" + "\n".join(lines) + "\n" + END + tail, encoding="utf-8")
    print(f"wrote {DOC}")


def _by_voice(cached: list[Item], decided: dict[str, str], langs: list[str]) -> list[str]:
    """The default matcher's table split by kind of voice, for a language read by more than one kind: the natural
    voice is nearer to the people the product is for than espeak-ng's formant voices."""
    lines: list[str] = []
    noises = PAPER_NOISES + MIXED_NOISES
    for lang in langs:
        mine = [it for it in cached if it.lang == lang and it.split == "test"]
        kinds = sorted({voice_kind(it) for it in mine})
        if len(kinds) < 2:
            continue
        lines += [f"{lang} by kind of voice, {DEFAULT_MATCHER}:", "",
                  "| voice | " + " | ".join(noises) + " | non-commands acted on |", "|---" * (len(noises) + 2) + "|"]
        for kind in kinds:
            sel = [it for it in mine if voice_kind(it) == kind]
            others = Score()
            for it in sel:
                if it.truth == "none" and it.key in decided:
                    others.add(it.truth, decided[it.key])
            cells = [_cell(score(sel, decided, noise=n)) for n in noises]
            lines.append(f"| {kind} | " + " | ".join(cells) + f" | {_fa(others)} |")
        lines.append("")
    return lines


def _previous_sections() -> dict[str, tuple[list[str], str]]:
    """engine -> (its "### engine" section, its Timing row) in the generated part of the current DOC.

    Caches are local files: a report run without one engine's cache keeps that engine's results
    as last written (with their date in the summary) instead of dropping them.
    """
    if not DOC.is_file():
        return {}
    _, _, rest = DOC.read_text(encoding="utf-8").partition(BEGIN)
    block = rest.partition(END)[0].splitlines()
    out: dict[str, tuple[list[str], str]] = {}
    current: str | None = None
    for line in block:
        if line.startswith("### "):
            current = line[4:].strip()
            out[current] = ([], "")
        elif line.startswith("## "):
            current = None
        if current is not None:
            out[current][0].append(line)
    for line in block:
        for engine, (section, _) in out.items():
            if line.startswith(f"| {engine} | "):
                out[engine] = (section, line)
    return {e: (sec, row) for e, (sec, row) in out.items() if not any("Not run" in x for x in sec)}


def _sweep_scores(ranked, max_d: float, margin: float) -> tuple[Score, Score]:
    """Decisions under one (max_distance, min_margin) from precomputed rankings: dev and real scores."""
    dev, real = Score(), Score()
    for it, r in ranked:
        got = "none"
        if r.best is not None and not r.reason and r.best.distance <= max_d + 1e-9:
            gap = math.inf if r.rival is None else r.rival.distance - r.best.distance
            if gap >= margin:
                got = r.best.phrase.action
        (real if it.split == "real" else dev).add(it.truth, got)
    return dev, real


def tune(engines: list[str], matchers: list[str], items: list[Item]) -> None:
    """Sweep max_distance x min_margin x min_confidence on the dev split + real voices; print the best."""
    dictionaries = {lang: load_language(lang) for lang in LANGS}
    items = [it for it in items if it.split in ("dev", "real")]
    for engine in engines:
        if engine.endswith("-score"):  # phrases scored by the engine: its own rejection settings
            for m in matchers:
                tune_scored(engine, m, items, CACHE_DIR / "tune")
            continue
        cache = fresh_cache(engine, items)
        cached = [it for it in items if it.key in cache]
        if not cached:
            continue
        for m in matchers:
            matcher = get_matcher(m)
            has_conf = any(h[1] is not None for it in cached for h in cache[it.key]["hypotheses"])
            recs = [(it, recognition(engine, cache[it.key])) for it in cached]
            rows = []
            for min_conf in (0.0, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7) if has_conf else (0.0,):
                limits = {**matcher.thresholds(engine), "min_confidence": min_conf}
                ranked = [(it, matcher.rank(rec, [dictionaries[it.lang]], limits)) for it, rec in recs]
                for max_d, margin in itertools.product(np.arange(0.0, 0.71, 0.05), (0.0, 0.05, 0.1, 0.15, 0.2)):
                    dev, real = _sweep_scores(ranked, max_d, margin)
                    ok = not dev.pct("false_accept") > 2.0 and real.false_accept <= 1
                    objective = (_z(dev.pct("right")) + _z(real.pct("right"))
                                 - 3 * (_z(dev.pct("wrong")) + _z(real.pct("wrong")))
                                 - 2 * (_z(dev.pct("false_accept")) + _z(real.pct("false_accept"))))
                    rows.append((ok, objective, max_d, margin, min_conf, dev, real))
            rows.sort(key=lambda r: (not r[0], -r[1]))
            print(f"\n{engine} + {m}: (meets FA limits?) max_distance min_margin min_confidence | "
                  f"dev right/wrong/rej FA | real right/wrong/rej acted-on-non-command")
            for ok, obj, max_d, margin, min_conf, dev, real in rows[:8]:
                print(f"  {'ok ' if ok else 'no '} {max_d:.2f} {margin:.2f} {min_conf:.1f} | {dev.pct('right'):5.1f} "
                      f"{dev.pct('wrong'):5.1f} {dev.pct('rejected'):5.1f} {dev.pct('false_accept'):5.1f} | "
                      f"{real.right}/{real.wrong}/{real.rejected} {real.false_accept}/{real.n_ood}  obj {obj:.1f}")


#: Whisper score-mode rejection setting swept by ``tune_scored`` on the synthetic corpus (a regression
#: check: the shipped value is chosen on real speakers by ``python -m tools.speech.bench_real tune``).
SCORED_GRID = {
    ("evidence", "min_margin"): (-1.5, -1.2, -1.0, -0.9, -0.8, -0.7, -0.6, -0.5, -0.4, -0.3),
}


def _toml(table: dict, prefix: str = "") -> str:
    """A nested dict of numbers as TOML (enough for thresholds.toml)."""
    scalars = [f"{k} = {v!r}" for k, v in table.items() if not isinstance(v, dict)]
    out = ([f"[{prefix}]"] if prefix and scalars else []) + scalars
    for k, v in table.items():
        if isinstance(v, dict):
            out.append(_toml(v, f"{prefix}.{k}" if prefix else k))
    return "\n".join(out) + "\n"


def tune_scored(engine: str, matcher_name: str, items: list[Item], workdir: Path) -> None:
    """Sweep the score-mode rejection settings (SCORED_GRID) on the dev split + real voices."""
    import tomllib

    from gcs_voice.understanding.thresholds import THRESHOLDS_PATH

    dictionaries = {lang: load_language(lang) for lang in LANGS}
    cache = fresh_cache(engine, items)
    cached = [(it, recognition(engine, cache[it.key])) for it in items
              if it.split in ("dev", "real") and it.key in cache]
    base = tomllib.loads(THRESHOLDS_PATH.read_text(encoding="utf-8"))
    workdir.mkdir(parents=True, exist_ok=True)
    rows = []
    for n, values in enumerate(itertools.product(*SCORED_GRID.values())):
        table = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
        for (section, key), value in zip(SCORED_GRID, values):
            table.setdefault(section, {})
            table[section] = dict(table[section])
            table[section][engine] = {**table[section].get(engine, {}), key: value}
        path = workdir / f"thresholds-{n}.toml"
        path.write_text(_toml(table), encoding="utf-8")
        matcher = get_matcher(matcher_name, thresholds_path=path)
        dev, real = Score(), Score()
        for it, rec in cached:
            got = matcher.decide(rec, [dictionaries[it.lang]]).action or "none"
            (real if it.split == "real" else dev).add(it.truth, got)
        ok = not dev.pct("false_accept") > 2.0 and real.false_accept <= 1
        objective = (_z(dev.pct("right")) + _z(real.pct("right")) - 3 * (_z(dev.pct("wrong")) + _z(real.pct("wrong")))
                     - 2 * (_z(dev.pct("false_accept")) + _z(real.pct("false_accept"))))
        rows.append((ok, objective, values, dev, real))
    rows.sort(key=lambda r: (not r[0], -r[1]))
    names = " ".join(key for _, key in SCORED_GRID)
    print(f"\n{engine} + {matcher_name}: (meets FA limits?) {names} | dev right/wrong/rej FA | real right/wrong/rej "
          f"acted-on-non-command  ({len(cached)} utterances)")
    for ok, obj, values, dev, real in rows[:10]:
        print(f"  {'ok ' if ok else 'no '} {' '.join(f'{v:g}' for v in values)} | {dev.pct('right'):5.1f} "
              f"{dev.pct('wrong'):5.1f} {dev.pct('rejected'):5.1f} {dev.pct('false_accept'):5.1f} | "
              f"{real.right}/{real.wrong}/{real.rejected} {real.false_accept}/{real.n_ood}  obj {obj:.1f}")
    table_path = workdir / f"{engine}-{matcher_name}.tsv"  # every setting, to look any of them up
    with table_path.open("w", encoding="utf-8") as f:
        f.write("\t".join(["meets_limits", *(key for _, key in SCORED_GRID), "dev_right", "dev_wrong", "dev_rejected",
                           "dev_commands", "dev_acted_on_non_commands", "dev_non_commands", "real_right", "real_wrong",
                           "real_rejected", "real_acted_on_non_commands", "objective"]) + "\n")
        for ok, obj, values, dev, real in rows:
            f.write("\t".join(str(x) for x in (ok, *values, dev.right, dev.wrong, dev.rejected, dev.n_cmd,
                                               dev.false_accept, dev.n_ood, real.right, real.wrong, real.rejected,
                                               real.false_accept, round(obj, 2))) + "\n")
    print(f"  every setting: {table_path}")


# -- paired stage: two or more engines on exactly the same files ---------------------------------------------
def paired(engines: list[str], matcher: str, items: list[Item], min_confidence: str) -> None:
    """One markdown table of ``matcher``'s decisions on the files every engine has cached (test split + real
    voices); ``min_confidence`` (comma-separated) adds the last engine once per value."""
    caches = {e: fresh_cache(e, items) for e in engines}
    both = [it for it in items if it.split in ("test", "real") and all(it.key in c for c in caches.values())]
    dictionaries = {lang: load_language(lang) for lang in ("en", "es")}
    decided = {e: decide_all(e, matcher, both, caches[e], dictionaries) for e in engines}
    last = engines[-1]
    for value in filter(None, min_confidence.split(",")):
        label = f"{last} min_confidence {value}"
        decided[label] = decide_all(last, matcher, both, caches[last], dictionaries,
                                    min_confidence=float(value))
    cells = sorted({(it.lang, it.noise) for it in both}, key=lambda c: (c[1] == "real", c))
    print("Cells: commands right / wrong class / rejected, non-commands acted on.\n")
    print("| lang | noise | n commands / non-commands | " + " | ".join(
        f"{e} + {matcher}" for e in decided) + " |")
    print("|---" * (3 + len(decided)) + "|")
    for lang, noise in cells:
        sel = [it for it in both if it.lang == lang and it.noise == noise]
        row = []
        for e in decided:
            s = score(sel, decided[e])
            row.append(f"**{s.right}** / {s.wrong} / {s.rejected}, {s.false_accept}/{s.n_ood}")
        s = score(sel, decided[engines[0]])
        print(f"| {lang} | {noise} | {s.n_cmd} / {s.n_ood} | " + " | ".join(row) + " |")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="stage", required=True)
    r = sub.add_parser("recognise", help="run engines over the corpus and real voices, cache hypotheses")
    r.add_argument("--engines", default="sphinx,whisper")
    r.add_argument("--corpus", type=Path, default=REPO / "corpus")
    r.add_argument("--noises", default="", help="only these noise labels (default: all)")
    r.add_argument("--split", default="", help="only this split (dev/test)")
    r.add_argument("--every", type=int, default=1, help="take every Nth file (subsample)")
    r.add_argument("--limit-s", type=float, default=None, help="stop an engine after this many seconds")
    r.add_argument("--no-real", action="store_true", help="skip ../shared/speech")
    for name in ("report", "tune"):
        q = sub.add_parser(name)
        q.add_argument("--engines", default="sphinx,whisper")
        q.add_argument("--matchers", default=",".join(MATCHERS))
        q.add_argument("--corpus", type=Path, default=REPO / "corpus")
    q = sub.add_parser("paired", help="engines on exactly the files all of them have cached (test split + real voices)")
    q.add_argument("engines", nargs="+")
    q.add_argument("--matcher", default=DEFAULT_MATCHER)
    q.add_argument("--corpus", type=Path, default=REPO / "corpus")
    q.add_argument("--min-confidence", default="", help="comma-separated values for the last engine")
    args = p.parse_args(argv)

    items = corpus_items(args.corpus)
    if args.stage == "recognise":
        if args.noises:
            items = [it for it in items if it.noise in args.noises.split(",")]
        if args.split:
            items = [it for it in items if it.split == args.split]
        if not args.no_real:
            items = real_items(SHARED / "speech") + items
        recognise(args.engines.split(","), items, args.limit_s, args.every)
        return 0
    items = real_items(SHARED / "speech") + items
    if args.stage == "paired":
        paired(args.engines, args.matcher, items, args.min_confidence)
    elif args.stage == "tune":
        tune(args.engines.split(","), args.matchers.split(","), items)
    else:
        report(args.engines.split(","), args.matchers.split(","), items)
    return 0


if __name__ == "__main__":
    sys.exit(main())
