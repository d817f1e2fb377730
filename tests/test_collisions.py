"""A flight that hits something says so and fails: the session's exit status, its log, the demo's summary.

The fast tests feed the bus the texts the simulator really sends (sim_bridge/mavlink_server.py,
``_physics_texts``; ArduPilot SITL's "SIM Hit ground" at every touchdown, ../shared/tlogs/README.md).
The slow ones fly the real simulator into a wall and a cabinet.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from e2e_support import REPO, SPEEDUP, demo_wav, require_parts
from gcs_voice.session.collisions import CollisionWatch, parse_hit
from gcs_voice.session.demo import DemoStep, step_summary
from gcs_voice.session.events import EventBus
from gcs_voice.session.sim_process import BundledSim


def test_hit_texts_are_parsed() -> None:
    hit = parse_hit("SIM Hit sofa (three-seat) at 1.20 m/s")
    assert hit is not None and (hit.obstacle, hit.speed_m_s) == ("sofa (three-seat)", 1.2)
    assert parse_hit("Hit ground").obstacle == "ground" and parse_hit("Hit ground").speed_m_s is None
    assert parse_hit("SIM Hit ground at 0.496600 m/s").speed_m_s == pytest.approx(0.4966)
    assert parse_hit("Arming motors") is None and parse_hit("EKF3 IMU0 is using GPS") is None


def _watch(mode: str = "GUIDED") -> tuple[EventBus, CollisionWatch]:
    bus = EventBus()
    watch = CollisionWatch(bus, hard_landing_m_s=1.0, mode=lambda: mode)
    bus.subscribe(watch)
    return bus, watch


def _collisions(bus: EventBus) -> list[str]:
    return [e.data["obstacle"] for e in bus.history if e.kind == "collision"]


def test_obstacles_are_collisions_and_a_landing_touchdown_is_not() -> None:
    bus, watch = _watch()
    bus.emit("command", "take_off", action="take_off")
    bus.emit("vehicle", "vehicle: SIM Hit north wall at 0.18 m/s", text="SIM Hit north wall at 0.18 m/s")
    bus.emit("vehicle", "vehicle: Hit ground", text="Hit ground")  # fell, nobody was landing
    bus.emit("command", "land", action="land")
    bus.emit("vehicle", "vehicle: SIM Hit ground at 0.50 m/s", text="SIM Hit ground at 0.50 m/s")  # the landing
    bus.emit("vehicle", "vehicle: SIM Hit ground at 2.50 m/s", text="SIM Hit ground at 2.50 m/s")  # too hard
    assert _collisions(bus) == ["north wall", "ground", "ground"] and watch.count == 3


def test_the_autopilot_landing_by_itself_is_not_a_collision() -> None:
    bus, _ = _watch(mode="LAND")  # e.g. a failsafe landing: no land command from us
    bus.emit("command", "take_off", action="take_off")
    bus.emit("vehicle", "vehicle: SIM Hit ground at 0.50 m/s", text="SIM Hit ground at 0.50 m/s")
    assert _collisions(bus) == []


def test_demo_summary_counts_only_what_was_done() -> None:
    """'land' heard right but refused (the vehicle disarmed after a crash) is not ok; a failed take-off neither."""
    steps = [DemoStep("take off", Path("t.wav"), "take_off", 0.5), DemoStep("go forward", Path("f.wav"), "go_forward", 1),
             DemoStep("land", Path("l.wav"), "land", 1)]
    events = [
        {"t": 0.0, "kind": "heard", "text": "take off", "utterance_end_t": 1.0},
        {"t": 0.1, "kind": "command", "action": "take_off", "utterance_end_t": 1.0},
        {"t": 3.0, "kind": "flight", "what": "take_off", "ok": True, "utterance_end_t": 1.0},
        {"t": 4.0, "kind": "heard", "text": "go forward", "transcript": "Go farward.", "utterance_end_t": 4.0},
        {"t": 4.1, "kind": "command", "action": "go_forward", "utterance_end_t": 4.0},
        {"t": 5.0, "kind": "heard", "text": "land", "utterance_end_t": 5.0},
        {"t": 5.1, "kind": "refused", "action": "land", "reason": "the vehicle is disarmed: nothing to land",
         "utterance_end_t": 5.0},
    ]
    lines, good = step_summary(steps, events)
    assert good == 2
    assert lines[0].endswith(" ok") and lines[1].endswith(" ok") and "NOT DONE: the vehicle is disarmed" in lines[2]
    assert "heard 'Go farward.'" in lines[1]  # the words Whisper wrote, not the phrase it scored best
    events[2] = {**events[2], "ok": False, "detail": "take off: timed out"}
    lines, good = step_summary(steps, events)
    assert good == 1 and "FAILED: take off: timed out" in lines[0]


@pytest.mark.slow
def test_a_session_that_hits_a_wall_exits_1_and_says_so(tmp_path: Path) -> None:
    require_parts("sim_bridge.cli")
    with BundledSim(autopilot="ardupilot", speedup=SPEEDUP, room="living_room", log_path=tmp_path / "sim.log") as sim:
        # 3 m from the north wall, forward at 1 m/s for up to 8 s (wall time, x2 simulated): it hits it.
        proc = subprocess.run([sys.executable, "-m", "gcs_voice", "--connect", sim.connection, "--say",
                               str(demo_wav("go_forward")), "--hold", "8", "--takeoff", "1.5", "--speed", "1",
                               "--engine", "sphinx", "--headless", "--json", "--log-dir", str(tmp_path),
                               "--log-name", "hit"], cwd=REPO, capture_output=True, text=True, timeout=180)
    events = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    hits = [e for e in events if e["kind"] == "collision"]
    assert hits and "wall" in hits[0]["obstacle"], proc.stdout[-3000:]
    end = events[-1]
    assert end["phase"] == "end" and end["collisions"] == len(hits) and end["exit_code"] == proc.returncode == 1


@pytest.mark.slow
def test_a_demo_that_collides_says_so_and_exits_non_zero(tmp_path: Path) -> None:
    """The shipped English sequence, flown in a room with a tall cabinet 0.6 m in front of the start."""
    require_parts("sim_bridge.cli", "gcs_voice.asr.registry")
    room = json.loads((REPO / "rooms" / "living_room.json").read_text())
    room["blocks"] = [{"name": "tall cabinet", "extents": [3.6, 4.2, 1.0, 4.2, 0.0, 2.6], "color": [0.3, 0.3, 0.3]}]
    (tmp_path / "cabinet.json").write_text(json.dumps(room))
    proc = subprocess.run([sys.executable, "-m", "gcs_voice", "demo", "--lang", "en", "--engine", "sphinx",
                           "--room", str(tmp_path / "cabinet.json")], cwd=tmp_path, capture_output=True, text=True,
                          timeout=240, env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    assert proc.returncode != 0, proc.stdout[-3000:] + proc.stderr
    assert "COLLIDED" in proc.stdout and "COLLISION at +" in proc.stdout and "tall cabinet" in proc.stdout, proc.stdout
    records = [json.loads(line) for line in (tmp_path / "demo-en.jsonl").read_text().splitlines()]
    printed = proc.stdout.count("COLLISION at +")
    assert printed == len([r for r in records if r["kind"] == "collision"])  # every hit is listed
    # and the demo's flight plot marks it where it happened
    import matplotlib.pyplot as plt

    from gcs_voice.session.plot import draw_flight, load_room

    fig = draw_flight(tmp_path / "demo-en.tlog", room=load_room(str(tmp_path / "cabinet.json")),
                      session_log=tmp_path / "demo-en.jsonl")
    try:
        assert any("hit tall cabinet" in t.get_text() for t in fig.axes[0].texts)
        assert any(line.get_label() == "collision" for line in fig.axes[0].lines)
    finally:
        plt.close(fig)
