"""Real ground stations against the gcs-sim process: MAVSDK-Python (its bundled C++ core) and MAVProxy."""

from __future__ import annotations

import asyncio
import queue
import shutil
import re
import subprocess
import threading
import time
from pathlib import Path

import pytest
from conftest import IN_CI

from gcs_voice.session.sim_process import BundledSim


async def _mavsdk_flight(port: int) -> dict:
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    seen: dict = {}
    async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as mavsdk:
        await mavsdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await mavsdk.first_autopilot(timeout_s=10.0)
        assert system is not None, "MAVSDK sees no autopilot"
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        for _ in range(50):
            health = await telemetry.health()
            if health.is_global_position_ok and health.is_home_position_ok and health.is_armable:
                break
            await asyncio.sleep(0.2)
        seen["health"] = health
        await action.set_takeoff_altitude(2.0)
        await action.arm()
        await action.takeoff()
        for _ in range(75):
            position = await telemetry.position()
            if position.relative_altitude_m > 1.8:
                break
            await asyncio.sleep(0.2)
        seen["position"] = position
        await action.land()
        for _ in range(75):
            seen["armed_after_land"] = await telemetry.armed()
            if not seen["armed_after_land"]:
                break
            await asyncio.sleep(0.2)
    return seen


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavsdk_connects_passes_health_arms_takes_off_and_lands(autopilot: str) -> None:
    with BundledSim(autopilot, room="open_field") as sim:
        seen = asyncio.run(asyncio.wait_for(_mavsdk_flight(sim.port), 60))
    health = seen["health"]
    assert health.is_global_position_ok and health.is_home_position_ok and health.is_armable
    assert health.is_local_position_ok and health.is_gyrometer_calibration_ok
    assert seen["position"].relative_altitude_m > 1.8
    assert seen["armed_after_land"] is False


class _Console:
    """MAVProxy's console over a pipe: send a line, wait for a line matching a pattern."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.lines: queue.Queue[str] = queue.Queue()
        self.log: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line)

    def send(self, line: str) -> None:
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def expect(self, pattern: str, timeout_s: float) -> re.Match:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                continue
            self.log.append(line)
            found = re.search(pattern, line)
            if found:
                return found
        raise AssertionError(f"MAVProxy never printed /{pattern}/; last lines:\n{''.join(self.log[-15:])}")


@pytest.mark.slow
def test_mavproxy_downloads_params_arms_takes_off_and_lands(tmp_path: Path) -> None:
    if shutil.which("mavproxy.py") is None:
        if IN_CI:
            pytest.fail("mavproxy.py is missing in CI (it is in the [test] extra)")
        pytest.skip("mavproxy.py not installed")
    sim = BundledSim(speedup=2, room="open_field", tcp=True, udp=False).start()
    mavproxy = subprocess.Popen(["mavproxy.py", "--master", f"tcp:127.0.0.1:{sim.tcp_port}", "--nowait"], cwd=tmp_path,
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    console = _Console(mavproxy)
    try:
        count = int(console.expect(r"Received (\d+) parameters", 30).group(1))
        import tomllib

        from sim_bridge.params import __file__ as params_module
        with open(Path(params_module).parent / "data" / "params_ardupilot.toml", "rb") as f:
            served = len(tomllib.load(f)["params"])
        assert count == served, "the whole ArduCopter parameter set, with a consistent param_count"
        console.send("mode guided")
        console.expect(r"DO_SET_MODE: ACCEPTED", 10)
        console.send("arm throttle")
        console.expect(r"COMPONENT_ARM_DISARM: ACCEPTED", 10)
        console.send("takeoff 2")
        console.expect(r"NAV_TAKEOFF: ACCEPTED", 10)
        altitude_mm = 0
        deadline = time.monotonic() + 20
        while altitude_mm < 1800 and time.monotonic() < deadline:
            time.sleep(0.5)
            console.send("status GLOBAL_POSITION_INT")
            altitude_mm = int(console.expect(r"relative_alt : (-?\d+)", 5).group(1))
        assert altitude_mm >= 1800
        console.send("mode land")
        console.expect(r"DISARMED", 20)
        breaches = [line for line in console.log if "fence breach" in line.lower()]
        assert not breaches, "SYS_STATUS says the fence is present but unhealthy"
    finally:
        mavproxy.terminate()
        try:
            mavproxy.wait(timeout=10)
        except subprocess.TimeoutExpired:
            mavproxy.kill()
            mavproxy.wait()
        sim.stop()
