"""Bridge safety rules against the real simulator, driven by key requests (no speech needed for these).

Link loss is made real: the simulator process is frozen (SIGSTOP), so the vehicle falls silent on the
wire exactly as a radio dropout would look to the ground station, then thawed (SIGCONT).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Callable

import pytest

from e2e_support import SPEEDUP, require_parts
from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.session.events import EventBus
from gcs_voice.session.flight_log import read_flight
from gcs_voice.link import VehicleLink
from gcs_voice.session.listen import start_voice_thread
from gcs_voice.session.session_log import SessionLog
from gcs_voice.session.sim_process import BundledSim
from gcs_voice.settings import load_settings

pytestmark = pytest.mark.slow


def _wait(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Poll until ``predicate()``; raise naming ``what`` if it never holds (the script then ends the session)."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout_s:.0f} s")
        time.sleep(0.05)


def test_link_loss_and_voice_crash(tmp_path: Path) -> None:
    """Motion before take-off and disarm in the air refused; link lost: refused, silent, then a stop first;
    voice crash: stop, exit 1."""
    require_parts("sim_bridge.cli")
    settings = load_settings()
    bus = EventBus()
    log = SessionLog(tmp_path / "s.jsonl")
    bus.subscribe(log)
    tlog = tmp_path / "s.tlog"
    marks: dict[str, float] = {}
    with BundledSim(speedup=SPEEDUP, room="open_field") as sim:
        link = VehicleLink(sim.connection, settings, tlog_path=tlog)
        link.open()
        try:
            link.wait_vehicle(30)
            link.request_telemetry()
            bridge = Bridge(link, ActionMapper(settings), bus, 1.5)

            def done(request: Request, what: str) -> None:
                if not request.done.wait(10):
                    raise AssertionError(f"{what}: request not handled within 10 s")

            def sent_more(count: int, what: str) -> None:
                first = link.setpoints_sent
                _wait(lambda: link.setpoints_sent >= first + count, 10, what)

            def link_event(state: str) -> bool:
                return any(e.kind == "link" and e.data.get("state") == state for e in bus.history)

            def script() -> None:
                # Runs beside bridge.run(); a failure is recorded and still ends the session (by the crash
                # below), so the main thread reports it instead of hanging or losing it in this thread.
                try:
                    done(bridge.submit(Request("go_forward", "key")), "go_forward before take-off")
                    bridge.submit(Request("take_off", "key"))
                    if not bridge.flying_ready.wait(60):
                        raise AssertionError("take-off did not finish within 60 s")
                    done(bridge.submit(Request("disarm", "key")), "disarm in the air")   # must be refused
                    done(bridge.submit(Request("go_forward", "key")), "go_forward")
                    sent_more(5, "forward setpoints on the wire")
                    marks["pause"] = time.time()
                    sim.pause()
                    _wait(lambda: link_event("lost"), 6, "link lost after the freeze")
                    marks["lost"] = time.time()
                    done(bridge.submit(Request("go_back", "key")), "go_back while lost")
                    time.sleep(0.5)   # a silence to check: nothing may be sent while lost
                    marks["resume"] = time.time()
                    sim.resume()
                    _wait(lambda: link_event("restored"), 6, "link restored after the thaw")
                    sent_more(1, "the first setpoint after the return")
                    done(bridge.submit(Request("go_right", "key")), "go_right")
                    sent_more(5, "go_right setpoints on the wire")
                except BaseException as exc:     # noqa: BLE001 - reported by the main thread
                    failures.append(exc)
                marks["crash"] = time.time()
                start_voice_thread(bridge, crash)  # the voice side dies mid-flight

            def crash() -> None:
                raise RuntimeError("microphone unplugged")

            failures: list[BaseException] = []
            worker = threading.Thread(target=script, daemon=True)
            worker.start()
            exit_code = bridge.run()
            worker.join(10)
            assert not worker.is_alive(), "the script thread did not finish"
            if failures:
                raise failures[0]
            assert exit_code == 1  # ended by the crash, vehicle stopped first
        finally:
            link.close()
            log.close()

    events = [e.to_dict() for e in bus.history]
    refused = [e for e in events if e["kind"] == "refused"]
    assert refused[0]["action"] == "go_forward" and "not armed" in refused[0]["reason"]
    assert any(e["action"] == "go_back" and "link lost" in e["reason"] for e in refused)
    assert any(e["action"] == "disarm" and "flying" in e["reason"] for e in refused)
    assert not any(e["kind"] == "flight" and e.get("what") == "disarm" for e in events)
    assert not any(e["kind"] == "command" and e.get("action") == "go_back" for e in events)
    states = [e["state"] for e in events if e["kind"] == "link"]
    assert states[:1] == ["connected"] and "lost" in states and states[-1] == "restored"

    flight = read_flight(tlog)
    sent = flight.setpoints
    # Nothing is commanded while the vehicle is silent (from 2 s after the freeze until it is heard again).
    during = [s for s in sent if marks["pause"] + settings.link_lost_s + 0.2 < s.t_s < marks["resume"]]
    assert during == []
    # Before the loss: forward at 0.5 m/s; the first setpoint after the return: zero velocity.
    before = [s for s in sent if s.t_s < marks["pause"]]
    assert before and abs(before[-1].vx_m_s) + abs(before[-1].vy_m_s) > 0.4
    after = [s for s in sent if s.t_s > marks["resume"]]
    assert after, "no setpoint after the link returned"
    assert (after[0].vx_m_s, after[0].vy_m_s, after[0].vz_m_s) == (0.0, 0.0, 0.0)

    # The voice side crashed while going right: reported, and the session ended with a stop on the wire.
    assert any(e["kind"] == "error" and "microphone unplugged" in e["msg"] for e in events)
    final = [s for s in sent if s.t_s > marks["crash"]]
    assert final and (final[-1].vx_m_s, final[-1].vy_m_s, final[-1].vz_m_s) == (0.0, 0.0, 0.0)
    right = [s for s in sent if marks["resume"] < s.t_s < marks["crash"]]
    assert any(abs(s.vx_m_s) + abs(s.vy_m_s) > 0.4 for s in right)  # it was moving when the voice side died
