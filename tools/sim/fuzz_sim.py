"""Fuzz a running gcs-sim on the wire (UDP and TCP), then check that it still serves.

Run as ``python -m tools.sim.fuzz_sim`` (default: 120 s per personality, writes docs/bench/fuzz_sim.md);
``tests/test_sim_fuzz.py`` runs the same fuzzer for a few seconds against each personality.

What is sent, as fast as the sim takes it: random bytes; valid frames with bytes overwritten, cut short
or run together; and well-formed messages of every type the sim handles, addressed to it, with hostile
field values (NaN, inf, huge, out of range). The well-formed ones leave out what a real ground station
would use to change the flight (arm, mode, take-off, land, home, parameter values that are finite): the
check afterwards must find the vehicle as a ground station finds it after boot. TCP clients also connect
and vanish mid-frame (RST). Afterwards: the process is alive, HEARTBEAT comes at 1 Hz (simulated time),
a normal GUIDED (ArduPilot) or OFFBOARD (PX4) take-off works, and the resident memory is flat.
"""

from __future__ import annotations

import argparse
import math
import random
import re
import select
import socket
import struct
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as M

from gcs_voice.session.sim_process import BundledSim

__all__ = ["hostile_message", "fuzz_chunk", "fuzz", "FuzzCounts", "Health", "Station", "check_serving", "rss_kb",
           "learn_sim_address"]

REPO = Path(__file__).resolve().parents[2]
#: Commands that change the flight (mode, arm, take-off, land, RTL, home, speed, reboot, mission start).
FLIGHT_COMMANDS = frozenset({11, 20, 21, 22, 176, 178, 179, 246, 300, 400})
#: Commands the sim answers without changing the flight: fuzzed with hostile parameters.
QUERY_COMMANDS = (115, 410, 511, 512, 520, 510)
HOSTILE_FLOATS = (0.0, 1.0, -1.0, -2.0, math.nan, math.inf, -math.inf, 1e30, -1e30, 2.2e9, 3.4e38)
#: Wall time the sim may take to work through what the fuzz left in its socket buffers (up to 1 MB of UDP
#: it reads at a bounded rate per tick), during which its simulated clock runs slower than the wall clock.
BACKLOG_S = 30.0
PX4_OFFBOARD = 393216
PX4_HOLD = 50593792
TAKEOFF_M = 1.5


def _num(rng: random.Random) -> float:
    return rng.choice(HOSTILE_FLOATS + (rng.uniform(-1e6, 1e6),))


def hostile_message(rng: random.Random, mav: M.MAVLink) -> M.MAVLink_message:
    """A well-formed message of a type the sim handles, for system 1, with hostile field values."""
    kind = rng.randrange(10)
    if kind == 0:
        command = rng.choice(QUERY_COMMANDS + (rng.randrange(65536),))
        if command in FLIGHT_COMMANDS:
            command = 512
        return mav.command_long_encode(1, rng.choice([0, 1]), command, rng.randrange(256),
                                       *(_num(rng) for _ in range(7)))
    if kind == 1:
        command = rng.choice(QUERY_COMMANDS)
        return mav.command_int_encode(1, 1, rng.randrange(0, 22), command, 0, 0, _num(rng), _num(rng), _num(rng),
                                      _num(rng), rng.randrange(-2**31, 2**31), rng.randrange(-2**31, 2**31), _num(rng))
    if kind == 2:   # disarmed on the ground: ignored by the flight, parsed and checked all the same
        return mav.set_position_target_local_ned_encode(rng.randrange(2**32), 1, 1, rng.randrange(256),
                                                        rng.randrange(65536), *(_num(rng) for _ in range(11)))
    if kind == 3:   # a real name only with a non-finite value (refused), else a name that does not exist
        name = rng.choice([b"GUID_TIMEOUT", b"MAV1_EXTRA1", b"COM_OF_LOSS_T", b"MPC_XY_VEL_MAX"])
        value = rng.choice([math.nan, math.inf, -math.inf])
        if rng.random() < 0.5:
            name, value = bytes(rng.randrange(1, 256) for _ in range(rng.randrange(1, 17))), _num(rng)
        return mav.param_set_encode(1, 1, name, value, rng.randrange(256))
    if kind == 4:
        return mav.param_request_read_encode(1, 1, bytes(rng.randrange(256) for _ in range(rng.randrange(17))),
                                             rng.randrange(-32768, 32768))
    if kind == 5:
        return mav.param_request_list_encode(1, 1)
    if kind == 6:
        return rng.choice([mav.mission_request_int_encode(1, 1, rng.randrange(65536), rng.randrange(256)),
                           mav.mission_request_encode(1, 1, rng.randrange(65536), rng.randrange(256)),
                           mav.mission_request_list_encode(1, 1, rng.randrange(256)),
                           mav.mission_count_encode(1, 1, rng.randrange(65536), rng.randrange(256)),
                           mav.mission_clear_all_encode(1, 1, rng.randrange(256))])
    if kind == 7:
        return mav.request_data_stream_encode(1, 1, rng.randrange(256), rng.randrange(1, 65536), 1)
    if kind == 8:
        return mav.timesync_encode(rng.randrange(-2**63, 2**63), rng.randrange(-2**63, 2**63))
    return mav.heartbeat_encode(rng.randrange(256), rng.randrange(256), rng.randrange(256), rng.randrange(2**32),
                                rng.randrange(256), rng.randrange(256))


def fuzz_chunk(rng: random.Random, mav: M.MAVLink) -> bytes:
    """One datagram (or one TCP write): random bytes, a mutated frame, frames run together, or a hostile one."""
    choice = rng.random()
    if choice < 0.25:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
    if choice < 0.6:
        frame = bytearray(hostile_message(rng, mav).pack(mav))
        for _ in range(rng.randrange(1, 4)):
            frame[rng.randrange(len(frame))] = rng.randrange(256)
        if rng.random() < 0.3:
            frame = frame[: rng.randrange(1, len(frame) + 1)]
        if len(frame) > 1 and rng.random() < 0.2:
            frame[1] = 255     # a length field that promises more than comes
        return bytes(frame)
    if choice < 0.75:
        return b"".join(hostile_message(rng, mav).pack(mav) for _ in range(rng.randrange(2, 6)))
    return hostile_message(rng, mav).pack(mav)


@dataclass
class FuzzCounts:
    udp_datagrams: int = 0
    tcp_writes: int = 0
    tcp_sessions: int = 0
    tcp_resets: int = 0


def _discard(sock: socket.socket) -> None:
    """Read and drop whatever the sim sent us, so it never has to drop us as a slow client."""
    while True:
        try:
            if not sock.recv(65536, socket.MSG_DONTWAIT):
                return
        except (BlockingIOError, InterruptedError):
            return
        except OSError:       # ICMP errors surface here on UDP; a reset TCP peer is handled by the sender
            return


def _tcp_client(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=5)
    sock.setblocking(False)
    return sock


def _reset(sock: socket.socket) -> None:
    """Vanish mid-stream: SO_LINGER 0 makes close() send RST."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    except OSError:
        pass
    sock.close()


def fuzz(udp_sock: socket.socket, sim_addr: tuple[str, int], tcp_port: int | None, seconds: float,
         rng: random.Random, max_rate_hz: float = 2000.0) -> FuzzCounts:
    """Send fuzz on UDP (to the sim's address) and on TCP (one client, reset and replaced now and then)."""
    mav = M.MAVLink(None, srcSystem=255, srcComponent=190)
    counts = FuzzCounts()
    tcp: socket.socket | None = None
    deadline = time.monotonic() + seconds
    sent = 0
    start = time.monotonic()
    while time.monotonic() < deadline:
        chunk = fuzz_chunk(rng, mav)
        if tcp_port is None or rng.random() < 0.5:
            try:
                udp_sock.sendto(chunk, sim_addr)
                counts.udp_datagrams += 1
            except OSError:
                pass
            _discard(udp_sock)
        else:
            if tcp is None:
                tcp = _tcp_client(tcp_port)
                counts.tcp_sessions += 1
            try:
                tcp.send(chunk)
                counts.tcp_writes += 1
                _discard(tcp)
            except (BlockingIOError, InterruptedError):
                _discard(tcp)
            except OSError:
                tcp.close()
                tcp = None
            if tcp is not None and rng.random() < 0.01:
                _reset(tcp)
                tcp = None
                counts.tcp_resets += 1
        sent += 1
        ahead_s = sent / max_rate_hz - (time.monotonic() - start)
        if ahead_s > 0:
            time.sleep(ahead_s)
    if tcp is not None:
        _reset(tcp)
    return counts


def learn_sim_address(udp_sock: socket.socket, timeout_s: float = 30.0) -> tuple[str, int]:
    """The sim sends from an ephemeral port: its first datagram tells where to answer (as for QGroundControl)."""
    ready, _, _ = select.select([udp_sock], [], [], timeout_s)
    if not ready:
        raise TimeoutError("no datagram from gcs-sim")
    _data, addr = udp_sock.recvfrom(65535)
    return addr


def rss_kb(pid: int) -> int:
    """Resident memory of a process (Linux /proc)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError(f"no VmRSS for pid {pid}")


@dataclass
class Health:
    """What a fresh ground station finds after the fuzz."""

    heartbeat_gaps_ms: list[int] = field(default_factory=list)
    udp_heartbeats: int = 0
    took_off: bool = False
    height_m: float = 0.0
    mode_ok: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def heartbeat_1hz(self) -> bool:
        return len(self.heartbeat_gaps_ms) >= 3 and all(800 <= gap <= 1200 for gap in self.heartbeat_gaps_ms)

    @property
    def ok(self) -> bool:
        return self.heartbeat_1hz and self.udp_heartbeats >= 2 and self.took_off and self.mode_ok


class Station:
    """A minimal ground station on a fresh TCP link (its own message intervals, its own ACKs)."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5)
        self.mav = M.MAVLink(None, srcSystem=255, srcComponent=190)
        self.parser = M.MAVLink(None)
        self.parser.robust_parsing = True
        self.pending: list[M.MAVLink_message] = []
        self.clock_ms = 0
        self.rel_alt_m = 0.0
        self.alt_amsl_m = 0.0

    def close(self) -> None:
        self.sock.close()

    def send(self, msg: M.MAVLink_message) -> None:
        self.sock.sendall(msg.pack(self.mav))

    def next(self, timeout_s: float) -> M.MAVLink_message | None:
        deadline = time.monotonic() + timeout_s
        while not self.pending:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self.sock], [], [], left)
            if ready:
                data = self.sock.recv(65536)
                if not data:
                    raise ConnectionError("gcs-sim closed the link")
                self.pending.extend(m for m in self.parser.parse_buffer(data) or []
                                    if m.get_type() != "BAD_DATA" and m.get_srcSystem() == 1)
        msg = self.pending.pop(0)
        if msg.get_type() == "GLOBAL_POSITION_INT":
            self.clock_ms = msg.time_boot_ms
            self.rel_alt_m = msg.relative_alt / 1000.0
            self.alt_amsl_m = msg.alt / 1000.0
        return msg

    def wait(self, kind: str, timeout_s: float, cond=lambda m: True, every=None) -> M.MAVLink_message | None:
        deadline = time.monotonic() + timeout_s
        next_every = 0.0
        while time.monotonic() < deadline:
            if every is not None and time.monotonic() >= next_every:
                every()
                next_every = time.monotonic() + 0.1
            msg = self.next(min(0.1, max(0.0, deadline - time.monotonic())))
            if msg is not None and msg.get_type() == kind and cond(msg):
                return msg
        return None

    def command(self, command: int, *params: float, acks: int = 1, every=None) -> list[int]:
        self.send(self.mav.command_long_encode(1, 1, command, 0, *params, *[0.0] * (7 - len(params))))
        results = []
        for _ in range(acks):
            ack = self.wait("COMMAND_ACK", 10.0, lambda m: m.command == command, every=every)
            if ack is None:
                break
            results.append(ack.result)
        return results

    def setpoint(self, vz: float = 0.0) -> None:
        mask = 0b0000_1101_1100_0111     # velocity only (3527)
        self.send(self.mav.set_position_target_local_ned_encode(0, 1, 1, M.MAV_FRAME_LOCAL_NED, mask,
                                                                0, 0, 0, 0, 0, vz, 0, 0, 0, 0, 0))


def check_serving(tcp_port: int, autopilot: str, udp_sock: socket.socket | None = None) -> Health:
    """Connect afresh and check: HEARTBEAT at 1 Hz (simulated), heard on UDP too, and a normal take-off."""
    health = Health()
    station = Station(tcp_port)
    try:
        accepted = M.MAV_RESULT_ACCEPTED
        # this link's own clock: GLOBAL_POSITION_INT at 10 Hz, whatever the fuzz did to the shared defaults
        if station.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 100_000) != [accepted]:
            health.notes.append("SET_MESSAGE_INTERVAL(GLOBAL_POSITION_INT) refused")
        stamps: list[int] = []
        while len(stamps) < 5:
            hb = station.wait("HEARTBEAT", BACKLOG_S)
            if hb is None:
                health.notes.append(f"HEARTBEAT stopped after {len(stamps)}")
                break
            if station.clock_ms:
                stamps.append(station.clock_ms)
        health.heartbeat_gaps_ms = [b - a for a, b in zip(stamps, stamps[1:])]
        if udp_sock is not None:
            health.udp_heartbeats = _count_udp_heartbeats(udp_sock, 2, BACKLOG_S)
        if health.udp_heartbeats < 2:
            health.notes.append(f"{health.udp_heartbeats} HEARTBEATs on UDP")
        prearm = M.MAV_SYS_STATUS_PREARM_CHECK
        if station.wait("SYS_STATUS", 30.0, lambda m: m.onboard_control_sensors_health & prearm) is None:
            health.notes.append("pre-arm checks never passed")
            return health
        if autopilot == "ardupilot":
            _ardupilot_takeoff(station, health)
        else:
            _px4_takeoff(station, health)
    finally:
        station.close()
    return health


def _count_udp_heartbeats(udp_sock: socket.socket, wanted: int, seconds: float) -> int:
    """HEARTBEATs heard on UDP, until ``wanted`` or ``seconds`` (wall), reading all the while: the fuzz may
    have sped up every stream on that link, and a reader that pauses would lose datagrams to a full buffer."""
    parser = M.MAVLink(None)
    parser.robust_parsing = True
    _discard(udp_sock)
    beats = 0
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0 and beats < wanted:
        if select.select([udp_sock], [], [], left)[0]:
            for msg in parser.parse_buffer(udp_sock.recv(65535)) or []:
                beats += msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1
    return beats


def _climbed(station: Station, timeout_s: float = 30.0) -> bool:
    return station.wait("GLOBAL_POSITION_INT", timeout_s, lambda m: m.relative_alt >= (TAKEOFF_M - 0.3) * 1000) \
        is not None


def _ardupilot_takeoff(station: Station, health: Health) -> None:
    accepted = [M.MAV_RESULT_ACCEPTED]
    steps = [("GUIDED", station.command(M.MAV_CMD_DO_SET_MODE, 1, 4)),
             ("arm", station.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)),
             ("takeoff", station.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, TAKEOFF_M))]
    health.notes += [f"{name}: {result}" for name, result in steps if result != accepted]
    hb = station.wait("HEARTBEAT", 3.0, lambda m: m.custom_mode == 4)
    health.mode_ok = hb is not None
    if not health.mode_ok:
        health.notes.append("no HEARTBEAT in GUIDED")
    health.took_off = not [1 for _n, r in steps if r != accepted] and _climbed(station)
    health.height_m = station.rel_alt_m


def _px4_takeoff(station: Station, health: Health) -> None:
    accepted = M.MAV_RESULT_ACCEPTED
    station.wait("GLOBAL_POSITION_INT", 5.0)
    home_amsl_m = station.alt_amsl_m - station.rel_alt_m
    arm = station.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    takeoff = station.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, home_amsl_m + TAKEOFF_M)
    if arm != [accepted] or takeoff != [accepted]:
        health.notes.append(f"arm {arm}, takeoff {takeoff}")
        return
    health.took_off = _climbed(station)
    health.height_m = station.rel_alt_m
    if station.wait("HEARTBEAT", 15.0, lambda m: m.custom_mode == PX4_HOLD) is None:
        health.notes.append("take-off did not end in Hold")
    station.wait("NO_SUCH_MESSAGE", 1.5, every=station.setpoint)    # stream setpoints for 1.5 s, as PX4 requires
    offboard = station.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0, acks=2, every=station.setpoint)
    hb = station.wait("HEARTBEAT", 3.0, lambda m: m.custom_mode == PX4_OFFBOARD, every=station.setpoint)
    health.mode_ok = offboard == [accepted, accepted] and hb is not None
    if not health.mode_ok:
        health.notes.append(f"OFFBOARD: {offboard}")


# ----------------------------------------------------------------------------- the benchmark
def run(autopilot: str, seconds: float, seed: int, rounds: int) -> dict:
    """Fuzz one personality for ``seconds`` in ``rounds`` slices; memory sampled after each slice."""
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    sim = BundledSim(autopilot, room="open_field", port=udp.getsockname()[1], tcp=True)
    rng = random.Random(seed)
    totals = FuzzCounts()
    try:
        sim.start()
        wall0 = time.monotonic()  # the clock ratio counts from the ready line
        sim_addr = learn_sim_address(udp)
        time.sleep(1.0)
        rss = [rss_kb(sim.process.pid)]
        for _ in range(rounds):
            counts = fuzz(udp, sim_addr, sim.tcp_port, seconds / rounds, rng)
            for name in vars(totals):
                setattr(totals, name, getattr(totals, name) + getattr(counts, name))
            rss.append(rss_kb(sim.process.pid))
        alive = sim.alive()
        health = check_serving(sim.tcp_port, autopilot, udp) if alive else Health(notes=["process died"])
    finally:
        out = sim.stop()
        udp.close()
    wall_s = time.monotonic() - wall0
    simulated = re.search(r"stopped after ([\d.]+) s simulated", out)
    return {"clock_ratio": float(simulated.group(1)) / wall_s if simulated else math.nan,"autopilot": autopilot, "seconds": seconds, "seed": seed, "counts": totals, "rss_kb": rss,
            "alive": alive, "health": health, "exit": out.strip().splitlines()[-1] if out.strip() else "",
            "stderr": sim.stderr.strip()}


def _report(results: list[dict], command: str) -> str:
    lines = ["# gcs-sim under fuzz", "",
             f"Produced by `{command}` (tools/sim/fuzz_sim.py) on {sys.platform}, Python {sys.version.split()[0]}. "
             "Random bytes, mutated frames and hostile well-formed messages on UDP and TCP (TCP clients also "
             "reset mid-frame), at up to 2000 writes/s, against `gcs-sim --room open_field` in real time; then a "
             "fresh TCP ground station checks HEARTBEAT (1 Hz in simulated time), UDP still heard, and a "
             "GUIDED (ArduPilot) or take-off + OFFBOARD (PX4) flight. Memory is the process's VmRSS, sampled "
             "after each tenth of the run.", "",
             "| autopilot | fuzz (s) | UDP datagrams | TCP writes | TCP sessions (reset) | alive | HEARTBEAT gaps (ms) "
             "| take-off | RSS start -> end (MB) | RSS max (MB) | sim clock / wall clock | ok |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        c, h, rss = r["counts"], r["health"], r["rss_kb"]
        lines.append(f"| {r['autopilot']} | {r['seconds']:g} | {c.udp_datagrams} | {c.tcp_writes} | "
                     f"{c.tcp_sessions} ({c.tcp_resets}) | {'yes' if r['alive'] else 'NO'} | "
                     f"{', '.join(map(str, h.heartbeat_gaps_ms))} | "
                     f"{'yes, %.2f m' % h.height_m if h.took_off else 'NO'} | "
                     f"{rss[0] / 1024:.1f} -> {rss[-1] / 1024:.1f} | {max(rss) / 1024:.1f} | {r['clock_ratio']:.2f} | "
                     f"{'yes' if r['alive'] and h.ok else 'NO'} |")
    lines += ["", "The sim reads a bounded number of datagrams and bytes per link per physics tick, so a flood never "
              "skips physics: it slows the simulated clock instead (the last column, over the whole run including "
              "the checks; 1.00 is real time). A ground station's wall-clock timers then see a slow vehicle, not a "
              "wrong one; the run ends with the same checks passing once the flood stops.",
              "", "Exit lines of the sim (what it counted and ignored):", ""]
    lines += [f"- {r['autopilot']}: `{r['exit']}`" for r in results]
    notes = [f"- {r['autopilot']}: {'; '.join(r['health'].notes)}" for r in results if r["health"].notes]
    if notes:
        lines += ["", "Notes:", "", *notes]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.sim.fuzz_sim", description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="fuzz time per personality (default 120)")
    parser.add_argument("--autopilot", choices=["ardupilot", "px4", "both"], default="both")
    parser.add_argument("--seed", type=int, default=20261202)
    parser.add_argument("--no-write", action="store_true", help="print only; do not write docs/bench/fuzz_sim.md")
    args = parser.parse_args(argv)
    if not 1.0 <= args.seconds <= 86400:
        parser.error("--seconds: 1 to 86400")
    autopilots = ["ardupilot", "px4"] if args.autopilot == "both" else [args.autopilot]
    results = [run(ap, args.seconds, args.seed, rounds=10) for ap in autopilots]
    command = "python -m tools.sim.fuzz_sim" + ("" if args.seconds == 120 else f" --seconds {args.seconds:g}")
    text = _report(results, command)
    print(text)
    if not args.no_write:
        out = REPO / "docs" / "bench" / "fuzz_sim.md"
        out.write_text(text, encoding="utf-8")
        print(f"wrote {out}")
    return 0 if all(r["alive"] and r["health"].ok for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
