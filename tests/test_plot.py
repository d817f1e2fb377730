"""``gcs-voice plot`` on real autopilot captures: a PNG, and the commands read back from the setpoints."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from gcs_voice.session.flight_log import read_flight
from gcs_voice.session.plot import PlotError, commands_from_session_log, commands_from_setpoints, load_room, plot_flight

REPO = Path(__file__).resolve().parent.parent


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    return struct.unpack(">II", data[16:24])


def test_commands_from_arducopter_setpoints(tlogs_dir: Path) -> None:
    flight = read_flight(tlogs_dir / "arducopter-sitl-guided-velocity.tlog")
    assert len(flight.setpoints) == 330  # ARDUCOPTER.md: 330 SET_POSITION_TARGET_LOCAL_NED from the GCS
    actions = [m.action for m in commands_from_setpoints(flight)]
    # The segments of tlogs/README.md: forward, hold, right, hold, yaw +90, climb, descend, hold, forward
    # (now facing east), then LOCAL_NED south while facing east = to the vehicle's right.
    assert actions == ["go_forward", "stop", "go_right", "stop", "turn_right", "up", "down", "stop",
                       "go_forward", "go_right"]
    # The vehicle really went north then east: 3.3 m in 4 s forward, per the capture's notes.
    north_end = max(flight.track.north_m)
    assert 3.5 < north_end < 4.5


def test_plot_cli_writes_png(tlogs_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "ac.png"
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "plot", str(tlogs_dir / "arducopter-sitl-guided-velocity.tlog"),
                           "-o", str(out)], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    width, height = _png_size(out)
    assert (width, height) == (1300, 750)
    assert out.stat().st_size > 30_000  # a drawn figure, not an empty canvas


def test_plot_px4_with_room_and_session_log(tlogs_dir: Path, tmp_path: Path) -> None:
    tlog = tlogs_dir / "px4-sih-offboard-velocity.tlog"
    flight = read_flight(tlog)
    room_file = tmp_path / "room.json"
    room_file.write_text(json.dumps({
        "name": "test room", "bounds": {"extents": [0, 10, 0, 8, 0, 3]}, "start": {"pos_m": [2.0, 3.0]},
        "blocks": [{"name": "table", "extents": [5, 6, 1, 2, 0, 1]}]}))
    room = load_room(str(room_file))
    assert (room.start_north_m, room.start_east_m) == (2.0, 3.0)
    assert room.boxes[0].name == "table"
    session = tmp_path / "s.jsonl"
    t = flight.setpoints[0].t_s
    session.write_text("\n".join(json.dumps(r) for r in [
        {"t": t, "kind": "heard", "msg": "x", "text": "go forward"},
        {"t": t + 5, "kind": "command", "msg": "x", "action": "go_forward", "phrase": "go forward"},
        {"t": t + 11, "kind": "command", "msg": "x", "action": "turn_right", "phrase": "turn right"},
    ]) + "\n{\"t\": 1, \"kind\": \"comm")  # a half-written last line, as after a crash
    assert [m.action for m in commands_from_session_log(session)] == ["go_forward", "turn_right"]
    out = plot_flight(tlog, tmp_path / "px4.png", room=room, session_log=session)
    assert _png_size(out) == (1300, 750)


def test_bundled_room_by_name(tmp_path: Path) -> None:
    room = load_room("living_room")
    assert room.bounds is not None and room.bounds.north_max_m > room.bounds.north_min_m
    assert len(room.boxes) >= 1


def test_bad_inputs_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(PlotError, match="nowhere.json: no such room file"):
        load_room("nowhere")
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    with pytest.raises(PlotError, match="not valid JSON"):
        load_room(str(bad))
    not_tlog = tmp_path / "x.tlog"
    not_tlog.write_bytes(b"hello, this is not MAVLink" * 10)
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "plot", str(not_tlog)], cwd=REPO,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("gcs-voice: error:")
    assert "Traceback" not in proc.stderr


def test_unwritable_outputs_are_one_line(tlogs_dir: Path, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    for cmd in (["plot", str(tlogs_dir / "px4-sih-offboard-velocity.tlog"), "-o", str(blocker / "x.png")],
                ["demo", "--lang", "en", "--out", str(blocker / "out")]):
        proc = subprocess.run([sys.executable, "-m", "gcs_voice", *cmd], cwd=REPO, capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.startswith("gcs-voice: error:") and proc.stderr.count("\n") == 1, proc.stderr
        assert str(blocker) in proc.stderr


def _overlaps(boxes: list) -> list[tuple[int, int]]:
    return [(i, j) for i in range(len(boxes)) for j in range(i + 1, len(boxes)) if boxes[i].overlaps(boxes[j])]


def test_top_view_reads_where_legs_overlap(tlogs_dir: Path, tmp_path: Path) -> None:
    """Ten commands and a collision, most of them at the same few spots: numbered labels that neither
    overlap nor leave their panel, the nose drawn along the track, the collision marked in every panel."""
    import matplotlib.pyplot as plt
    from matplotlib.quiver import Quiver
    from matplotlib.text import Text

    from gcs_voice.session.plot import draw_flight

    tlog = tlogs_dir / "arducopter-sitl-guided-velocity.tlog"
    flight = read_flight(tlog)
    marks = commands_from_setpoints(flight)
    t0 = flight.setpoints[0].t_s
    records = [{"t": m.t_s, "kind": "command", "msg": "x", "action": m.action} for m in marks]
    records += [{"t": m.t_s + 0.2, "kind": "command", "msg": "x", "action": "stop"} for m in marks[:4]]
    hit_t = marks[3].t_s + 1.0
    records.append({"t": hit_t, "kind": "collision", "msg": "COLLISION: the vehicle hit table", "obstacle": "table"})
    session = tmp_path / "s.jsonl"
    session.write_text("\n".join(json.dumps(r) for r in sorted(records, key=lambda r: r["t"])) + "\n")
    assert t0 <= hit_t
    fig = draw_flight(tlog, session_log=session)
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        top, alt = fig.axes[0], fig.axes[1]
        # nose arrows along the track
        noses = [c for c in top.collections if isinstance(c, Quiver)]
        assert noses and noses[0].N >= len(marks)
        # top-view labels: every command numbered once, none overlapping another, none outside the panel
        labels = [t for t in top.texts if t.get_bbox_patch() is not None]
        text = "\n".join(t.get_text() for t in labels)
        for n in range(1, len(marks) + 5):
            assert f"\n{n} " in "\n" + text, n
        boxes = [Text.get_window_extent(t, renderer) for t in labels]  # the text, not its leader line
        assert _overlaps(boxes) == []
        frame = top.get_window_extent(renderer)
        for box in boxes:
            assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
        # the collision: a red cross in the top view, a labelled line in the time panels
        assert "hit table" in text
        assert any(line.get_label() == "collision" for line in top.lines)
        time_labels = [t for t in alt.texts if t.get_rotation() == 90]
        assert any(t.get_text() == "hit table" for t in time_labels)
        assert _overlaps([Text.get_window_extent(t, renderer) for t in time_labels]) == []
        figure_box = fig.bbox
        for t in time_labels:  # nothing clipped by the figure's edge
            box = Text.get_window_extent(t, renderer)
            assert figure_box.y0 <= box.y0 and box.y1 <= figure_box.y1
    finally:
        plt.close(fig)
