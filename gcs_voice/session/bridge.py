"""The session loop: decided actions in, vehicle commands out, with the safety rules between them.

Three kinds of thread meet here. The voice side (``gcs_voice.session.listen``) and the keyboard call
``Bridge.submit``; the link's own thread streams ``ActionMapper.setpoint`` at 10 Hz; this loop
(``Bridge.run``) takes one submitted action at a time and watches the link. It sleeps until something
wakes it: a request, ``finish()``, a signal, the link (lost, heard, a HEARTBEAT) or the mapper (an
automatic stop, a new limit); nothing it does is periodic, so it never polls. A setpoint has one route:
the mapper decides it and the link sends it (``stream_now`` sends a new command's first one at once,
the stream the rest); the bridge never sends one itself. Rules, in order:

- no action (rejected utterance): nothing is commanded (the voice side already said why);
- between the end of an utterance and its decision the voice side asks for a pause (``PAUSE``): a
  moving vehicle holds where it is, so a stop is a stop from the end of the speech whatever the
  recogniser takes; the decided action replaces the pause, and after speech that was not understood
  ``RESUME`` goes on with the paused motion (``STAY``: stays stopped, when what was heard was nearest a stop);
- link lost (vehicle silent ``link_lost_s``): nothing is commanded until it returns, and the first
  setpoint after it returns is a stop (the link and the mapper both enforce this; we refuse and say so);
- motion (even stop) while disarmed, outside the velocity mode, or during take-off/landing: refused with
  the reason (a setpoint would cut an ArduCopter take-off short near the ground);
- the other station is in charge when it says so: a HEARTBEAT that shows the armed vehicle out of the
  velocity mode we flew in (QGroundControl's BRAKE / LOITER / Hold, or a failsafe's RTL / LAND) ends the
  voice motion (the stream stops; the bridge never asks for GUIDED / OFFBOARD back) and is said once as a
  ``takeover`` event; voice flies again only once someone puts the velocity mode back;
- disarm while flying: refused (a misheard word must not drop the vehicle); land while disarmed (after
  a crash): refused, so that it cannot look done;
- take-off / land / arm / disarm run in a worker thread so the loop keeps watching the link;
- floor, ceiling and fence are applied by the mapper on every setpoint; we show its reasons;
- whatever ends the session (end of script, Ctrl-C / SIGTERM / SIGHUP, a crash of the voice side, a
  refused ``--takeoff``) ends in ``shutdown``, which commands a stop and keeps it on the wire before the
  link closes; a signal halts the mapper in its handler, so the stream turns to stop at once.
- a session that ends after an accepted "land" waits (``readiness.toml`` [landing] timeout_s) until the
  vehicle reports itself landed (EXTENDED_SYS_STATE) and disarmed (HEARTBEAT), and says which it saw.
"""

from __future__ import annotations

import queue
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.actions.setpoint import round_deg
from gcs_voice.understanding.decision import Decision
from gcs_voice.domain.dictionary import FLIGHT_ACTIONS, HOME_ACTIONS, MOTION_ACTIONS
from gcs_voice.link.acks import OperationResult
from gcs_voice.link.readiness import assess
from gcs_voice.link.state import VehicleState
from gcs_voice.link.vehicle_link import VehicleLink
from gcs_voice.session.events import EventBus

__all__ = ["Bridge", "Request", "status_of", "PAUSE", "RESUME", "STAY"]

#: how long the final stop is kept on the wire before the link closes (several 10 Hz setpoints)
FINAL_STOP_S = 0.6
#: below this height above home a vehicle without EXTENDED_SYS_STATE counts as on the ground
ON_GROUND_HEIGHT_M = 0.2
#: signals that end a session with the vehicle stopped first: Ctrl-C, ``kill`` / a service manager, a
#: closed terminal. The exit status is 128 + the signal's number (130, 143, 129), as a shell reports it.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
#: the voice side's requests around a decision (not actions): hold a moving vehicle while an utterance is
#: decided; go on with the paused motion after speech that was not understood; or end the pause stopped
PAUSE, RESUME, STAY = "pause", "resume", "stay"
_SIGNAL_WORDS = {"SIGINT": "interrupted (Ctrl-C)", "SIGTERM": "terminated (SIGTERM)", "SIGHUP": "hung up (SIGHUP)"}


@dataclass
class Request:
    """One action to carry out: from the voice (with its decision), a key, or the script (--takeoff)."""

    action: str
    origin: str  # voice | key | script
    decision: Decision | None = None
    utterance_end_t: float | None = None  # UNIX time the utterance ended (latency origin)
    decided_t: float | None = None
    done: threading.Event = field(default_factory=threading.Event)
    accepted: bool = False
    #: why, for a STAY: what said stop ("Whisper heard 'stop'", "the domain ear gave stop 14 %"), logged with it
    why: str = ""


def status_of(state: VehicleState | None, action: str | None) -> dict[str, Any]:
    """The view's vehicle panel from a link VehicleState (None-safe)."""
    if state is None:
        return {"link": "waiting"}
    speed = None
    if state.north_m_s is not None and state.east_m_s is not None:
        speed = (state.north_m_s ** 2 + state.east_m_s ** 2 + (state.down_m_s or 0.0) ** 2) ** 0.5
    link = "waiting" if state.last_heard_s is None else ("ok" if state.link_ok else "lost")
    ready = None
    if state.heartbeats and not state.armed:
        ready = str(assess(state))
    heading = round_deg(state.heading_deg, 0) if state.heading_deg is not None else None  # 359.7 is north: 0
    return {"link": link, "autopilot": state.autopilot, "mode": state.mode, "armed": state.armed,
            "alt_m": state.height_m, "heading_deg": heading, "speed_m_s": speed, "action": action,
            "ready": ready, "battery_pct": state.battery_pct}


def _on_ground(state: VehicleState) -> bool:
    """Landed by the autopilot's own word (EXTENDED_SYS_STATE), else by height above home."""
    if state.landed_state is not None:
        return state.landed_state == "ON_GROUND"
    height = state.height_m
    return height is not None and height < ON_GROUND_HEIGHT_M


class Bridge:
    """Owns the mapper's current action and the vehicle operations; ``run()`` until ``finish()``."""

    def __init__(self, link: VehicleLink, mapper: ActionMapper, bus: EventBus, takeoff_m: float) -> None:
        self.link = link
        self.mapper = mapper
        self.bus = bus
        self.takeoff_m = takeoff_m
        #: requests, and None for "something changed: look again". A SimpleQueue, because the signal handler
        #: puts into it too (its put is reentrant; a Queue's or an Event's lock could be held by the code the
        #: handler interrupted)
        self._inbox: queue.SimpleQueue[Request | None] = queue.SimpleQueue()
        self._finish = threading.Event()
        #: notified when a flight operation ends and at finish(): a script waits on it (no signal handler takes it)
        self._changed = threading.Condition()
        self._interrupted = False  # set by the signal handler (a plain flag: no lock taken in a handler)
        self._signum = int(signal.SIGINT)
        self.halted_t: float | None = None  # UNIX time the SIGINT handler stopped the setpoint source
        self._busy: str | None = None  # flight operation in progress
        self._op_thread: threading.Thread | None = None
        self._link_ok: bool | None = None
        self._heartbeats_at_loss = 0
        self._limit_reason = ""
        self.exit_code = 0
        self.flying_ready = threading.Event()  # set when a take-off finished (scripts wait on it)
        self._landing = False  # an accepted "land" not yet followed by a take-off: the end waits for touchdown
        self._mode_seen: str | None = None  # the mode at the last look (a take-over is a change from the velocity mode)

    # ---- inputs (any thread) ----------------------------------------------------------------------
    def submit(self, request: Request) -> Request:
        self._inbox.put(request)
        return request

    def finish(self, exit_code: int = 0) -> None:
        self.exit_code = self.exit_code or exit_code
        self._finish.set()
        with self._changed:
            self._changed.notify_all()
        self._wake()

    def _wake(self) -> None:
        """Something the loop watches changed: make it look again (safe in a signal handler)."""
        self._inbox.put(None)

    @property
    def busy(self) -> str | None:
        """The flight operation in progress (take_off, land, ...), or None."""
        return self._busy

    @property
    def finished(self) -> bool:
        return self._finish.is_set()

    def wait_finished(self, timeout_s: float) -> bool:
        """Sleep up to ``timeout_s`` unless the session ends first (then True): a script's pause ends with it."""
        return self._finish.wait(timeout_s)

    def wait_idle(self, timeout_s: float) -> bool:
        """Wait until no flight operation runs or the session ended; False if one still runs after ``timeout_s``.

        A script holds here after a take-off or a landing, so that its next pause counts from the vehicle up."""
        with self._changed:
            return self._changed.wait_for(lambda: not self._busy or self._finish.is_set(), timeout_s)

    def status(self) -> dict[str, Any]:
        paused = self.mapper.paused
        return status_of(self.link.state, self._busy or (f"{paused} (paused)" if paused else self.mapper.action))

    # ---- the loop ---------------------------------------------------------------------------------
    def run(self) -> int:
        """Serve requests and watch the link until ``finish()``; always ends with ``shutdown()``.

        Ctrl-C (and SIGTERM, SIGHUP) halts the mapper (the setpoint source: the next setpoint the 10 Hz
        stream sends is a stop), sets a flag that the loop reads and wakes the loop; nothing else happens
        in the handler: a KeyboardInterrupt raised at an arbitrary bytecode could leave a lock (the link's,
        a queue's) held and hang the final stop.
        """
        previous: dict[int, Any] = {}
        if threading.current_thread() is threading.main_thread():
            for signum in STOP_SIGNALS:
                previous[signum] = signal.signal(signum, self._on_sigint)
        watchers = self.link.on_change, self.mapper.on_change
        self.link.on_change = self.mapper.on_change = self._wake
        self._wake()  # look once at what was so before the loop began (a link already up)
        try:
            while not self._finish.is_set() and not self._interrupted:
                request = self._inbox.get()  # no timeout: whatever the loop watches wakes it (see _wake)
                self._watch()
                if request is not None:
                    try:
                        self._serve(request)
                    finally:
                        request.done.set()
        except KeyboardInterrupt:  # only when no handler could be installed (not the main thread)
            self._interrupted = True
        finally:
            self.link.on_change, self.mapper.on_change = watchers
            if self._interrupted:
                self.mapper.halt()  # already done by the handler, unless it came as KeyboardInterrupt
                name = signal.Signals(self._signum).name
                self.bus.emit("session", f"{_SIGNAL_WORDS.get(name, name)}: stopping the vehicle", phase="interrupt",
                              signal=name, halted_t=self.halted_t)
                self.exit_code = self.exit_code or 128 + self._signum
            try:
                self.shutdown()
            finally:
                for signum, handler in previous.items():
                    signal.signal(signum, handler)
        return self.exit_code

    def _on_sigint(self, signum: int, _frame: Any) -> None:
        self.mapper.halt()  # first: every setpoint decided from here on is a stop
        if self.halted_t is None:
            self.halted_t = time.time()
            self._signum = signum
        self._interrupted = True
        self._wake()

    def _watch(self) -> None:
        """Link transitions and the mapper's automatic changes, said once each."""
        state = self.link.state
        if state.last_heard_s is not None and state.link_ok != self._link_ok:
            if state.link_ok and self._link_ok is False and state.heartbeats <= self._heartbeats_at_loss:
                pass  # heard again, but no HEARTBEAT yet: the mode we hold is from before the loss (a failsafe
                #       may have changed it), so "restored" waits for the HEARTBEAT that says the mode now
            elif state.link_ok:
                what = "connected" if self._link_ok is None else "restored"
                self.bus.emit("link", f"link {what}: {state.autopilot or 'unknown autopilot'}, mode {state.mode}",
                              state=what, autopilot=state.autopilot, system_id=state.system_id, mode=state.mode)
                self._link_ok = True
            else:
                self.bus.emit("link", f"link LOST: vehicle silent for {self.link.settings.link_lost_s:g} s; "
                              "nothing is commanded until it returns, then a stop", state="lost")
                self._link_ok = False
                self._heartbeats_at_loss = state.heartbeats
        self._watch_mode(state)
        while self.mapper.events:  # the mapper's automatic changes (floor reached, link lost), said once
            self.bus.emit("warning", self.mapper.events.popleft(), source="mapper")
        reason = self.mapper.limit_reason
        if reason != self._limit_reason:
            if reason:
                self.bus.emit("refused", f"{self.mapper.action} limited: {reason}", action=self.mapper.action,
                              reason=reason)
            self._limit_reason = reason

    #: an ACK of a mode change for another station this recent explains the next mode change (tracker clock)
    TAKEOVER_ACK_S = 3.0
    #: how long the take-over event waits for that ACK when it comes after the HEARTBEAT
    TAKEOVER_ACK_GRACE_S = 0.3

    def _watch_mode(self, state: VehicleState) -> None:
        """Another station (or the vehicle itself) took the vehicle out of the velocity mode: stop flying it.

        Only a change seen while idle counts: our own take-off and landing change the mode too. The stream
        stops, so that a later switch back to GUIDED by the other station does not resume a stale voice
        motion (in GUIDED without setpoints ArduCopter holds where it is)."""
        previous, self._mode_seen = self._mode_seen, state.mode
        velocity_mode = state.profile.velocity_mode if state.profile else None
        if (previous is None or state.mode is None or previous == state.mode or previous != velocity_mode
                or not state.armed or self._busy or self._landing or not state.link_ok):
            return
        self.mapper.apply("stop", state)
        self.link.stop_stream()
        changed_s = state.heartbeat_s or 0.0

        def acked(s: VehicleState) -> bool:
            return s.other_station_mode_s is not None and s.other_station_mode_s >= changed_s - self.TAKEOVER_ACK_S

        # the other station's ACK may come just after the HEARTBEAT that shows its mode (gcs-sim sends the
        # HEARTBEAT first; ArduCopter sends both within 10 ms): wait a moment for it, the stream already stopped
        seen = self.link.wait_for(acked, self.TAKEOVER_ACK_GRACE_S)
        by_station = seen is not None
        station = seen.other_station if seen is not None else None
        if by_station:
            msg = f"another station took over: {state.mode}"
        else:  # PX4's second link carries no other station's ACKs; a failsafe or an RC switch sends none
            msg = f"vehicle left {velocity_mode}: {state.mode} (another station, the RC switch or a failsafe)"
        self.bus.emit("takeover", msg + f"; voice motions wait until it is back in {velocity_mode}",
                      mode=state.mode, previous=previous, by="station" if by_station else "unknown",
                      station=list(station) if station else None)

    # ---- carrying out one request -------------------------------------------------------------------
    def _refuse(self, request: Request, reason: str) -> None:
        self.bus.emit("refused", f"{request.action} not done: {reason}", action=request.action, reason=reason,
                      origin=request.origin, utterance_end_t=request.utterance_end_t)

    def _serve(self, request: Request) -> None:
        action = request.action
        state = self.link.state
        if action in (PAUSE, RESUME, STAY):
            return self._serve_pause(request, state)
        if not state.link_ok:
            return self._refuse(request, "link lost - nothing is commanded until the vehicle is heard again")
        autopilot_return = action in HOME_ACTIONS and bool(self.link.settings.return_home_lands)
        if action in FLIGHT_ACTIONS or autopilot_return:
            if self._busy:
                return self._refuse(request, f"busy: {self._busy} in progress")
            if action == "disarm" and not _on_ground(state):
                # A misheard "disarm" in the air would drop the vehicle: only on the ground.
                return self._refuse(request, "the vehicle is flying: say 'land' first")
            if action in ("land", "return_home") and state.armed is False:
                # After a crash the autopilot disarms: a "land" then does nothing and must not look done.
                return self._refuse(request, f"the vehicle is disarmed: nothing to {action.replace('_', ' ')}")
            # motions end: the mapper holds while the operation runs
            self.mapper.apply("stop" if autopilot_return else action, state)
            self._start_operation(request)
            return None
        if action not in MOTION_ACTIONS and action not in HOME_ACTIONS:
            return self._refuse(request, "unknown action")
        if self._busy:
            # Even a stop: a velocity setpoint ends an ArduCopter take-off where it is (a hover near the
            # ground), and a landing is the autopilot's to finish. Both end in a hold by themselves.
            return self._refuse(request, f"busy: {self._busy} in progress; the vehicle holds when it is done")
        if not state.armed:
            return self._refuse(request, "vehicle is not armed: say 'take off' first" if action != "stop"
                                else "vehicle is not armed: nothing to stop")
        velocity_mode = state.profile.velocity_mode if state.profile else None
        if velocity_mode and state.mode != velocity_mode and not self._busy:
            # Someone else (another station, the autopilot's failsafe, an RC switch, a landing) has the
            # vehicle: do not grab it. On the ground "take off" starts again; in the air whoever took it
            # gives it back by switching to the velocity mode.
            how = ("say 'take off' to fly by voice again" if _on_ground(state)
                   else f"voice flies again once it is switched back to {velocity_mode}")
            return self._refuse(request, f"vehicle is in {state.mode}, not {velocity_mode}: {how}")
        decided_s = time.time()  # before the mapper decides (see LinkChannel.send_setpoint)
        amount = request.decision.amount if request.decision else None
        mapped = self.mapper.apply(action, state, amount)
        if mapped.refused:  # the amount would cross a limit (fence, ceiling, floor): nothing changed
            return self._refuse(request, mapped.refused)
        # the link streams the mapper's setpoint; this one goes at once, not at the next 10 Hz tick
        setpoint = self.link.stream_now(self.mapper.setpoint, decided_s)
        sent_t = time.time()
        request.accepted = True
        d = request.decision
        self.bus.emit(
            "command", f"{(repr(d.phrase) + ' -> ') if d and d.phrase else ''}{action}"
            + (f" {mapped.amount}" if mapped.amount else "")
            + (f" (score {d.score:.2f})" if d else f" ({request.origin})"),
            action=action, phrase=d.phrase if d else None, score=round(d.score, 3) if d else None,
            amount=mapped.amount or None, origin=request.origin, yaw_target_deg=round_deg(mapped.yaw_target_deg, 1),
            said_amount=d.amount.to_dict() if d and d.amount and mapped.amount else None,
            setpoint=None if setpoint is None else {
                "forward_m_s": setpoint.forward_m_s, "right_m_s": setpoint.right_m_s,
                "down_m_s": setpoint.down_m_s, "yaw_deg": round_deg(setpoint.yaw_deg, 2)},
            utterance_end_t=request.utterance_end_t, decided_t=request.decided_t, sent_t=sent_t,
        )
        return None

    def _serve_pause(self, request: Request, state: VehicleState) -> None:
        """PAUSE / RESUME / STAY (see the module's rules); silent when there is nothing to pause or resume."""
        velocity_mode = state.profile.velocity_mode if state.profile else None
        not_flying = ("link lost" if not state.link_ok else f"busy: {self._busy}" if self._busy
                      else "vehicle is not armed" if not state.armed
                      else f"vehicle is in {state.mode}, not {velocity_mode}"
                      if velocity_mode and state.mode != velocity_mode else "")
        if request.action == PAUSE:
            changed = None if not_flying else self.mapper.pause(state)
            said, what = "paused while the utterance is decided", "paused"
        elif self.mapper.paused is None:
            return None
        elif request.action == STAY or not_flying:
            paused = self.mapper.forget_pause()
            reason = not_flying or f"{request.why or 'what was heard was nearest a stop'}; staying stopped"
            self.bus.emit("paused", f"{paused} not resumed: {reason}", state="stayed", action=paused, reason=reason,
                          utterance_end_t=request.utterance_end_t, sent_t=time.time())
            return None
        else:
            changed = self.mapper.resume(state)
            said, what = "resumed: nothing was understood", "resumed"
        if changed is None:
            return None
        decided_s = self.mapper.paused_t  # read under the mapper's lock: every later setpoint follows the change
        self.link.stream_now(self.mapper.setpoint, decided_s)
        self.bus.emit("paused", f"{changed} {said}", state=what, action=changed,
                      utterance_end_t=request.utterance_end_t, decided_t=decided_s, sent_t=time.time())
        return None

    def _start_operation(self, request: Request) -> None:
        self._busy = request.action
        self._op_thread = threading.Thread(target=self._operate, args=(request,), name=f"op-{request.action}",
                                           daemon=True)
        self._op_thread.start()

    def _operate(self, request: Request) -> None:
        action = request.action
        d = request.decision
        self.bus.emit("command", f"{(repr(d.phrase) + ' -> ') if d and d.phrase else ''}{action}"
                      + (f" (score {d.score:.2f})" if d else f" ({request.origin})"),
                      action=action, phrase=d.phrase if d else None, score=round(d.score, 3) if d else None,
                      origin=request.origin, utterance_end_t=request.utterance_end_t, decided_t=request.decided_t,
                      sent_t=time.time())
        try:
            result = self._operation(action)
            ok = result.ok
            self.bus.emit("flight", f"{action}: {result}", what=action, ok=ok, detail=str(result),
                          utterance_end_t=request.utterance_end_t)
            request.accepted = ok
            if ok and action == "take_off":
                self.flying_ready.set()
                self._landing = False
            elif action == "take_off" and request.origin == "script":
                # --takeoff (or the demo's scripted take-off) failed: nothing the script says can fly now,
                # so end at once instead of waiting out the script's ready timeout.
                self.bus.emit("error", f"take_off failed ({result}): ending the session", what=action)
                self.finish(1)
            if ok and action in ("land", "return_home"):
                self._landing = True  # the autopilot lands by itself: the end of the session waits for it
        except Exception as exc:  # a failed operation is reported, never fatal to the loop
            self.bus.emit("error", f"{action} failed: {exc}", what=action)
        finally:
            with self._changed:
                self._busy = None
                self._changed.notify_all()

    def _operation(self, action: str) -> OperationResult:
        """Run one flight operation on the link (blocking); returns its OperationResult."""
        link = self.link
        if action == "take_off":
            # The link sets the arming mode, arms (retrying while the vehicle says it cannot yet), climbs,
            # then streams the mapper's setpoints (a hold at the heading kept through the climb).
            self.mapper.reset_heading(link.state)
            return link.takeoff(self.takeoff_m, source=self.mapper.setpoint)
        if action == "land":
            return link.land()  # stops the stream first: both autopilots land on their own
        if action == "return_home":
            return link.return_to_launch()  # return_home_lands = 1: the autopilot's RTL flies home and lands
        if action == "arm":
            return link.arm()
        if action == "disarm":
            return link.disarm()
        raise ValueError(f"not a flight operation: {action}")

    # ---- the end ------------------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Stop the vehicle (hold where it is) and keep that on the wire; after "land", wait for touchdown."""
        if self._busy in ("land", "return_home") and self._op_thread is not None:
            self._op_thread.join(timeout=self.link.settings.mode_confirm_s + 5.0)
        if self._landing and not self._interrupted:
            self._wait_landed()
            return
        try:
            state = self.link.state
            in_velocity_mode = state.profile is None or state.mode == state.profile.velocity_mode
            if state.armed and state.link_ok and in_velocity_mode and self._busy not in ("land", "return_home"):
                if self.mapper.action != "stop":
                    self.mapper.apply("stop", state)
                self.link.stream_now(self.mapper.setpoint)
                self.bus.emit("command", "stop (end of session)", action="stop", origin="shutdown",
                              sent_t=time.time())
                time.sleep(FINAL_STOP_S)
        except Exception as exc:  # the link itself may be what failed
            self.bus.emit("error", f"could not command the final stop: {exc}")

    def _wait_landed(self) -> None:
        """Wait for EXTENDED_SYS_STATE ON_GROUND and a disarmed HEARTBEAT, within the time limit; say which."""
        limit_s = self.link.readiness_rules.landed_timeout_s
        start = time.monotonic()
        self.bus.emit("flight", f"waiting up to {limit_s:g} s for the vehicle to land and disarm", what="landed",
                      ok=None, detail="waiting")
        try:
            done = self.link.wait_for(lambda s: (s.armed is False and _on_ground(s)) or not s.link_ok
                                      or self._interrupted, limit_s)
        except Exception as exc:  # the link itself may be what failed
            self.bus.emit("error", f"could not watch the landing: {exc}")
            return
        state = self.link.state
        took = time.monotonic() - start
        if done is not None and done.armed is False and _on_ground(done):
            self.bus.emit("flight", f"landed and disarmed ({took:.1f} s after the session ended)", what="landed",
                          ok=True, detail=f"landed_state {done.landed_state}, disarmed")
            return
        why = ("link lost" if not state.link_ok else "interrupted" if self._interrupted
               else f"not seen within {limit_s:g} s")
        self.bus.emit("warning", f"landing not confirmed ({why}): mode {state.mode}, "
                      f"{'armed' if state.armed else 'disarmed'}, landed state {state.landed_state or '?'}, "
                      f"height {state.height_m if state.height_m is None else round(state.height_m, 2)} m",
                      source="bridge")
