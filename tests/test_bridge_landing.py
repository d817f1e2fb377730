"""A session that ends after "land" waits for the vehicle to say it is landed and disarmed, within a limit.

A real VehicleLink and Bridge on 127.0.0.1 against the scripted vehicle of ``link_peer`` (it descends at
5 m/s after NAV_LAND and disarms on the ground, like ArduCopter's LAND): nothing is faked on our side.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from pathlib import Path

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.session.events import EventBus
from link_peer import ScriptedVehicle


def _session(vehicle: ScriptedVehicle, tmp_path: Path, landed_timeout_s: float | None = None):
    link = VehicleLink(vehicle.connection, tlog_path=tmp_path / "f.tlog")
    link.connect(timeout_s=5)
    if landed_timeout_s is not None:
        link.readiness_rules = replace(link.readiness_rules, landed_timeout_s=landed_timeout_s)
    bus = EventBus()
    bridge = Bridge(link, ActionMapper(link.settings), bus, 2.0)
    runner = threading.Thread(target=bridge.run, daemon=True)
    runner.start()
    took_off = bridge.submit(Request("take_off", "script"))
    assert bridge.flying_ready.wait(20), [e.msg for e in bus.history]
    assert took_off.done.wait(5)
    return link, bus, bridge, runner


def _land_and_end(bridge: Bridge) -> None:
    land = bridge.submit(Request("land", "script"))
    assert land.done.wait(5)
    bridge.finish()   # the script ends at once, as in the live PX4 session of issue 11


def test_session_end_after_land_waits_for_touchdown_and_disarm(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot") as vehicle:
        link, bus, bridge, runner = _session(vehicle, tmp_path)
        try:
            _land_and_end(bridge)
            runner.join(15)
            assert not runner.is_alive()
            assert link.state.armed is False and link.state.landed_state == "ON_GROUND"
        finally:
            link.close()
    said = [e.msg for e in bus.history if e.kind == "flight"]
    assert any(m.startswith("waiting up to 40 s for the vehicle to land and disarm") for m in said), said
    assert any(m.startswith("landed and disarmed") for m in said), said


def test_landing_not_seen_within_the_limit_is_said(tmp_path: Path) -> None:
    with ScriptedVehicle("ardupilot") as vehicle:
        link, bus, bridge, runner = _session(vehicle, tmp_path, landed_timeout_s=1.5)
        try:
            stuck = threading.Event()

            def keep_in_the_air() -> None:   # a LAND that never completes
                while not stuck.wait(0.02):
                    vehicle.target_height_m = max(vehicle.target_height_m, 1.0)
                    vehicle.armed = True

            threading.Thread(target=keep_in_the_air, daemon=True).start()
            land = bridge.submit(Request("land", "script"))
            assert land.done.wait(5)
            started = time.monotonic()
            bridge.finish()
            runner.join(10)
            assert not runner.is_alive() and time.monotonic() - started < 5
        finally:
            stuck.set()
            link.close()
    warnings = [e.msg for e in bus.history if e.kind == "warning"]
    assert any(m.startswith("landing not confirmed (not seen within 1.5 s): mode LAND, armed") for m in warnings), \
        warnings


def test_a_script_waits_on_the_bridge_for_an_operation_and_for_the_end(tmp_path: Path) -> None:
    """What ``run_script`` waits on: ``wait_idle`` is woken when the operation ends (it does not run out its
    time), ``wait_finished`` returns True at ``finish()`` from another thread."""
    limit_s = 30.0
    with ScriptedVehicle("ardupilot") as vehicle:
        link, bus, bridge, runner = _session(vehicle, tmp_path)
        try:
            assert bridge.wait_idle(limit_s) and bridge.busy is None
            land = bridge.submit(Request("land", "script"))
            assert land.done.wait(5)
            started = time.monotonic()
            assert bridge.wait_idle(limit_s) and bridge.busy is None, [e.msg for e in bus.history]
            assert time.monotonic() - started < limit_s / 2, "wait_idle ran out its time: nothing woke it"
            assert not bridge.wait_finished(0.0)
            threading.Thread(target=bridge.finish, daemon=True).start()
            assert bridge.wait_finished(30)
            assert bridge.wait_idle(0.0)  # finished: nothing left to wait for
            runner.join(15)
            assert not runner.is_alive()
        finally:
            link.close()
