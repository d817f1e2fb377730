"""Draw one flight as a PNG: top view in the room, altitude and heading over time, commands marked.

Commands come from the session log (``.jsonl`` written beside the tlog by ``gcs-voice``) when there is
one, otherwise from the setpoints found in the tlog itself, so a tlog from any ground station plots.
Rooms are JSON data files read by ``rooms``, the one room reader the simulator uses too (the bridge never
imports ``sim_bridge``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import rooms
from gcs_voice.errors import GcsVoiceError
from gcs_voice.session.flight_log import Flight, read_flight, setpoint_action

__all__ = ["Room", "Box", "CommandMark", "load_room", "commands_from_session_log",
           "commands_from_setpoints", "plot_flight"]

#: Colour per action, so the same command looks the same in every panel and every plot.
ACTION_COLOURS = {
    "up": "tab:green", "down": "tab:brown", "go_right": "tab:orange", "go_left": "tab:purple",
    "go_forward": "tab:blue", "go_back": "tab:cyan", "turn_right": "tab:red", "turn_left": "tab:pink",
    "stop": "black", "take_off": "tab:olive", "land": "tab:gray", "arm": "tab:gray", "disarm": "tab:gray",
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


def commands_from_session_log(path: str | Path) -> list[CommandMark]:
    """Commands the bridge sent, from its JSON-lines session log (events of kind ``command``)."""
    marks: list[CommandMark] = []
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise PlotError(f"{path}: cannot read session log: {exc}") from None
    for line in lines:
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue  # a session cut short may leave half a line
        if isinstance(event, dict) and event.get("kind") == "command" and event.get("action"):
            heard = event.get("phrase") or ""
            marks.append(CommandMark(float(event["t"]), str(event["action"]), str(heard)))
    return marks


def rejections_from_session_log(path: str | Path) -> list[tuple[float, str]]:
    """(time, what was heard) of each utterance the matcher rejected (no action)."""
    out: list[tuple[float, str]] = []
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return out
    for line in lines:
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(event, dict) and event.get("kind") == "rejected":
            out.append((float(event["t"]), str(event.get("text") or "")))
    return out


def link_losses_from_session_log(path: str | Path) -> list[tuple[float, float | None]]:
    """(lost, back) UNIX times of each link loss in a session log; back is None if it never returned."""
    spans: list[tuple[float, float | None]] = []
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return spans
    for line in lines:
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue
        if not isinstance(event, dict) or event.get("kind") != "link":
            continue
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


def plot_flight(tlog: str | Path, out_png: str | Path, room: Room | None = None,
                session_log: str | Path | None = None, title: str | None = None) -> Path:
    """Render the flight in ``tlog`` to ``out_png`` and return its path."""
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
    if tr.t_s:
        east = [e + off_e for e in tr.east_m]
        north = [n + off_n for n in tr.north_m]
        top.plot(east, north, "-", color="tab:blue", lw=1.5, label="track")
        top.plot(east[0], north[0], "o", color="green", label="start")
        top.plot(east[-1], north[-1], "s", color="red", label="end")
        for mark in marks:
            pos = flight.position_at(mark.t_s)
            if pos is not None:
                xy = (pos[1] + off_e, pos[0] + off_n)
                top.plot(*xy, "^", color=ACTION_COLOURS.get(mark.action, "k"), ms=7)
                top.annotate(mark.action, xy, textcoords="offset points", xytext=(4, 4), fontsize=7)
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
    top.legend(loc="best", fontsize=8)
    top.set_title(f"top view{' - room ' + room.name if room else ''}")

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
    for mark in marks:
        colour = ACTION_COLOURS.get(mark.action, "k")
        for ax in (alt, hdg):
            ax.axvline(mark.t_s - t0, color=colour, lw=0.8, ls="--", alpha=0.7)
        alt.annotate(mark.action, (mark.t_s - t0, 1.0), xycoords=("data", "axes fraction"), rotation=90,
                     va="top", ha="right", fontsize=7, color=colour)
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
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png)
    plt.close(fig)
    return out_png
