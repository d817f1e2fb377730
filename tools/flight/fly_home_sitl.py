"""Say "return home" to a real autopilot: the ArduCopter or PX4 SITL of ../shared/sitl, flown by voice.

Starts the SITL from a cold boot, then runs gcs-voice as a user would (``python -m gcs_voice --connect ...
--say ... --takeoff 1.5``, Whisper base) on three espeak-ng utterances: "move forward three metres", "go left
two metres", "return home". With ``--lands`` a settings file sets ``return_home_lands = 1`` (the autopilot's own
RTL) and only the first and last are said. From the session's tlog (the vehicle's own LOCAL_POSITION_NED) it
reports how far from home the vehicle was when "return home" was decided, how far from the point it hovered at
after take-off it ended, and its height then against before; with ``--lands``, whether it showed RTL, landed
and disarmed, and where.

    python -m tools.flight.fly_home_sitl --vehicle arducopter-sitl [--lands] [--out docs/bench/home.md]

Real time: a cold ArduCopter arms about 41 s after boot; the whole flight takes 2-4 minutes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from gcs_voice.session.flight_log import read_flight
from gcs_voice.session.sim_process import free_udp_port
from tools.speech.make_demo_audio import synthesize
from tools.flight.soak_two_stations import PX4_START, SITL_START, _start_sitl

REPO = Path(__file__).resolve().parents[2]
MODEL = REPO.parent / "shared" / "models" / "faster-whisper-base"
RTL_MODES = {"arducopter-sitl": 6, "px4-sitl": 84148224}  # ArduCopter RTL; PX4 AUTO (4) sub RTL (5): 5 << 24 | 4 << 16


def _wav(path: Path, text: str) -> Path:
    path.write_bytes(synthesize(text, "en-us", 175))  # the demo's own espeak-ng rendering, 0.3 s either side
    return path


def _home_position(tlog: Path) -> tuple[float, float] | None:
    """The last HOME_POSITION's local (x, y) in the tlog (what the bridge flies back to)."""
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(str(tlog))
    home = None
    while (msg := log.recv_match(type="HOME_POSITION")) is not None:
        home = (float(msg.x), float(msg.y))
    return home


def fly(vehicle: str, lands: bool, work: Path, px4_start: Path = PX4_START) -> list[str]:
    """One flight; the report's lines."""
    texts = ["move forward three metres"] + ([] if lands else ["go left two metres"]) + ["return home"]
    wavs = [_wav(work / f"{i}.wav", t) for i, t in enumerate(texts)]
    if vehicle == "px4-sitl":
        pid, connection = _start_sitl([str(px4_start)]), "udpin:127.0.0.1:14540"
    else:
        port = free_udp_port()
        pid, connection = _start_sitl([str(SITL_START), str(port)]), f"udpin:127.0.0.1:{port}"
    extra = []
    if lands:
        config = work / "rtl.toml"
        config.write_text("[motion]\nreturn_home_lands = 1\n", encoding="utf-8")
        extra = ["--config", str(config)]
    cmd = [sys.executable, "-m", "gcs_voice", "--connect", connection, "--say", *map(str, wavs), "--gap", "12",
           "--hold", "3" if lands else "15", "--takeoff", "1.5", "--headless", "--json", "--log-dir", str(work),
           "--log-name", "flight", "--engine", "whisper", "--model", str(MODEL), "--no-stop-spotter", *extra]
    try:
        done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=900)
    finally:
        os.kill(pid, 15)
    events = []
    for line in done.stdout.splitlines():
        try:
            events.append(json.loads(line))
        except json.JSONDecodeError:
            pass
    commands = [e for e in events if e["kind"] == "command" and e.get("origin") == "voice"]
    lines = [f"`{' '.join(Path(c).name if c.startswith('/') else c for c in cmd[2:])}` -> exit {done.returncode}",
             "", "decided: " + ", ".join(f"{c['action']}{' ' + c['amount'] if c.get('amount') else ''}" for c in commands)]
    home_cmd = next((c for c in commands if c["action"] == "return_home"), None)
    if home_cmd is None or not commands:
        return lines + ["", "no 'return home' decided: " + "; ".join(e["msg"] for e in events if e["kind"] == "rejected")]
    flight = read_flight(work / "flight.tlog")
    start = flight.position_at(commands[0]["sent_t"])
    at_home_cmd = flight.position_at(home_cmd["sent_t"])
    end = flight.position_at(flight.track.t_s[-1])
    lines.append(f"'return home' decided {math.dist(start[:2], at_home_cmd[:2]):.2f} m from where it hovered after "
                 f"take-off; the flight ended {math.dist(start[:2], end[:2]):.2f} m from it, "
                 f"{end[2] - at_home_cmd[2]:+.2f} m in height against when it was said")
    home = _home_position(work / "flight.tlog")
    if home is not None:
        lines.append(f"the vehicle's HOME_POSITION (local x, y): ({home[0]:.2f}, {home[1]:.2f}); the flight ended "
                     f"{math.dist(home, end[:2]):.2f} m from it")
    if lands:
        rtl = any(mode == RTL_MODES[vehicle] for _t, mode, _armed in flight.modes)
        landed = [e for e in events if e["kind"] == "flight" and e.get("what") == "landed"]
        lines.append(f"RTL seen in the HEARTBEAT: {'yes' if rtl else 'no'}; disarmed at the end: "
                     f"{'yes' if flight.modes and not flight.modes[-1][2] else 'no'}; "
                     + (landed[-1]["msg"] if landed else "no landing reported"))
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.flight.fly_home_sitl", description=__doc__.splitlines()[0])
    parser.add_argument("--vehicle", choices=("arducopter-sitl", "px4-sitl"), default="arducopter-sitl")
    parser.add_argument("--lands", action="store_true", help="return_home_lands = 1: the autopilot's RTL")
    parser.add_argument("--out", type=Path, help="append the report to this markdown file")
    parser.add_argument("--px4-start", type=Path, default=PX4_START,
                        help="PX4's start script (a copy with its bin/px4-* command links restored: docs/link.md)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fly-home-") as tmp:
        lines = fly(args.vehicle, args.lands, Path(tmp), args.px4_start)
    report = "\n".join([f"## {args.vehicle}, return_home_lands = {int(args.lands)}", "",
                        f"`python -m tools.flight.fly_home_sitl --vehicle {args.vehicle}{' --lands' if args.lands else ''}`", "",
                        *lines, ""])
    print(report)
    if args.out:
        with open(args.out, "a", encoding="utf-8") as f:
            f.write(report + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
