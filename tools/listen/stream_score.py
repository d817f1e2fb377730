"""What a stream's segments did, utterance by utterance: commands right, wrong and missed, false actions, the
longest deaf stretch, the level the segmenter heard and the loud-room hint (``python -m tools.listen.bench_stream``'s
counts, on streams of tools/listen/streams.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_voice.session.listen import loud_room_hint
from tools.listen.streams import RATE, Placed


@dataclass
class Counts:
    segments: int = 0
    commands: int = 0
    right: int = 0
    wrong: int = 0
    wrong_stop: int = 0  # of the wrong: a stop where a motion was said (the vehicle held; it did not go astray)
    missed: int = 0
    unsegmented: int = 0  # missed commands that produced no segment at all
    others: int = 0  # non-command utterances
    false_speech: int = 0  # actions during non-command speech
    false_noise: int = 0  # actions during noise alone
    minutes: float = 0.0
    deaf_s: float = 0.0  # the longest deaf stretch (see tools/listen/bench_stream.py's docstring)


#: speech at least this far above the noise around it must be heard (the deaf-stretch rule)
AUDIBLE_DB = 10.0


def overlaps(a0: float, a1: float, b0: float, b1: float) -> bool:
    return min(a1, b1) - max(a0, b0) > 0


def local_snr_db(speech: np.ndarray, noise: np.ndarray | None, p: Placed) -> float:
    """The utterance's voiced level over the noise's level around it (its voiced span and 0.5 s either side)."""
    if noise is None:
        return float("inf")
    v0, v1 = int(p.voiced_start_s * RATE), int(p.voiced_end_s * RATE)
    s_rms = float(np.sqrt(np.mean(speech[v0:v1] ** 2) + 1e-12))
    n_rms = float(np.sqrt(np.mean(noise[max(0, v0 - RATE // 2):v1 + RATE // 2] ** 2) + 1e-12))
    return 20 * np.log10(s_rms / n_rms)


def deaf_stretch_s(placed: list[Placed], heard: list[bool], audible: list[bool]) -> float:
    """Longest time over which audible utterances produced no segment and nothing said between them did either.

    A quieter utterance missed in between does not end the stretch (nor start one); one heard, however quiet,
    does: the segmenter was listening."""
    longest, run_start = 0.0, None
    for p, h, a in zip(placed, heard, audible):
        if h:
            run_start = None
            continue
        if not a:
            continue
        run_start = p.voiced_start_s if run_start is None else run_start
        longest = max(longest, p.voiced_end_s - run_start)
    return longest


def owner_of(row: dict, placed: list[Placed]) -> int | None:
    """The utterance a segment overlaps most (None: it lies on noise alone)."""
    best, overlap = None, 0.0
    for i, p in enumerate(placed):
        o = min(row["end_s"], p.end_s) - max(row["start_s"], p.start_s)
        if o > overlap:
            best, overlap = i, o
    return best


def score(rows: list[dict], placed: list[Placed], total_s: float,
          audible: list[bool] | None = None) -> Counts:
    """Give each segment to the utterance it overlaps most (none: noise alone) and count the outcomes.

    ``audible``: which utterances the deaf-stretch rule counts (default: all)."""
    c = Counts(segments=len(rows), minutes=total_s / 60)
    actions: dict[int, list[str]] = {i: [] for i in range(len(placed))}
    for row in rows:
        best = owner_of(row, placed)
        if row.get("action"):
            if best is None:
                c.false_noise += 1
            else:
                actions[best].append(row["action"])
    heard = [any(overlaps(r["start_s"], r["end_s"], p.voiced_start_s, p.voiced_end_s) for r in rows) for p in placed]
    for i, p in enumerate(placed):
        got = actions[i]
        if p.clip.action is None:
            c.others += 1
            c.false_speech += len(got)
        else:
            c.commands += 1
            if any(a != p.clip.action for a in got):
                c.wrong += 1
                c.wrong_stop += all(a in (p.clip.action, "stop") for a in got)
            elif got:
                c.right += 1
            else:
                c.missed += 1
                c.unsegmented += not heard[i]
    c.deaf_s = deaf_stretch_s(placed, heard, audible if audible is not None else [True] * len(placed))
    return c


def outcomes(rows: list[dict], placed: list[Placed]) -> list[str]:
    """One TSV line per utterance (and per segment over noise alone): what was said, what the segments heard,
    what acted and why not, so that a wrong or missed command can be looked at, not only counted."""
    owner: dict[int | None, list[dict]] = {}
    for row in rows:
        owner.setdefault(owner_of(row, placed), []).append(row)
    lines = ["index\tstart_s\ttruth\toutcome\tactions\theard\treasons\tpath"]
    for i, p in enumerate([*placed, None]):
        got = owner.get(None if p is None else i, [])
        if p is None and not got:
            continue
        acts = [r["action"] for r in got if r.get("action")]
        truth = "noise" if p is None else (p.clip.action or "none")
        if p is None or p.clip.action is None:
            outcome = "false action" if acts else "ignored"
        else:
            # "no segment" as score() counts it: no segment overlaps the utterance's speech at all
            cut = any(overlaps(r["start_s"], r["end_s"], p.voiced_start_s, p.voiced_end_s) for r in rows)
            outcome = "wrong" if any(a != p.clip.action for a in acts) else "right" if acts else \
                ("missed" if cut else "no segment")
        heard = " | ".join(r.get("transcript") or r.get("text") or "" for r in got)
        reasons = " | ".join(r.get("reason", "") for r in got if r.get("reason"))
        lines.append("\t".join([str(i) if p else "-", f"{p.start_s:.2f}" if p else
                                 ",".join(f"{r['start_s']:.2f}" for r in got), truth, outcome, ",".join(acts),
                                 heard, reasons, str(p.clip.path) if p else ""]))
    return lines


def pct(n: int, d: int) -> str:
    return f"{100 * n / d:.1f} % ({n}/{d})" if d else "-"


@dataclass(frozen=True)
class HeardLevel:
    """One utterance: how far the segmenter heard its voice above the room (its first segment's ``snr_db``; None
    when not segmented or no room was heard before it), how far it truly was (``local_snr_db``), what came of it."""

    heard_db: float | None
    true_db: float
    command: bool
    outcome: str  # right / wrong / missed (commands); acted / ignored (other speech)


def heard_levels(rows: list[dict], placed: list[Placed], true_db: list[float]) -> list[HeardLevel]:
    owner: dict[int | None, list[dict]] = {}
    for row in rows:
        owner.setdefault(owner_of(row, placed), []).append(row)
    out = []
    for i, p in enumerate(placed):
        got = owner.get(i, [])
        heard = next((r["snr_db"] for r in got if r.get("snr_db") is not None), None)
        acts = [r["action"] for r in got if r.get("action")]
        if p.clip.action is None:
            outcome = "acted" if acts else "ignored"
        else:
            outcome = "wrong" if any(a != p.clip.action for a in acts) else "right" if acts else "missed"
        out.append(HeardLevel(heard, true_db[i], p.clip.action is not None, outcome))
    return out


#: the bins of the SNR the segmenter heard, dB (issue 30: what a "the room is loud" hint can go by)
LEVEL_BINS = (6.0, 10.0, 14.0, 18.0)


def levels_report(levels: list[HeardLevel], limit_db: float) -> list[str]:
    """Commands right and other speech acted on by the SNR the segmenter heard; and how near it was to the truth."""
    edges = [-np.inf, *LEVEL_BINS, np.inf]
    names = [f"below {LEVEL_BINS[0]:g}", *(f"{a:g} to {b:g}" for a, b in zip(LEVEL_BINS, LEVEL_BINS[1:])),
             f"{LEVEL_BINS[-1]:g} and above"]
    lines = ["| voice over the room, as heard (dB) | commands right | wrong | other speech acted on |",
             "|---|---|---|---|"]
    seen = [h for h in levels if h.heard_db is not None]
    for name, lo, hi in zip(names, edges, edges[1:]):
        group = [h for h in seen if lo <= h.heard_db < hi]
        commands = [h for h in group if h.command]
        others = [h for h in group if not h.command]
        lines.append(f"| {name} | {pct(sum(h.outcome == 'right' for h in commands), len(commands))} | "
                     f"{sum(h.outcome == 'wrong' for h in commands)} | "
                     f"{pct(sum(h.outcome == 'acted' for h in others), len(others))} |")
    below = [h for h in seen if h.command and h.heard_db < limit_db]
    above = [h for h in seen if h.command and h.heard_db >= limit_db]
    error = np.array([h.heard_db - h.true_db for h in seen if np.isfinite(h.true_db)])
    lines += ["", f"Commands heard less than `loud_room_snr_db` = {limit_db:g} dB above the room (gcs_voice/audio/vad.toml: "
              "a rejection of such a voice tells the pilot the room is loud): "
              f"{pct(sum(h.outcome == 'right' for h in below), len(below))} right; at or above it "
              f"{pct(sum(h.outcome == 'right' for h in above), len(above))}."]
    if error.size:
        lines.append(f"The SNR as heard, less the true one (the voiced level over the noise in the utterance's span and "
                     f"0.5 s either side): median {np.median(error):+.1f} dB, 10th to 90th percentile "
                     f"{np.percentile(error, 10):+.1f} to {np.percentile(error, 90):+.1f} dB (n = {error.size}; the "
                     "recordings' own background, which the true figure leaves out, counts as room).")
    return lines


#: what was said, in the order the hint's table gives it
KINDS = {"command": "commands", "word": "non-command words", "sentence": "sentences", "noise": "noise alone"}


def hint_tally(rows: list[dict], placed: list[Placed], limit_db: float, repeat_s: float,
               min_margin: float = -float("inf")) -> dict[tuple[str, str], int]:
    """Rejected segments whose voice stood less than ``limit_db`` above the room, by what was said: how many
    (``loud``), how many the pilot is told the room is loud (``hint``: gcs_voice.session.listen.loud_room_hint), and
    how many of those it says aloud (``said``: at most every ``repeat_s`` of the stream); ``said_any``: aloud if every
    such rejection were told (session 33's rule)."""
    tally: dict[tuple[str, str], int] = {}
    said_t = said_any_t = -float("inf")
    for row in sorted(rows, key=lambda r: r["end_s"]):
        if row.get("action") or row.get("snr_db") is None or row["snr_db"] >= limit_db:
            continue
        owner = owner_of(row, placed)
        kind = "noise" if owner is None else placed[owner].clip.kind
        tally[kind, "loud"] = tally.get((kind, "loud"), 0) + 1
        if row["end_s"] - said_any_t >= repeat_s:
            said_any_t = row["end_s"]
            tally[kind, "said_any"] = tally.get((kind, "said_any"), 0) + 1
        if loud_room_hint(row["snr_db"], limit_db, bool(row.get("went_on")), row.get("extra", {}).get("margin"),
                          min_margin):
            tally[kind, "hint"] = tally.get((kind, "hint"), 0) + 1
            if row["end_s"] - said_t >= repeat_s:
                said_t = row["end_s"]
                tally[kind, "said"] = tally.get((kind, "said"), 0) + 1
    return tally


def hint_report(tally: dict[tuple[str, str], int], minutes: float, limit_db: float, repeat_s: float) -> list[str]:
    """The hint's table: for what it was said, and how often aloud."""
    lines = [f"What a rejection of a voice less than {limit_db:g} dB above the room says, by what was said: the hint "
             "(\"the room is loud ...; speak up\") on the pilot's screen, and \"too noisy\" aloud at most every "
             f"{repeat_s:g} s of the stream (gcs_voice/session/listen.py `loud_room_hint`: not for talk that went on "
             "past a command's words, nor when no command phrase came within `loud_room_min_margin` of what Whisper "
             "heard).", "",
             "| what was said | rejected below the limit | the hint shown | said aloud | said aloud if every one were told |",
             "|---|---|---|---|---|"]
    for kind, name in KINDS.items():
        lines.append(f"| {name} | {tally.get((kind, 'loud'), 0)} | {tally.get((kind, 'hint'), 0)} | "
                     f"{tally.get((kind, 'said'), 0)} | {tally.get((kind, 'said_any'), 0)} |")
    said = sum(v for (k, stage), v in tally.items() if stage == "said")
    said_any = sum(v for (k, stage), v in tally.items() if stage == "said_any")
    lines += ["", f"Said aloud {said} times in {minutes:.0f} minutes of noisy streams ({said / minutes:.2f} a minute; "
              f"{said_any} if every one were told, session 33's rule)."]
    return lines
