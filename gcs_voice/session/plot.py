"""Draw one flight as a PNG: top view in the room, altitude and heading over time, commands marked.

Commands come from the session log (``.jsonl`` written beside the tlog by ``gcs-voice``) when there is
one, otherwise from the setpoints found in the tlog itself, so a tlog from any ground station plots.
Rooms are JSON data files read by ``rooms``, the one room reader the simulator uses too (the bridge never
imports ``sim_bridge``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import rooms
from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.collisions import parse_hit
from gcs_voice.session.flight_log import Flight, read_flight, setpoint_action
from gcs_voice.session.session_log import read_session_log

__all__ = ["Room", "Box", "CommandMark", "load_room", "commands_from_session_log",
           "commands_from_setpoints", "collisions_for_plot", "plot_flight", "draw_flight"]

#: nose arrows along the top-view track: one per this fraction of the drawn area's size travelled
NOSE_STEP_FRACTION = 0.06
#: and this long, as a fraction of the drawn area's size
NOSE_LENGTH_FRACTION = 0.035
#: command marks closer than this fraction of the drawn area's size share one label
GROUP_FRACTION = 0.04

#: Colour per action, so the same command looks the same in every panel and every plot.
ACTION_COLOURS = {
    "up": "tab:green", "down": "tab:brown", "go_right": "tab:orange", "go_left": "tab:purple",
    "go_forward": "tab:blue", "go_back": "tab:cyan", "turn_right": "tab:red", "turn_left": "tab:pink",
    "stop": "black", "take_off": "tab:olive", "land": "tab:gray", "arm": "tab:gray", "disarm": "tab:gray",
    "return_home": "gold",
}


class PlotError(GcsVoiceError):
    """A room or session-log file given to ``gcs-voice plot`` is unusable."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in the local NED frame, metres (north/east extents, heights above floor)."""

    name: str
    north_min_m: float
    north_max_m: float
    east_min_m: float
    east_max_m: float


@dataclass(frozen=True)
class Room:
    """A room in its own frame (x north, y east from a corner); ``start_*`` is where local NED (0, 0) is."""

    name: str
    bounds: Box | None
    boxes: tuple[Box, ...]
    start_north_m: float = 0.0
    start_east_m: float = 0.0


@dataclass(frozen=True)
class CommandMark:
    t_s: float
    action: str
    label: str


def load_room(name_or_path: str) -> Room:
    """A room by bundled name or file path, read by the one room reader (``rooms``); bad files raise PlotError."""
    try:
        room = rooms.load_room(name_or_path)
    except rooms.RoomError as exc:
        raise PlotError(str(exc)) from None
    (n_min, e_min, _), (n_max, e_max, _) = room.bounds_min_m, room.bounds_max_m
    bounds = Box("walls" if room.walls else "bounds", n_min, n_max, e_min, e_max)
    boxes = tuple(Box(b.name, b.min_m[0], b.max_m[0], b.min_m[1], b.max_m[1]) for b in room.blocks)
    return Room(room.name, bounds, boxes, room.start_xy_m[0], room.start_xy_m[1])


def _session_events(path: str | Path, kind: str, strict: bool = False) -> list[dict]:
    """The events of one kind in a session log (one reader: ``read_session_log``). An unreadable log is a
    PlotError when ``strict``, else no events (the plot is still drawn from the tlog)."""
    try:
        events = read_session_log(path)
    except (OSError, UnicodeDecodeError) as exc:
        if strict:
            raise PlotError(f"{path}: cannot read session log: {exc}") from None
        return []
    return [event for event in events if event.get("kind") == kind]


def commands_from_session_log(path: str | Path) -> list[CommandMark]:
    """Commands the bridge sent, from its JSON-lines session log (events of kind ``command``)."""
    return [CommandMark(float(event["t"]), str(event["action"]),
                        " ".join(filter(None, (str(event.get("phrase") or ""), str(event.get("amount") or "")))))
            for event in _session_events(path, "command", strict=True) if event.get("action")]


def rejections_from_session_log(path: str | Path) -> list[tuple[float, str]]:
    """(time, what was heard) of each utterance the matcher rejected (no action)."""
    return [(float(event["t"]), str(event.get("text") or "")) for event in _session_events(path, "rejected")]


def link_losses_from_session_log(path: str | Path) -> list[tuple[float, float | None]]:
    """(lost, back) UNIX times of each link loss in a session log; back is None if it never returned."""
    spans: list[tuple[float, float | None]] = []
    for event in _session_events(path, "link"):
        if event.get("state") == "lost":
            spans.append((float(event["t"]), None))
        elif event.get("state") == "restored" and spans and spans[-1][1] is None:
            spans[-1] = (spans[-1][0], float(event["t"]))
    return spans


def commands_from_setpoints(flight: Flight) -> list[CommandMark]:
    """One mark per change of setpoint, named by ``setpoint_action`` (no session log available)."""
    marks: list[CommandMark] = []
    for start, _end, sp in flight.segments():
        action = setpoint_action(sp, flight.heading_at(start))
        if marks and marks[-1].action == action:
            continue
        marks.append(CommandMark(start, action, ""))
    return marks


def collisions_for_plot(flight: Flight, session_log: str | Path | None) -> list[tuple[float, str]]:
    """(time, what was hit): the session log's collision events, else the tlog's "SIM Hit" texts that are
    not the ground (without the log, a touchdown cannot be told from a crash)."""
    if session_log is not None:
        return [(float(event["t"]), str(event.get("obstacle") or "?")) for event in _session_events(session_log, "collision")]
    hits = [(t, parse_hit(text)) for t, text in flight.statustexts]
    return [(t, hit.obstacle) for t, hit in hits if hit is not None and hit.obstacle.lower() != "ground"]


def _span(ax) -> float:
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return max(abs(x1 - x0), abs(y1 - y0), 1e-6)


def _draw_noses(ax, flight: Flight, marks: list[CommandMark], off_n: float, off_e: float) -> None:
    """The vehicle's nose (heading) as arrows along the track, and after each command, so overlapping legs
    still read: which way it faced and which way it went."""
    import math

    tr = flight.track
    span = _span(ax)
    step, length = NOSE_STEP_FRACTION * span, NOSE_LENGTH_FRACTION * span
    times, travelled = [tr.t_s[0]], 0.0
    for i in range(1, len(tr.t_s)):
        travelled += math.hypot(tr.north_m[i] - tr.north_m[i - 1], tr.east_m[i] - tr.east_m[i - 1])
        if travelled >= step:
            times.append(tr.t_s[i])
            travelled = 0.0
    ends = [m.t_s for m in marks[1:]] + [tr.t_s[-1]]
    times += [min(end, tr.t_s[-1]) - 0.05 for end in ends]  # the heading each command left the vehicle in
    xs, ys, us, vs, cs = [], [], [], [], []
    for t in sorted(times):
        pos, heading = flight.position_at(t), flight.heading_at(t)
        if pos is None or heading is None:
            continue
        xs.append(pos[1] + off_e)
        ys.append(pos[0] + off_n)
        us.append(length * math.sin(math.radians(heading)))
        vs.append(length * math.cos(math.radians(heading)))
        cs.append(t - flight.t0_s)
    if xs:
        # Coloured by time, so two legs over the same ground tell apart (early dark, late yellow).
        arrows = ax.quiver(xs, ys, us, vs, cs, cmap="viridis", angles="xy", scale_units="xy", scale=1.0,
                           width=0.005, headwidth=4, headlength=5, zorder=4, label="nose (heading)")
        arrows.set_clim(0.0, max(tr.t_s[-1] - flight.t0_s, 1.0))  # the time axis of the other panels
        bar = ax.figure.colorbar(arrows, ax=ax, orientation="horizontal", fraction=0.04, pad=0.09, aspect=40)
        bar.set_label("nose arrows: time (s)", fontsize=8)
        bar.ax.tick_params(labelsize=7)


def _draw_numbered_marks(fig, ax, flight: Flight, marks: list[CommandMark], hits: list[tuple[float, str]],
                         off_n: float, off_e: float) -> None:
    """Commands as numbered triangles (numbers as on the time panels) and collisions as red crosses; marks at
    the same spot share one label, and labels are moved until none overlaps another or leaves the axes."""
    span = _span(ax)
    points: list[tuple[float, float, str, str]] = []  # x, y, text, colour
    for n, mark in enumerate(marks, 1):
        pos = flight.position_at(mark.t_s)
        if pos is not None:
            xy = (pos[1] + off_e, pos[0] + off_n)
            ax.plot(*xy, "^", color=ACTION_COLOURS.get(mark.action, "k"), ms=7, zorder=5)
            points.append((xy[0], xy[1], f"{n} {mark.action}", "black"))
    for i, (t, what) in enumerate(hits):
        pos = flight.position_at(t)
        if pos is not None:
            xy = (pos[1] + off_e, pos[0] + off_n)
            ax.plot(*xy, "X", color="red", ms=11, mec="darkred", zorder=6, label="collision" if i == 0 else None)
            points.append((xy[0], xy[1], f"hit {what}", "red"))
    groups: list[list[tuple[float, float, str, str]]] = []
    for point in points:
        near = next((g for g in groups if abs(g[0][0] - point[0]) < GROUP_FRACTION * span
                     and abs(g[0][1] - point[1]) < GROUP_FRACTION * span and g[0][3] == point[3]), None)
        if near is None:
            groups.append([point])
        else:
            near.append(point)
    (x0, x1) = ax.get_xlim()
    labels = []
    for group in groups:
        x, y = group[0][0], group[0][1]
        text = "\n".join(p[2] for p in group)
        colour = "red" if any(p[3] == "red" for p in group) else "black"
        label = ax.annotate(text, (x, y), xytext=(14, 0), textcoords="offset points", ha="left", va="center",
                            fontsize=7, color=colour, zorder=7, annotation_clip=False,
                            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "lightgray", "alpha": 0.85},
                            arrowprops={"arrowstyle": "-", "color": "gray", "lw": 0.6})
        label.set_in_layout(False)  # kept inside the panel by _place; tight_layout must not make room for it
        labels.append((label, x < (x0 + x1) / 2))  # first try the side with more room
    _place(fig, ax, labels)


def _text_box(label, renderer):
    """A label's own box (its rounded frame included), without the leader line that Annotation adds."""
    from matplotlib.text import Text

    label.update_positions(renderer)  # where xyann puts it now (Text's own extent does not recompute that)
    return Text.get_window_extent(label, renderer).padded(3.0)


def _place(fig, ax, labels: list) -> None:
    """Put each label at the nearest offset (right or left of its point, then further up or down) where it
    overlaps no label placed before nor any labelled mark, and stays inside the axes; labels nearer the top
    are placed first."""
    from matplotlib.transforms import Bbox

    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    # the marks themselves (a collision's cross, a command's triangle) must stay visible too
    placed: list = [Bbox.from_bounds(*(ax.transData.transform(label.xy) - 7.0), 14.0, 14.0) for label, _ in labels]
    mine = {id(label) for label, _ in labels}
    placed += [t.get_window_extent(renderer) for t in ax.texts if id(t) not in mine]  # the room's furniture names
    candidates = [(side, 12.0 * i * sign) for i in range(0, 40) for sign in ((1, -1) if i else (1,))
                  for side in (0, 1)]
    order = sorted(labels, key=lambda item: -item[0].xy[1])
    for label, right_first in order:
        best, best_cost = None, None
        for side, dy in candidates:
            right = right_first if side == 0 else not right_first
            label.set_horizontalalignment("left" if right else "right")
            label.xyann = (14.0 if right else -14.0, dy)
            box = _text_box(label, renderer)
            outside = (max(0.0, frame.x0 - box.x0) + max(0.0, box.x1 - frame.x1)
                       + max(0.0, frame.y0 - box.y0) + max(0.0, box.y1 - frame.y1))
            overlap = sum(max(0.0, min(box.x1, b.x1) - max(box.x0, b.x0)) * max(0.0, min(box.y1, b.y1) - max(box.y0, b.y0))
                          for b in placed)
            cost = (outside * 1000 + overlap, abs(dy))
            if best_cost is None or cost < best_cost:
                best, best_cost = (right, dy), cost
            if outside == 0 and overlap == 0:
                break
        right, dy = best
        label.set_horizontalalignment("left" if right else "right")
        label.xyann = (14.0 if right else -14.0, dy)
        placed.append(_text_box(label, renderer))


def _spread(fig, labels: list) -> None:
    """Move the time panels' command labels right (by their offset in points) until no two overlap."""
    renderer = fig.canvas.get_renderer()
    points_per_px = 72.0 / fig.dpi
    placed = []
    for label in sorted(labels, key=lambda a: _text_box(a, renderer).x0):
        for _ in range(60):
            box = _text_box(label, renderer)
            clash = next((b for b in placed if box.overlaps(b)), None)
            if clash is None:
                break
            ox, oy = label.xyann
            label.xyann = (ox + (clash.x1 - box.x0 + 1) * points_per_px, oy)
        placed.append(_text_box(label, renderer))


def plot_flight(tlog: str | Path, out_png: str | Path, room: Room | None = None,
                session_log: str | Path | None = None, title: str | None = None) -> Path:
    """Render the flight in ``tlog`` to ``out_png`` and return its path."""
    import matplotlib.pyplot as plt

    fig = draw_flight(tlog, room, session_log, title)
    out_png = Path(out_png)
    try:
        out_png.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(out_png)
    except OSError as exc:
        raise PlotError(f"cannot write {out_png}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
    return out_png


def draw_flight(tlog: str | Path, room: Room | None = None, session_log: str | Path | None = None,
                title: str | None = None):
    """The figure of ``plot_flight`` (a matplotlib Figure; the caller closes it): axes 0 is the top view."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    flight = read_flight(tlog)
    if session_log is None:
        beside = Path(tlog).with_suffix(".jsonl")
        session_log = beside if beside.is_file() else None
    marks = commands_from_session_log(session_log) if session_log else commands_from_setpoints(flight)
    t0 = flight.t0_s
    tr = flight.track

    fig = plt.figure(figsize=(13, 7.5), dpi=100)
    grid = fig.add_gridspec(2, 2, width_ratios=(1.1, 1.4))
    top = fig.add_subplot(grid[:, 0])
    alt = fig.add_subplot(grid[0, 1])
    hdg = fig.add_subplot(grid[1, 1], sharex=alt)

    # Top view: east to the right, north up, as on a map; in room coordinates when a room is drawn
    # (the vehicle's local NED origin is the room's start position).
    off_n, off_e = (room.start_north_m, room.start_east_m) if room is not None else (0.0, 0.0)
    if room is not None:
        if room.bounds is not None:
            b = room.bounds
            top.add_patch(Rectangle((b.east_min_m, b.north_min_m), b.east_max_m - b.east_min_m,
                                    b.north_max_m - b.north_min_m, fill=False, lw=2, ec="dimgray"))
        for box in room.boxes:
            top.add_patch(Rectangle((box.east_min_m, box.north_min_m), box.east_max_m - box.east_min_m,
                                    box.north_max_m - box.north_min_m, fc="lightgray", ec="gray"))
            top.annotate(box.name, ((box.east_min_m + box.east_max_m) / 2, (box.north_min_m + box.north_max_m) / 2),
                         ha="center", va="center", fontsize=7, color="dimgray")
    hits = collisions_for_plot(flight, session_log)
    if tr.t_s:
        east = [e + off_e for e in tr.east_m]
        north = [n + off_n for n in tr.north_m]
        top.plot(east, north, "-", color="tab:blue", lw=1.5, label="track")
        top.plot(east[0], north[0], "o", color="green", label="start")
        top.plot(east[-1], north[-1], "s", color="red", label="end")
    zoomed = False
    if tr.t_s and room is not None and room.bounds is not None:
        # A big room (an open field) would shrink the track to a dot: frame the track instead.
        b = room.bounds
        span_track = max(max(east) - min(east), max(north) - min(north), 2.0)
        if max(b.north_max_m - b.north_min_m, b.east_max_m - b.east_min_m) > 4 * span_track + 10:
            half = 0.5 * span_track + 0.25 * span_track + 1.0
            mid_e, mid_n = (max(east) + min(east)) / 2, (max(north) + min(north)) / 2
            top.set_xlim(mid_e - half, mid_e + half)
            top.set_ylim(mid_n - half, mid_n + half)
            zoomed = True
    frame = "room" if room is not None else "local"
    top.set_xlabel(f"east (m, {frame})")
    top.set_ylabel(f"north (m, {frame})")
    top.set_aspect("equal", adjustable="box" if zoomed else "datalim")
    top.grid(alpha=0.3)
    if tr.t_s:
        _draw_noses(top, flight, marks, off_n, off_e)
        _draw_numbered_marks(fig, top, flight, marks, hits, off_n, off_e)
    # Above the panel, not in it: labels are placed around the track and must not hide under the legend.
    top.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=5, fontsize=7, frameon=False,
               handlelength=1.5, columnspacing=1.0)
    top.set_title(f"top view{' - room ' + room.name if room else ''}", pad=24)

    if tr.t_s:
        alt.plot([t - t0 for t in tr.t_s], tr.alt_m, color="tab:blue")
    alt.set_ylabel("altitude (m)")
    alt.grid(alpha=0.3)
    if flight.heading_t_s:
        import numpy as np

        # Unwrapped, so a turn through north is a step and not a jump of 360 deg.
        unwrapped = np.degrees(np.unwrap(np.radians(flight.heading_deg)))
        unwrapped -= 360.0 * round(float(unwrapped[0]) / 360.0)  # start near 0, not near 360
        hdg.plot([t - t0 for t in flight.heading_t_s], unwrapped, "-", lw=1.2, color="tab:red")
        low, high = float(unwrapped.min()), float(unwrapped.max())
        hdg.set_yticks(range(int(low // 90) * 90, int(high // 90) * 90 + 91, 90))
    hdg.set_ylabel("heading (deg, unwrapped)")
    hdg.set_xlabel("time (s)")
    hdg.grid(alpha=0.3)
    time_labels = []
    for n, mark in enumerate(marks, 1):
        colour = ACTION_COLOURS.get(mark.action, "k")
        for ax in (alt, hdg):
            ax.axvline(mark.t_s - t0, color=colour, lw=0.8, ls="--", alpha=0.7)
        time_labels.append(alt.annotate(f"{n} {mark.action}", (mark.t_s - t0, 1.0), xycoords=("data", "axes fraction"),
                                        xytext=(0, 3), textcoords="offset points", rotation=90, va="bottom",
                                        ha="center", fontsize=7, color=colour, annotation_clip=False))
    for i, (t, what) in enumerate(hits):
        for ax in (alt, hdg):
            ax.axvline(t - t0, color="red", lw=1.6, label="collision" if i == 0 and ax is hdg else None)
        time_labels.append(alt.annotate(f"hit {what}", (t - t0, 1.0), xycoords=("data", "axes fraction"),
                                        xytext=(0, 3), textcoords="offset points", rotation=90, va="bottom",
                                        ha="center", fontsize=7, color="red", fontweight="bold",
                                        annotation_clip=False))
    if hits:
        hdg.legend(loc="lower right", fontsize=8)
    t_end = max(tr.t_s[-1] if tr.t_s else t0, flight.heading_t_s[-1] if flight.heading_t_s else t0)
    for i, (lost, back) in enumerate(link_losses_from_session_log(session_log) if session_log else []):
        for ax in (alt, hdg):
            ax.axvspan(lost - t0, (back or t_end) - t0, color="red", alpha=0.12,
                       label="link lost" if i == 0 and ax is alt else None)
        alt.legend(loc="lower right", fontsize=8)
    rejected = rejections_from_session_log(session_log) if session_log else []
    for i, (t, text) in enumerate(rejected):
        alt.plot(t - t0, 0.0, "x", color="dimgray", ms=8, label="rejected (no action)" if i == 0 else None)
        alt.annotate(f'"{text}"' if text else "(nothing heard)", (t - t0, 0.0), textcoords="offset points",
                     xytext=(3, 6), fontsize=7, color="dimgray", rotation=45)
    if rejected:
        alt.legend(loc="lower right", fontsize=8)
    source = "session log" if session_log else "setpoints in the tlog"
    fig.suptitle(title or f"{Path(tlog).name} (commands from the {source})", fontsize=11)
    fig.tight_layout()
    _spread(fig, time_labels)  # commands close in time: side by side, not on top of each other
    fig.tight_layout()
    if tr.t_s:  # tight_layout moved the axes: place the top view's labels again where they fit now
        top.apply_aspect()  # ("datalim" moves the limits at draw time: settle them first)
        _place(fig, top, [(a, a.get_horizontalalignment() == "left") for a in top.texts if a.get_bbox_patch()])
    return fig
