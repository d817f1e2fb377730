"""The MAVLink endpoint: links in, personality and vehicle in the middle, telemetry out, one loop.

``SimServer.step()`` is one physics tick: read what the links have (bounded, so a flood cannot stall
the physics), dispatch it, step the vehicle, let the personality react, send what is due. Tests call
``run_for(sim_s)`` (lockstep: simulated time only moves when asked); the command line calls
``serve(speedup)`` which paces the same loop against the wall clock.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sim_bridge import telemetry
from sim_bridge.autopilot import personality_class
from sim_bridge.autopilot.base import INT32_MAX, Autopilot, CommandContext
from sim_bridge.params import ParamStore
from sim_bridge.protocols import ParamProtocol, mission_reply
from sim_bridge.signing import SimSigning
from sim_bridge.transport import Link, TcpClientLink, TcpServer, TlogWriter, UdpOutLink, wait_readable
from sim_bridge.vehicle import Vehicle, VehicleEvent

__all__ = ["SimServer", "ServerStats"]

SYSTEM_ID = 1
COMPONENT_ID = 1
#: How often (simulated s) the link statistics are summarised in a STATUSTEXT, when something changed.
STATS_PERIOD_S = 10.0
#: Statustext bodies are 50 bytes on the wire.
STATUSTEXT_BYTES = 50
HEADER_LEN_V1 = 6


def interval_us(rate_hz: float) -> int:
    """MESSAGE_INTERVAL.interval_us for a rate: -1 = off, else the interval, within int32 (the field's type)."""
    if rate_hz <= 0:
        return -1
    return int(min(INT32_MAX, max(1, round(1e6 / rate_hz))))


@dataclass
class ServerStats:
    """Why input was ignored, summed over links; reported as a 'SIM rx ...' STATUSTEXT and on exit.

    The text (at most every 10 simulated s, only when a count changed) reads
    ``SIM rx bad,unk,fgn,drop,clamp B,U,F,D,C``: bad frames (CRC, truncated, garbage), unknown message
    ids, messages for another system/component, setpoints dropped (frame, mask, NaN), setpoints clamped.
    """

    bad_frames: int = 0
    unknown_messages: int = 0
    foreign: int = 0           # addressed to another system or component
    handler_errors: int = 0    # a message that made a handler fail (a bug: reported, never fatal)
    received: int = 0
    sent: int = 0

    def summary(self, rejected_setpoints: int, clamped_setpoints: int) -> str:
        counts = (self.bad_frames, self.unknown_messages, self.foreign, rejected_setpoints, clamped_setpoints)
        return "SIM rx bad,unk,fgn,drop,clamp " + ",".join(str(n) for n in counts)


class SimServer:
    """One simulated vehicle with its personality, speaking over any number of links."""

    def __init__(self, vehicle: Vehicle, autopilot: str, params: ParamStore, home: tuple[float, float, float],
                 physics_dt_s: float = 0.01, tlog: TlogWriter | None = None, epoch_unix_s: float | None = None) -> None:
        self.vehicle = vehicle
        self.params = params
        self.dt_s = physics_dt_s
        self.tlog = tlog
        self.links: list[Link] = []
        self.tcp_servers: list[TcpServer] = []
        self.stats = ServerStats()
        self.epoch_unix_s = time.time() if epoch_unix_s is None else epoch_unix_s
        self._tlog_mav = mavlink.MAVLink(None, srcSystem=SYSTEM_ID, srcComponent=COMPONENT_ID)
        self._text_id = 0
        self._last_summary = ""
        self._next_summary_s = STATS_PERIOD_S
        self._home_sent = False
        self.last_handler_error = ""
        self.autopilot: Autopilot = personality_class(autopilot)(vehicle, params, self, home, self.epoch_unix_s)
        self.param_protocol = ParamProtocol(params, self)
        self.signing = SimSigning(autopilot)      # no key until --signing-key or a SETUP_SIGNING
        # Message intervals are per link, as in both firmwares (SET_MESSAGE_INTERVAL changes the asking link
        # only); defaults are shared. The tlog records what a link with no overrides receives.
        self._default_hz: dict[int, float] = {}
        self._schedules: dict[int, tuple[Link, telemetry.Schedule]] = {}   # id(link) -> (link, its schedule)
        self._tlog_schedule = telemetry.Schedule()
        self._setup_streams()
        params.on_change(self._on_param_change)

    # ----------------------------------------------------------------- links
    def add_link(self, link: Link) -> None:
        self.signing.attach(link)
        self.links.append(link)
        self._schedule_for(link)

    def _schedule_for(self, link: Link) -> telemetry.Schedule:
        entry = self._schedules.get(id(link))
        if entry is None or entry[0] is not link:        # (an id can be reused once a link is gone)
            entry = self._schedules[id(link)] = (link, telemetry.Schedule())
            for msg_id, rate_hz in self._default_hz.items():
                entry[1].set_default(msg_id, rate_hz)
        return entry[1]

    def _set_default_rate(self, msg_id: int, rate_hz: float) -> None:
        self._default_hz[msg_id] = rate_hz
        for schedule in (self._tlog_schedule, *(entry[1] for entry in self._schedules.values())):
            schedule.set_default(msg_id, rate_hz)

    def add_tcp_server(self, server: TcpServer) -> None:
        self.tcp_servers.append(server)

    def close(self) -> None:
        for link in self.links:
            link.close()
        for server in self.tcp_servers:
            server.close()
        if self.tlog is not None:
            self.tlog.close()

    # ----------------------------------------------------------------- streams
    def _setup_streams(self) -> None:
        self._set_default_rate(mavlink.MAVLINK_MSG_ID_HEARTBEAT, 1.0)
        for name, rate_hz in self.autopilot.stream_rates().items():
            self._set_default_rate(telemetry.message_id(name), rate_hz)

    def _on_param_change(self, name: str, value: float) -> None:
        for msg_name in self.autopilot.messages_paced_by(name):
            self._set_default_rate(telemetry.message_id(msg_name), value)

    def request_data_stream(self, msg: Any) -> None:
        """REQUEST_DATA_STREAM (no ACK): what it does is the personality's."""
        self.autopilot.on_request_data_stream(msg)

    # ----------------------------------------------------------------- output (the personality's Outbox)
    def send(self, msg: Any, link: Link | None = None) -> None:
        targets = self.links if link is None else [link]
        for target in targets:
            if not target.closed:
                target.send_bytes(msg.pack(target.mav))
        self.stats.sent += 1
        if self.tlog is not None:
            self.tlog.write(self._tlog_time_us(), msg.pack(self._tlog_mav))

    def text(self, severity: int, text: str) -> None:
        data = text.encode("utf-8", "replace")
        if len(data) <= STATUSTEXT_BYTES or not self.autopilot.chunks_long_texts:
            self.send(self._tlog_mav.statustext_encode(severity, data[:STATUSTEXT_BYTES]))
            return
        self._text_id = self._text_id % 65535 + 1          # PX4: long texts in chunks sharing an id
        for seq, start in enumerate(range(0, len(data), STATUSTEXT_BYTES)):
            self.send(self._tlog_mav.statustext_encode(severity, data[start:start + STATUSTEXT_BYTES],
                                                       self._text_id, seq))

    def send_heartbeat_now(self) -> None:
        self.send_now(mavlink.MAVLINK_MSG_ID_HEARTBEAT)

    def send_now(self, msg_id: int) -> None:
        """Send one message outside its schedule (mode change HEARTBEAT, HOME_POSITION when home is set)."""
        msg = telemetry.build(msg_id, self.autopilot, self._tlog_mav)
        if msg is not None:
            self.send(msg)

    def _ack(self, command: int, result: int, link: Link, src_system: int, src_component: int,
             verdict: bool = False) -> None:
        """A COMMAND_ACK addressed to the sender, on its link; a personality's ``verdict`` on PX4 goes to
        every link that saw the sender (see ``Autopilot.acks_on_links_that_saw_the_sender``)."""
        ack = self._tlog_mav.command_ack_encode(command, result, 0, 0, src_system, src_component)
        if not (verdict and self.autopilot.acks_on_links_that_saw_the_sender):
            self.send(ack, link)
            return
        self.send(ack, link)   # logged once; the same ACK on the other links that saw the sender
        sender = (src_system, src_component)
        for other in self.links:
            if other is not link and sender in other.seen and not other.closed:
                other.send_bytes(ack.pack(other.mav))

    def _tlog_time_us(self) -> int:
        return int((self.epoch_unix_s + self.vehicle.time_s) * 1e6)

    # ----------------------------------------------------------------- input
    def poll(self) -> None:
        for server in self.tcp_servers:
            for client in server.accept():
                self.add_link(client)
        for link in list(self.links):
            for chunk in link.read():
                link.stats.bytes_in += len(chunk)
                try:
                    msgs = link.mav.parse_buffer(chunk) or []
                except Exception:       # pymavlink can raise on pathological input: count, never crash
                    msgs = []
                    self.stats.bad_frames += 1
                    self._reset_parser(link)
                if isinstance(link, UdpOutLink):   # a datagram never continues in the next one
                    if link.mav.buf_len() > 0:
                        self.stats.bad_frames += 1
                    self._reset_parser(link)
                for msg in msgs:
                    self._dispatch(msg, link)
        self._drop_closed_links()

    def _drop_closed_links(self) -> None:
        """Forget TCP clients that left or were dropped (during a read *or* a send): a closed socket has fd -1."""
        gone = [link for link in self.links if link.closed and isinstance(link, TcpClientLink)]
        if gone:
            self.links = [link for link in self.links if not any(link is g for g in gone)]
            for link in gone:
                self._schedules.pop(id(link), None)

    @staticmethod
    def _reset_parser(link: Link) -> None:
        link.mav.buf = bytearray()
        link.mav.buf_index = 0
        link.mav.expected_length = HEADER_LEN_V1 + 2

    def _dispatch(self, msg: Any, link: Link) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            if "unknown MAVLink message ID" in str(getattr(msg, "reason", "")):
                self.stats.unknown_messages += 1
            else:
                self.stats.bad_frames += 1
            return
        if kind.startswith("UNKNOWN_"):
            self.stats.unknown_messages += 1
            return
        self.stats.received += 1
        link.stats.packets_in += 1
        if self.tlog is not None:
            self.tlog.write(self._tlog_time_us(), bytes(msg.get_msgbuf()))
        if not self.signing.accept(msg):       # with a key: unsigned, wrongly signed or replayed
            return
        link.seen.add((msg.get_srcSystem(), msg.get_srcComponent()))
        target = getattr(msg, "target_system", 0)
        component = getattr(msg, "target_component", 0)
        if target not in (0, SYSTEM_ID) or component not in (0, COMPONENT_ID) or msg.get_srcSystem() == SYSTEM_ID:
            self.stats.foreign += 1
            return
        handler = self._HANDLERS.get(kind)
        if handler is None:
            return
        try:
            handler(self, msg, link)
        except Exception as exc:   # a bug, never fatal: counted and named in the exit line
            self.stats.handler_errors += 1
            self.last_handler_error = f"{kind}: {exc!r}"

    def _on_command(self, msg: Any, link: Link) -> None:
        if msg.get_type() == "COMMAND_INT":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        else:
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        ctx = CommandContext(msg.command, params, link, msg.get_srcSystem(), msg.get_srcComponent())
        common = self._common_command(ctx)
        results = common or self.autopilot.on_command(ctx)
        for i, result in enumerate(results):   # PX4's DO_SET_MODE: the module's ACK, then commander's verdict
            verdict = common is None and i == len(results) - 1
            self._ack(ctx.command, result, link, ctx.src_system, ctx.src_component, verdict)
        for reply in ctx.replies:
            self.send(reply, link)

    def _common_command(self, ctx: CommandContext) -> list[int] | None:
        """Commands answered the same way by both personalities; None = not one of them."""
        p = ctx.params
        wanted = {mavlink.MAV_CMD_REQUEST_MESSAGE: p[0] if math.isfinite(p[0]) else -1,
                  mavlink.MAV_CMD_GET_HOME_POSITION: mavlink.MAVLINK_MSG_ID_HOME_POSITION,
                  mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                  }.get(ctx.command)
        if wanted is not None:
            reply = telemetry.build(int(wanted), self.autopilot, self._tlog_mav) if wanted >= 0 else None
            if reply is None:
                return [mavlink.MAV_RESULT_FAILED]
            ctx.replies = [reply]
            return [mavlink.MAV_RESULT_ACCEPTED]
        if ctx.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            if not (math.isfinite(p[0]) and math.isfinite(p[1])) or int(p[0]) not in telemetry.BUILDERS:
                return [mavlink.MAV_RESULT_FAILED]
            result, rate = self.autopilot.message_interval(int(p[0]), p[1])
            if result == mavlink.MAV_RESULT_ACCEPTED:
                # never faster than the physics loop (ArduPilot caps at 80 % of its loop rate likewise)
                self._schedule_for(ctx.link).set_override(int(p[0]), rate if not rate else min(rate, 1.0 / self.dt_s))
            return [result]
        if ctx.command == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            if not math.isfinite(p[0]) or int(p[0]) not in telemetry.BUILDERS:
                return [mavlink.MAV_RESULT_FAILED]
            rate = self._schedule_for(ctx.link).rate_hz(int(p[0]))
            ctx.replies = [self._tlog_mav.message_interval_encode(int(p[0]), interval_us(rate))]
            return [mavlink.MAV_RESULT_ACCEPTED]
        return None

    def _on_set_mode(self, msg: Any, link: Link) -> None:
        if msg.target_system not in (0, SYSTEM_ID):
            return
        for result in self.autopilot.on_set_mode(msg):   # PX4: commander's ACK only
            self._ack(mavlink.MAV_CMD_DO_SET_MODE, result, link, msg.get_srcSystem(), msg.get_srcComponent(),
                      verdict=True)

    def _on_setpoint(self, msg: Any, link: Link) -> None:
        self.autopilot.on_setpoint(msg)

    def _on_param(self, msg: Any, link: Link) -> None:
        self.param_protocol.handle(msg, link)

    def _on_mission(self, msg: Any, link: Link) -> None:
        reply = mission_reply(msg, self.autopilot.mission_items(), self._tlog_mav)
        if reply is not None:
            self.send(reply, link)

    def _on_data_stream(self, msg: Any, link: Link) -> None:
        self.request_data_stream(msg)

    def _on_setup_signing(self, msg: Any, link: Link) -> None:
        if self.vehicle.armed:          # both firmwares refuse a key change in flight
            self.text(mavlink.MAV_SEVERITY_WARNING, self.signing.armed_refusal)
            return
        self.signing.setup_signing(msg)

    def _on_timesync(self, msg: Any, link: Link) -> None:
        if msg.tc1 == 0:
            self.send(self._tlog_mav.timesync_encode(int(self.vehicle.time_s * 1e9), msg.ts1), link)

    _HANDLERS: dict[str, Callable[["SimServer", Any, Link], None]] = {
        "COMMAND_LONG": _on_command, "COMMAND_INT": _on_command, "SET_MODE": _on_set_mode,
        "SET_POSITION_TARGET_LOCAL_NED": _on_setpoint,
        "PARAM_REQUEST_LIST": _on_param, "PARAM_REQUEST_READ": _on_param, "PARAM_SET": _on_param,
        "MISSION_REQUEST_LIST": _on_mission, "MISSION_REQUEST_INT": _on_mission, "MISSION_REQUEST": _on_mission,
        "MISSION_COUNT": _on_mission, "MISSION_CLEAR_ALL": _on_mission,
        "REQUEST_DATA_STREAM": _on_data_stream, "TIMESYNC": _on_timesync, "SETUP_SIGNING": _on_setup_signing,
    }

    # ----------------------------------------------------------------- the loop
    def step(self) -> None:
        """One physics tick with everything around it."""
        self.poll()
        events = self.vehicle.step(self.dt_s)
        self.autopilot.update(events)
        for text in self._physics_texts(events):
            self.text(mavlink.MAV_SEVERITY_INFO, text)
        if self.autopilot.booted and not self._home_sent:
            self._home_sent = True      # ArduCopter sends HOME_POSITION when home is set
            self.send_now(mavlink.MAVLINK_MSG_ID_HOME_POSITION)
        self.param_protocol.trickle()
        self._send_due()
        if self.vehicle.time_s >= self._next_summary_s:
            self._next_summary_s += STATS_PERIOD_S
            summary = self.summary_text()
            if summary != self._last_summary and any(n != "0" for n in summary.rsplit(" ", 1)[1].split(",")):
                self._last_summary = summary
                self.text(mavlink.MAV_SEVERITY_INFO, summary)

    def _send_due(self) -> None:
        """Each link gets what its own schedule says is due; each message is built once per tick."""
        now_s = self.vehicle.time_s
        built: dict[int, Any] = {}

        def message(msg_id: int) -> Any:
            if msg_id not in built:
                built[msg_id] = telemetry.build(msg_id, self.autopilot, self._tlog_mav)
                if built[msg_id] is not None:
                    self.stats.sent += 1
            return built[msg_id]

        for link in self.links:
            for msg_id in self._schedule_for(link).due(now_s):
                msg = message(msg_id)
                if msg is not None and not link.closed:
                    link.send_bytes(msg.pack(link.mav))
        if self.tlog is not None:
            for msg_id in self._tlog_schedule.due(now_s):
                msg = message(msg_id)
                if msg is not None:
                    self.tlog.write(self._tlog_time_us(), msg.pack(self._tlog_mav))

    def summary_text(self) -> str:
        return self.stats.summary(self.autopilot.rejected_setpoints, self.vehicle.clamped_setpoints)

    def _physics_texts(self, events: list[VehicleEvent]) -> list[str]:
        """SITL-style "SIM Hit ..." texts for contacts (and, as ArduPilot SITL does, for touchdown)."""
        state = self.vehicle.state
        speed = float(math.sqrt(sum(float(v) ** 2 for v in state.vel_ned_m_s)))
        texts = [f"SIM Hit {contact.obstacle_name} at {speed:.2f} m/s" for contact in self.vehicle.multicopter.pop_events()]
        if self.autopilot.touchdown_is_a_hit and VehicleEvent.TOUCHDOWN in events:
            texts.append(f"SIM Hit ground at {self.vehicle.touchdown_speed_m_s:.2f} m/s")
        return texts

    def run_for(self, sim_s: float) -> None:
        """Lockstep: advance ``sim_s`` of simulated time as fast as the CPU allows."""
        for _ in range(max(1, int(round(sim_s / self.dt_s)))):
            self.step()

    def serve(self, speedup: float | None, should_stop: Callable[[], bool]) -> None:
        """Run until ``should_stop()``; ``speedup`` None = as fast as possible, else paced to the wall clock."""
        wall0, sim0 = time.monotonic(), self.vehicle.time_s
        while not should_stop():
            if speedup is not None:
                lag_s = wall0 + (self.vehicle.time_s - sim0) / speedup - time.monotonic()
                if lag_s > 0:
                    # Ahead of the wall clock: wait, waking for input, which is read at once. The physics
                    # waits for its time: stepping on every wake-up ran the clock ahead under a flood, then
                    # froze the vehicle (every stream) until the wall clock caught up.
                    self._drop_closed_links()      # a send during the last tick may have closed a client
                    wait_readable([*self.links, *self.tcp_servers], lag_s)
                    self.poll()
                    continue
                if lag_s < -0.5:        # too slow for this speed-up: slip instead of bursting to catch up
                    wall0 -= lag_s + 0.5
            self.step()
