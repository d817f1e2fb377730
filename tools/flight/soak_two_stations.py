#!/usr/bin/env python3
"""Two ground stations on one bundled-sim vehicle through MAVProxy, for a bounded time (issue 32's soak).

gcs-sim (real time) -> MAVProxy ``--out`` to gcs-voice's bridge (key requests, no speech) and to a
QGroundControl-like station (tools/flight/qgc_like.py: 255/190, HEARTBEAT 1 Hz, a parameter read every 2 s).
Loopback only. Cycles until the time is up:

  voice take off -> go forward / stop / go back / stop -> the other station switches to BRAKE (or Hold)
  -> voice "go left" (must be refused) -> the other station gives GUIDED (or nothing on PX4) back ->
  voice "go right" / stop -> voice land, wait until disarmed.

Counts: every COMMAND_LONG each station sent and every COMMAND_ACK each took as its own (addressed to its
system and component); an ACK "to the wrong station" is one a station took for a command it never sent,
or more ACKs than commands (ArduPilot answers each command once). The take-over is timed from the other
station's DO_SET_MODE to the bridge's ``takeover`` event, and to the vehicle HEARTBEAT that showed it.

    nice -n 5 python -m tools.flight.soak_two_stations --minutes 10
    nice -n 5 python -m tools.flight.soak_two_stations --vehicle arducopter-sitl --cycles 1   # ../shared/sitl

``--vehicle arducopter-sitl`` flies the real ArduCopter SITL of ../shared/sitl instead (real time; a cold
boot needs ~41 s before it can arm); ``--vehicle px4-sitl`` the real PX4 SITL on its own two links (gcs-voice
on 14540, the other station on 14550; no router), whose cycle has no GUIDED given back (a station cannot
enter OFFBOARD without a setpoint stream): take off, fly, Hold by the other station, refused motion, land.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from pymavlink import mavutil

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.session.events import EventBus
from gcs_voice.session.sim_process import BundledSim, free_udp_port
from gcs_voice.settings import load_settings
from tools.cpu_steal import CpuSample
from tools.flight.qgc_like import QGC_COMPONENT, QGC_SYSTEM, QgcLikeStation

ARDUCOPTER_BRAKE, ARDUCOPTER_GUIDED = 17, 4
SITL_DIR = Path(__file__).resolve().parents[3] / "shared" / "sitl"
SITL_START, PX4_START = SITL_DIR / "arducopter" / "start.sh", SITL_DIR / "px4" / "start.sh"
#: a cold ArduCopter SITL arms ~41 s after boot, PX4 SITL ~4 s; the bundled simulator at once
TAKEOFF_TIMEOUT_S = {"gcs-sim": 90.0, "arducopter-sitl": 180.0, "px4-sitl": 90.0}
PX4_AUTO, PX4_LOITER = mavutil.PX4_CUSTOM_MAIN_MODE_AUTO, mavutil.PX4_CUSTOM_SUB_MODE_AUTO_LOITER


def mavproxy_fan_out(master: str, ports: list[int], cwd: Path) -> subprocess.Popen:
    """MAVProxy as sim_vehicle.py runs it: one master, ``--out`` to each ground station's UDP port."""
    cmd = ["mavproxy.py", "--master", master, "--nowait", "--non-interactive", "--no-state"]
    for port in ports:
        cmd += ["--out", f"udp:127.0.0.1:{port}"]
    return subprocess.Popen(cmd, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def stop_process(proc: subprocess.Popen) -> None:
    """Terminate a process we started, and kill it if it does not end within 10 s."""
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


class SoakError(RuntimeError):
    """A part of the setup could not start (said in one line)."""


def _start_sitl(cmd: list[str]) -> int:
    """Run a ../shared/sitl start script; its process id (its last line says ``PID RUN_DIR``)."""
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or ["no output"])
        raise SoakError(f"{cmd[0]} failed: {' / '.join(why[:3])}")
    return int(done.stdout.strip().splitlines()[-1].split()[0])


@contextmanager
def stations(kind: str, cwd: Path) -> Iterator[tuple[str, str]]:
    """Start the vehicle and what links it to two stations; yields (gcs-voice's, the other station's) connection.

    gcs-sim and the ArduCopter SITL send to one UDP port: MAVProxy fans it out. PX4 SITL serves both
    stations itself: its GCS link (to 14550) for QGroundControl, its API link (to 14540) for gcs-voice."""
    if kind == "px4-sitl":
        pid = _start_sitl([str(PX4_START)])
        try:
            yield "udpin:127.0.0.1:14540", "udpin:127.0.0.1:14550"
        finally:
            os.kill(pid, 15)
        return
    port, voice_port, qgc_port = free_udp_port(), free_udp_port(), free_udp_port()
    sim = BundledSim(room="open_field", port=port).start() if kind == "gcs-sim" else None
    pid = None
    if sim is None:
        pid = _start_sitl([str(SITL_START), str(port)])
    router = mavproxy_fan_out(f"udpin:127.0.0.1:{port}", [voice_port, qgc_port], cwd)
    try:
        yield f"udpin:127.0.0.1:{voice_port}", f"udpin:127.0.0.1:{qgc_port}"
    finally:
        stop_process(router)
        if sim is not None:
            sim.stop()
        if pid is not None:
            os.kill(pid, 15)


DO_SET_MODE = mavutil.mavlink.MAV_CMD_DO_SET_MODE


class Soak:
    """One soak: the bridge, the other station, and what each sent and took."""

    def __init__(self, link: VehicleLink, qgc: QgcLikeStation, bus: EventBus, bridge: Bridge,
                 takeoff_timeout_s: float = 90.0, px4: bool = False) -> None:
        self.link, self.qgc, self.bus, self.bridge = link, qgc, bus, bridge
        self.takeoff_timeout_s = takeoff_timeout_s
        self.px4 = px4
        self.voice_sent: list[int] = []
        self.takeover_s: list[float] = []
        self.takeover_beat_s: list[float] = []
        self.cycles = 0
        self.refused_after_takeover = 0
        self.failures: list[str] = []

    def request(self, action: str, timeout_s: float = 15.0) -> Request:
        request = self.bridge.submit(Request(action, "key"))
        if not request.done.wait(timeout_s):
            raise RuntimeError(f"{action}: not handled within {timeout_s:g} s")
        return request

    def wait(self, predicate, timeout_s: float, what: str) -> None:   # noqa: ANN001
        deadline = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > deadline:
                raise RuntimeError(f"{what}: not within {timeout_s:g} s")
            time.sleep(0.02)

    def cycle(self) -> None:
        self.bridge.flying_ready.clear()
        self.request("take_off")
        if not self.bridge.flying_ready.wait(self.takeoff_timeout_s):
            raise RuntimeError(f"take-off did not finish within {self.takeoff_timeout_s:g} s")
        for action, hold_s in (("go_forward", 1.5), ("stop", 0.5), ("go_back", 1.5), ("stop", 0.5)):
            if not self.request(action).accepted:
                raise RuntimeError(f"{action} refused while flying")
            time.sleep(hold_s)
        takeovers = sum(e.kind == "takeover" for e in self.bus.history)
        beats = self.link.state.heartbeats
        sent_t = time.monotonic()
        self.qgc.set_mode(*((PX4_AUTO, PX4_LOITER) if self.px4 else (ARDUCOPTER_BRAKE, 0)))
        self.wait(lambda: sum(e.kind == "takeover" for e in self.bus.history) > takeovers, 10, "take-over event")
        self.takeover_s.append(time.monotonic() - sent_t)
        self.takeover_beat_s.append((self.link.state.heartbeat_s or sent_t) - sent_t)
        if self.link.state.heartbeats - beats > 2:
            self.failures.append(f"cycle {self.cycles}: take-over seen only after {self.link.state.heartbeats - beats} "
                                 "HEARTBEATs")
        if self.request("go_left").accepted:
            self.failures.append(f"cycle {self.cycles}: go_left flown after the take-over")
        else:
            self.refused_after_takeover += 1
        if not self.px4:   # PX4: no station can give OFFBOARD back without a setpoint stream of its own
            self.qgc.set_mode(ARDUCOPTER_GUIDED)      # the other station gives it back
            self.wait(lambda: self.link.state.mode == "GUIDED", 10, "GUIDED given back")
            for action, hold_s in (("go_right", 1.0), ("stop", 0.5)):
                if not self.request(action).accepted:
                    raise RuntimeError(f"{action} refused after GUIDED was given back")
                time.sleep(hold_s)
        self.request("land")
        self.wait(lambda: self.link.state.armed is False, 60, "landed and disarmed")
        self.cycles += 1


def run(minutes: float, kind: str = "gcs-sim", cycles: int | None = None) -> int:
    if shutil.which("mavproxy.py") is None:
        print("soak_two_stations: mavproxy.py is not installed (pip install mavproxy)", file=sys.stderr)
        return 2
    settings = load_settings()
    cpu = CpuSample()
    started = time.monotonic()
    with cpu, tempfile.TemporaryDirectory() as tmp, stations(kind, Path(tmp)) as (voice_at, qgc_at):
        link = VehicleLink(voice_at, settings)
        send = link.send
        voice_sent: list[int] = []

        def counting_send(msg, time_s=None):   # noqa: ANN001 - the link's own signature
            if msg.get_type() == "COMMAND_LONG":
                voice_sent.append(int(msg.command))
            send(msg, time_s)

        link.send = counting_send   # counts what gcs-voice asks; every message still goes out unchanged
        soak: Soak | None = None
        try:
            with QgcLikeStation(qgc_at) as qgc:
                link.open()
                link.wait_vehicle(60)
                link.request_telemetry()
                qgc.wait_for(lambda q: q.vehicle is not None, 30, "the vehicle's HEARTBEAT")
                bus = EventBus()
                bridge = Bridge(link, ActionMapper(settings), bus, 1.5)
                soak = Soak(link, qgc, bus, bridge, TAKEOFF_TIMEOUT_S[kind], px4=kind == "px4-sitl")
                soak.voice_sent = voice_sent

                def script() -> None:
                    try:
                        while (soak.cycles < cycles) if cycles else (time.monotonic() - started < minutes * 60):
                            soak.cycle()
                    except Exception as exc:   # noqa: BLE001 - reported below
                        soak.failures.append(f"cycle {soak.cycles}: {exc}")
                    finally:
                        bridge.finish(0)

                worker = threading.Thread(target=script, daemon=True)
                worker.start()
                bridge.run()
                worker.join(30)
                qgc_sent = Counter(command for _, command in qgc.sent)
                qgc_took = Counter(a[1] for a in qgc.acks_to((QGC_SYSTEM, QGC_COMPONENT)))
                qgc_heard_other = len(qgc.acks) - sum(qgc_took.values())
                param_values = qgc.param_values
        finally:
            link.close()
    assert soak is not None
    voice_sent = Counter(soak.voice_sent)
    voice_due, qgc_due = Counter(voice_sent), Counter(qgc_sent)   # the ACKs each should get
    if kind == "px4-sitl":   # PX4 answers DO_SET_MODE twice (the mavlink module, then commander)
        voice_due[DO_SET_MODE] *= 2
        qgc_due[DO_SET_MODE] *= 2
    voice_took = Counter(a.command for a in link.tracker.acks)
    wrong_voice = sum(max(0, n - voice_due[c]) for c, n in voice_took.items())
    wrong_qgc = sum(max(0, n - qgc_due[c]) for c, n in qgc_took.items())
    unanswered_voice = sum(max(0, n - voice_took[c]) for c, n in voice_due.items())
    unanswered_qgc = sum(max(0, n - qgc_took[c]) for c, n in qgc_due.items())
    elapsed = time.monotonic() - started
    story = ("take off, fly, Hold by the other station, land" if kind == "px4-sitl"
             else "take off, fly, BRAKE by the other station, GUIDED given back, fly, land")
    print(f"soak ({kind}): {elapsed / 60:.1f} min, {soak.cycles} cycles ({story}); {cpu.describe()}, load average {os.getloadavg()[0]:.1f} at the end "
          "(a shared 2-core machine)")
    print(f"gcs-voice (255/{settings.gcs_component_id}): {sum(voice_sent.values())} commands, "
          f"{sum(voice_took.values())} ACKs taken, unanswered {unanswered_voice}, taken without a command {wrong_voice}")
    print(f"QGroundControl-like (255/190): {sum(qgc_sent.values())} commands, {sum(qgc_took.values())} ACKs taken, "
          f"unanswered {unanswered_qgc}, taken without a command {wrong_qgc}; heard {qgc_heard_other} ACKs "
          f"addressed to others (left alone); {param_values} PARAM_VALUEs")
    if soak.takeover_s:
        print(f"take-over: {len(soak.takeover_s)}, said {statistics.median(soak.takeover_s):.2f} s median, "
              f"{max(soak.takeover_s):.2f} s max after the other station's DO_SET_MODE (the HEARTBEAT that showed "
              f"it: {max(soak.takeover_beat_s):.2f} s max); voice motions refused after it "
              f"{soak.refused_after_takeover}/{len(soak.takeover_s)}; named the station "
              f"{sum(e.kind == 'takeover' and e.data.get('by') == 'station' for e in soak.bus.history)}/"
              f"{len(soak.takeover_s)}")
    for failure in soak.failures:
        print(f"FAILED: {failure}")
    bad = wrong_voice or wrong_qgc or unanswered_qgc or soak.failures
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="how long to cycle (default 10)")
    parser.add_argument("--cycles", type=int, help="fly this many cycles instead of --minutes")
    parser.add_argument("--vehicle", choices=sorted(TAKEOFF_TIMEOUT_S), default="gcs-sim",
                        help="the bundled simulator, or the real ArduCopter SITL of ../shared/sitl")
    args = parser.parse_args(argv)
    if not 0 < args.minutes <= 120:
        parser.error("--minutes must be within (0, 120]")
    if args.cycles is not None and not 0 < args.cycles <= 100:
        parser.error("--cycles must be within 1-100")
    start = {"arducopter-sitl": SITL_START, "px4-sitl": PX4_START}.get(args.vehicle)
    if start is not None and not start.exists():
        parser.error(f"no SITL at {start}")
    try:
        return run(args.minutes, args.vehicle, args.cycles)
    except SoakError as exc:
        print(f"soak_two_stations: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
