"""The ground station's MAVLink channel to one vehicle: the connection and the thread that owns it.

One reader/timer thread receives and tracks state, sends our GCS HEARTBEAT at 1 Hz, re-sends the
current setpoint at 10 Hz while a stream is active, and notices a silent vehicle (link lost after
``link_lost_s``: nothing more is commanded; the first setpoint after it returns is a stop). Other
threads read ``state``, wait on it (``wait_for``), send messages (``send``, ``send_command``) and
gather the answers to them (``collect_acks``): that is all ``link.operations`` needs.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.errors import LinkError
from gcs_voice.link.acks import AckCollector
from gcs_voice.link.connection import open_connection, parse_connection
from gcs_voice.link.setpoints import Setpoint, setpoint_fields
from gcs_voice.link.security import LinkSecurity, SecurityHooks
from gcs_voice.link.state import StatusText, VehicleState, VehicleStateTracker
from gcs_voice.link.tlog import TlogWriter
from gcs_voice.settings import Settings, load_settings

if TYPE_CHECKING:  # annotations only: mavutil is imported by link.connection, after MAVLINK20 is set
    from pymavlink import mavutil

__all__ = ["LinkChannel", "SetpointSource"]

#: called at the stream rate with the latest state; returns the setpoint to send
SetpointSource = Callable[[VehicleState], Setpoint]


class LinkChannel:
    """The connection and its thread: ``open()``, ``state``, ``wait_for``, ``send``, the setpoint stream."""

    def __init__(self, connection: str, settings: Settings | None = None, tlog_path: str | Path | None = None,
                 on_event: Callable[[str], None] | None = None, security: LinkSecurity | None = None) -> None:
        self.spec = parse_connection(connection)
        self.security = security or LinkSecurity()
        self._guard: SecurityHooks | None = None
        self.settings = settings or load_settings()
        try:
            self.tlog = TlogWriter(tlog_path) if tlog_path else None
        except OSError as exc:
            raise LinkError(f"cannot write the flight log {tlog_path}: {exc.strerror or exc}") from None
        self.on_event = on_event or (lambda _line: None)
        self._battery_warned = False
        self.tracker = VehicleStateTracker(self.settings.gcs_system_id, self.settings.link_lost_s,
                                           gcs_component_id=self.settings.gcs_component_id)
        self._conn: mavutil.mavfile | None = None
        self._lock = threading.RLock()
        self._changed = threading.Condition(self._lock)
        self._send_lock = threading.Lock()
        #: held from reading the stream's source to sending its setpoint, and while the source changes: a
        #: tick that read the old source cannot send it after a new command went out
        self._tick_lock = threading.RLock()
        self._collectors: list[AckCollector] = []
        self._source: SetpointSource | None = None
        self._stop_first = False
        self._link_was_ok = False
        self._link_was_lost = False
        self._thread: threading.Thread | None = None
        self._running = False
        self._boot_s = time.monotonic()
        self.last_setpoint: Setpoint | None = None
        self.setpoints_sent = 0
        self.read_errors = 0
        #: called (in a thread of its own) when a vehicle lost for ``link_lost_s`` is heard again
        self.on_link_back: Callable[[], object] | None = None
        #: called in the link's thread when the link is lost or heard (again) and at each vehicle HEARTBEAT
        #: (mode, armed): a watcher (the session loop) waits for this instead of polling ``state``. It must
        #: not block.
        self.on_change: Callable[[], object] | None = None

    # ---- lifetime -------------------------------------------------------------------------------
    def open(self) -> Self:
        self._conn = open_connection(self.spec, self.settings.gcs_system_id, self.settings.gcs_component_id)
        self._guard = self.security.attach(self._conn, self.on_event)   # signing, --lock-vehicle
        self._running = True
        self._thread = threading.Thread(target=self._loop, name="vehicle-link", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self._conn is not None:
            try:
                self._conn.close()
            except OSError:
                pass
        if self._guard is not None:
            self._guard.close()
        if self.tlog is not None:
            self.tlog.close()

    def __enter__(self) -> Self:
        return self.open()

    def __exit__(self, *_exc: Any) -> None:
        self.close()

    # ---- state ----------------------------------------------------------------------------------
    @property
    def state(self) -> VehicleState:
        with self._lock:
            return self.tracker.snapshot(time.monotonic())

    def wait_for(self, predicate: Callable[[VehicleState], bool], timeout_s: float) -> VehicleState | None:
        """Block until ``predicate(state)`` holds (that state) or ``timeout_s`` passes (None)."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while True:
                state = self.tracker.snapshot(time.monotonic())
                if predicate(state):
                    return state
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(min(left, 0.1))

    def wait_vehicle(self, timeout_s: float = 30.0) -> VehicleState:
        """Wait for a flight controller's HEARTBEAT; LinkError if none comes."""
        state = self.wait_for(lambda s: s.heartbeats > 0 and s.link_ok, timeout_s)
        if state is None:
            why = self._guard.diagnosis() if self._guard is not None else ""
            raise LinkError(f"no vehicle heard on {self.spec} within {timeout_s:g} s{why}")
        return state

    # ---- the reader / timer thread --------------------------------------------------------------
    def _loop(self) -> None:
        period_hb, period_sp = 1.0 / self.settings.heartbeat_hz, 1.0 / self.settings.setpoint_hz
        next_hb = next_sp = time.monotonic()
        while self._running:
            try:
                self._receive(timeout_s=min(0.02, max(0.0, min(next_hb, next_sp) - time.monotonic())))
                now = time.monotonic()
                if now >= next_hb:
                    next_hb = max(next_hb + period_hb, now)
                    self.send(self._conn.mav.heartbeat_encode(
                        mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))
                self._check_link(now)
                if now >= next_sp:
                    next_sp = max(next_sp + period_sp, now)
                    self._stream_tick()
            except Exception as exc:  # this thread is the link: report a bug, never die of it
                self.read_errors += 1
                self.on_event(f"link thread error (ignored): {exc!r}")
                time.sleep(0.05)

    def _receive(self, timeout_s: float) -> None:
        try:
            msg = self._conn.recv_match(blocking=True, timeout=timeout_s)
            while msg is not None and self._running:
                self._take(msg)
                msg = self._conn.recv_match(blocking=False)
        except Exception:  # a socket error or a parser surprise must not end the link
            self.read_errors += 1
            time.sleep(0.01)

    def _take(self, msg: mavlink.MAVLink_message) -> None:
        if msg.get_type() == "BAD_DATA":
            return
        if self.tlog is not None:
            self.tlog.write(msg.get_msgbuf())
        with self._changed:
            mode_before, armed_before = self.tracker.state.mode, self.tracker.state.armed
            heartbeats_before = self.tracker.state.heartbeats
            events = self.tracker.update(msg, time.monotonic())
            mode_after, armed_after = self.tracker.state.mode, self.tracker.state.armed
            heartbeat = self.tracker.state.heartbeats != heartbeats_before
            for event in events:
                for collector in self._collectors:
                    collector.take(event)
            self._changed.notify_all()
        if heartbeat:
            self._tell_watcher()
        if self._guard is not None:
            self._guard.observe(msg, self.tracker.state.system_id)
        if mode_before is not None and (mode_after, armed_after) != (mode_before, armed_before):
            self.on_event(f"vehicle now {mode_after}, {'armed' if armed_after else 'disarmed'}")
        for event in events:
            if isinstance(event, StatusText):
                self.on_event(f"vehicle: {event.text}")
        self._check_battery(self.tracker.state.battery_pct)

    def _check_battery(self, pct: int | None) -> None:
        """Say once when the charge falls below ``battery_low_pct``, whatever the autopilot's own warnings are
        set to; again only after it has been 5 points above (another battery)."""
        low = self.settings.battery_low_pct
        if pct is None or low <= 0:
            return
        if pct < low and not self._battery_warned:
            self._battery_warned = True
            self.on_event(f"battery low: {pct} % left (warning below {low:g} %)")
        elif pct >= low + 5:
            self._battery_warned = False

    def _check_link(self, now: float) -> None:
        with self._lock:
            state = self.tracker.snapshot(now)
        if state.last_heard_s is None or state.link_ok == self._link_was_ok:
            return
        self._link_was_ok = state.link_ok
        if not state.link_ok:
            self._stop_first = self._link_was_lost = True
            self.on_event(f"link lost: vehicle silent for {self.settings.link_lost_s:g} s")
        elif not self._link_was_lost:
            self.on_event(f"link up: {state.autopilot or 'unknown autopilot'} system {state.system_id}")
        else:
            self.on_event("link back")
            if self.on_link_back is not None:  # e.g. a rebooted autopilot forgot our message intervals
                threading.Thread(target=self.on_link_back, name="link-back", daemon=True).start()
        with self._changed:
            self._changed.notify_all()
        self._tell_watcher()

    def _tell_watcher(self) -> None:
        watcher = self.on_change
        if watcher is not None:
            watcher()

    # ---- sending, and the answers ------------------------------------------------------------------
    @property
    def mav(self) -> mavlink.MAVLink:
        """The MAVLink encoder of this connection: ``link.send(link.mav.command_long_encode(...))``."""
        return self._conn.mav

    @property
    def running(self) -> bool:
        """Open and not yet closing: an operation waiting on the vehicle gives up when this turns False."""
        return self._running

    def send(self, msg: mavlink.MAVLink_message, time_s: float | None = None) -> None:
        """Send one message (any thread) and log it; ``time_s`` stamps the .tlog record (default: now)."""
        with self._send_lock:
            try:
                self._conn.mav.send(msg)
            except OSError:
                return
            if self.tlog is not None:
                self.tlog.write(msg.get_msgbuf(), time_s)

    @contextmanager
    def collect_acks(self) -> Iterator[AckCollector]:
        """Within the block, every COMMAND_ACK and STATUSTEXT the reader hears is also put in the collector."""
        collector = AckCollector()
        with self._lock:
            self._collectors.append(collector)
        try:
            yield collector
        finally:
            with self._lock:
                self._collectors.remove(collector)

    # ---- setpoint stream ------------------------------------------------------------------------
    def start_stream(self, source: SetpointSource | None = None) -> None:
        """Re-send ``source(state)`` at ``setpoint_hz`` from now on (default: hold at the current heading)."""
        with self._tick_lock, self._lock:
            self._source = source or self._hold_source()

    def stop_stream(self) -> None:
        with self._tick_lock, self._lock:
            self._source = None

    @property
    def streaming(self) -> bool:
        return self._source is not None

    def hold(self) -> None:
        """Zero velocity at the current heading target, streamed."""
        self.start_stream(self._hold_source())

    def _hold_source(self) -> SetpointSource:
        """Stop at the heading target being streamed, or at the current heading when nothing streams."""
        state = self.state
        if self._source is not None and self.last_setpoint is not None:
            yaw = self.last_setpoint.yaw_deg
        else:
            yaw = state.heading_deg if state.heading_deg is not None else 0.0
        hold = Setpoint.stop(yaw)
        if state.north_m is not None and state.east_m is not None and state.down_m is not None:
            hold = Setpoint(0.0, 0.0, 0.0, yaw, state.north_m, state.east_m, state.down_m)  # here, position held
        return lambda _state: hold

    def stream_now(self, source: SetpointSource, decided_s: float | None = None) -> Setpoint | None:
        """Stream ``source`` from now on and send its setpoint at once, in the caller's thread: a new
        command does not wait up to a tick. The same route as the stream's ticks (link lost: nothing sent).

        ``decided_s``: see ``send_setpoint`` (default: now, before ``source`` decides). Returns the
        setpoint ``source`` decided (None while no vehicle was heard)."""
        if decided_s is None:
            decided_s = time.time()
        with self._tick_lock:
            with self._lock:
                self._source = source
            return self._stream_tick(decided_s)

    def _stream_tick(self, decided_s: float | None = None) -> Setpoint | None:
        """Ask the source for the setpoint and send it: the one route a streamed setpoint takes to the wire."""
        with self._tick_lock:
            return self._tick(time.time() if decided_s is None else decided_s)  # before the source decides

    def _tick(self, decided_s: float) -> Setpoint | None:
        with self._lock:
            source, state = self._source, self.tracker.snapshot(time.monotonic())
        if source is None or state.system_id is None:
            return None
        if not state.link_ok:  # command nothing, but let the source see the loss (the mapper turns to stop)
            try:
                return source(state)
            except Exception:
                return None
        try:
            setpoint = source(state)
        except Exception as exc:  # a broken source must not leave the last velocity running
            self.on_event(f"setpoint source failed ({exc}); holding")
            setpoint = Setpoint.stop(self.last_setpoint.yaw_deg if self.last_setpoint else 0.0)
        self.send_setpoint(setpoint, decided_s)
        return setpoint

    def send_setpoint(self, setpoint: Setpoint, decided_s: float | None = None) -> bool:
        """Send one SET_POSITION_TARGET_LOCAL_NED now (the stream calls this; a session sends through
        ``stream_now`` instead, so that its setpoints have one route). Nothing is sent while no vehicle is
        heard or the link is lost: returns False then.

        ``decided_s`` (UNIX time read *before* the setpoint was computed) stamps the .tlog record, so the
        log orders a setpoint by when it was decided: one stamped after a source switched to stop was
        computed after the switch (Ctrl-C: every setpoint after the halt time is a stop)."""
        state = self.state
        if state.system_id is None or not state.link_ok:
            return False
        if self._stop_first:
            if not setpoint.is_stop:
                setpoint = Setpoint.stop(setpoint.yaw_deg)
            self._stop_first = False
        boot_ms = int((time.monotonic() - self._boot_s) * 1000)
        separately = state.profile.position_axes_separately if state.profile else False
        fields = setpoint_fields(setpoint, state.system_id, state.component_id or 0, boot_ms, separately)
        self.send(self._conn.mav.set_position_target_local_ned_encode(*fields), decided_s)
        self.last_setpoint = setpoint
        self.setpoints_sent += 1
        return True
