"""The nine action classes as velocity + heading setpoints, with the safety rules applied every tick.

``go_*`` move in the body frame of the heading *target* and keep it; ``up``/``down`` change height;
``turn_*`` move the heading target by exactly ``turn_step_deg`` from the current target (two
"turn right" make 180); ``stop`` holds (zero velocity, same heading target). An action lasts until the
next one. ``down`` turns itself into ``stop`` at ``floor_m`` above home, or above whatever a fresh
downward rangefinder sees (a table), whichever is nearer; climbs stop at ``ceiling_m``;
horizontal motion stops at ``fence_radius_m`` from home (only the outward motion). Unknown height or
position counts as "at the limit": the mapper does not command what it cannot check. A lost link
turns the action into ``stop``, so the first setpoint after the link returns is a hold. ``halt()``
(Ctrl-C) makes every later setpoint a stop at once, whatever thread asks next. NaN never leaves the mapper.

Holds (positions carried with the setpoint, see ``actions.setpoint``): ``stop`` holds the point and
height where it was heard; a turn holds the point it started from; ``go_*`` hold their height;
``up``/``down`` hold their horizontal point. A hold carries over while the next action keeps that axis
still (stop then turn keeps the stop's point), so repeated commands do not creep.

Bounded motions (an amount was said, ``gcs_voice.domain.amounts``): "go forward 3 m" sets a target 3 m
ahead of where the vehicle is held, "up 2 m" / "climb to 5 m" a height, "turn left 45" the heading target
45 degrees on. The motion flies at the usual speed, slowing within ``1 / BOUND_GAIN_HZ`` seconds of its target,
and ends by itself there: a stop whose hold is the target itself (not where the vehicle happened to be), so
the autopilot's position controller puts it on the target. Stop and any other command end it at once, as they
end any motion. An amount whose target would cross the fence, the ceiling or the floor is refused with the
reason (``MappedAction.refused``) and nothing changes: never clipped to the limit.

``pause()`` holds a moving vehicle while an utterance is being decided, and ``resume()`` goes on with the
same motion when the utterance was not understood: a stop said to a moving vehicle is a stop from the end of
the speech, however long the recogniser takes, and speech that is not a command changes nothing. Any
other action ends the pause (the decided one replaces it); so do the automatic stops.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from gcs_voice.actions.setpoint import Setpoint, body_to_ned, ned_to_body, wrap_deg
from gcs_voice.domain.dictionary import ACTIONS, FLIGHT_ACTIONS
from gcs_voice.settings import Settings, load_settings
from gcs_voice.domain.amounts import Amount

__all__ = ["ActionMapper", "MappedAction", "UnknownActionError"]


class VehicleState(Protocol):
    """What the mapper reads of the vehicle (``gcs_voice.link.VehicleState`` is one): NED metres from the
    EKF origin, heading clockwise from north, and whether the link is alive. None = not yet known."""

    north_m: float | None
    east_m: float | None
    down_m: float | None
    home_north_m: float | None
    home_east_m: float | None
    heading_deg: float | None
    ground_clearance_m: float | None
    last_heard_s: float | None
    link_ok: bool

    @property
    def height_m(self) -> float | None: ...


class UnknownActionError(ValueError):
    """An action id that is not one of gcs_voice.domain.dictionary.ACTIONS (a programming error, not user input)."""


@dataclass(frozen=True)
class MappedAction:
    """What one decided action means: a motion (handled by the streamer) or a flight operation for the link."""

    action: str
    flight_operation: str | None  # "take_off" | "land" | "arm" | "disarm" | None for motions
    yaw_target_deg: float
    #: why the amount was not taken (fence, ceiling, floor, unknown position): then nothing changed
    refused: str = ""
    #: the amount taken ("3 m", "45°", "to 5 m"), "" for an open-ended motion
    amount: str = ""


@dataclass(frozen=True)
class Bound:
    """Where a bounded motion ends: a horizontal point (go_*) or a local down (up/down), NED metres, and the
    unit vector (north, east) or sign (down) along which the remaining distance is measured."""

    label: str
    point: tuple[float, float] | None = None
    direction: tuple[float, float] = (0.0, 0.0)
    down_m: float | None = None


def _finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)


HORIZONTAL_MOTIONS = frozenset({"go_forward", "go_back", "go_right", "go_left"})
VERTICAL_MOTIONS = frozenset({"up", "down"})
#: a bounded motion slows within 1/BOUND_GAIN_HZ seconds of its target, and ends within ARRIVED_M of it
BOUND_GAIN_HZ = 1.0
ARRIVED_M = 0.05
#: "return home" (settings return_home_lands = 0): a horizontal motion to home, bounded there, at the present height
HOMEWARD = "return_home"
#: what moves the vehicle over the ground (no horizontal hold while it runs)
MOVING_OVER_GROUND = HORIZONTAL_MOTIONS | {HOMEWARD}
#: what ``pause`` holds: the motions that move the vehicle through space (a turn only rotates it in place)
TRANSLATING_MOTIONS = MOVING_OVER_GROUND | VERTICAL_MOTIONS


def _point(state: VehicleState) -> tuple[float, float] | None:
    """The vehicle's horizontal position, or None when unknown."""
    if _finite(state.north_m) and _finite(state.east_m):
        return float(state.north_m), float(state.east_m)
    return None


class ActionMapper:
    """Holds the current action and heading target; ``setpoint(state)`` is called at the stream rate."""

    def __init__(self, settings: Settings | None = None) -> None:
        self.settings = settings or load_settings()
        self.action: str = "stop"
        self.yaw_target_deg: float | None = None
        #: why the last setpoint differs from the plain action ("" when it does not)
        self.limit_reason: str = ""
        #: automatic action changes (floor reached, link lost), newest last, for the UI
        self.events: deque[str] = deque(maxlen=32)
        #: apply() runs in the caller's thread, setpoint() in the link's stream thread
        self._lock = threading.RLock()
        #: the held horizontal point (north, east) and height (down), local NED metres; None = not held
        self.hold_point: tuple[float, float] | None = None
        self.hold_down_m: float | None = None
        #: set by halt(): a plain flag, because a signal handler sets it (no lock may be taken there)
        self._halted = False
        #: the motion ``pause()`` holds until ``resume()`` (None: nothing paused)
        self.paused: str | None = None
        #: the target of the current bounded motion (None: open-ended, or no motion), and of the paused one
        self.bound: Bound | None = None
        self.paused_bound: Bound | None = None
        #: UNIX time of the last pause or resume, read under the lock: every setpoint decided from then on
        #: (a setpoint's time is read before it is computed) follows it
        self.paused_t = 0.0
        #: called when ``events`` gets an entry or ``limit_reason`` changes, in the thread that asked for the
        #: setpoint (the link's stream): the session loop waits for this instead of polling. It must not block.
        self.on_change: Callable[[], object] | None = None

    def halt(self) -> None:
        """From now on every setpoint is a stop and no motion is taken (Ctrl-C: safe in a signal handler).

        The streamer asks ``setpoint()`` at 10 Hz in its own thread, so the very next setpoint is a stop,
        not the one after the session loop has noticed."""
        self._halted = True

    @property
    def halted(self) -> bool:
        return self._halted

    def pause(self, state: VehicleState) -> str | None:
        """Hold where the vehicle is while an utterance is decided; the motion paused, or None (none moving).

        A bounded motion is paused too, and resumes toward the same target."""
        with self._lock:
            if self._halted or self.action not in TRANSLATING_MOTIONS:
                return None
            self._update_holds(self.action, "stop", state)
            self.paused, self.action = self.action, "stop"
            self.paused_bound, self.bound = self.bound, None
            self.paused_t = time.time()
            return self.paused

    def resume(self, state: VehicleState) -> str | None:
        """Go on with the paused motion (the utterance was not a command); None when nothing is paused now."""
        with self._lock:
            action, self.paused = self.paused, None
            bound, self.paused_bound = self.paused_bound, None
            if action is None or self._halted:
                return None
            self._apply(action, state)
            self.bound = bound   # a bounded motion goes on to the same target
            self.paused_t = time.time()
            return action

    def forget_pause(self) -> str | None:
        """End a pause without resuming: the vehicle stays stopped; the motion that was paused, or None."""
        with self._lock:
            action, self.paused = self.paused, None
            self.paused_bound = None
            return action

    def _init_yaw(self, state: VehicleState) -> float:
        if self.yaw_target_deg is None or not _finite(self.yaw_target_deg):
            self.yaw_target_deg = wrap_deg(state.heading_deg) if _finite(state.heading_deg) else 0.0
        return self.yaw_target_deg

    def reset_heading(self, state: VehicleState) -> None:
        """Forget the heading target; the next setpoint takes the vehicle's current heading (after take-off)."""
        with self._lock:
            self.yaw_target_deg = None
            self._init_yaw(state)
            self.hold_point = self.hold_down_m = None   # taken where the vehicle is at the next setpoint

    def apply(self, action: str, state: VehicleState, amount: Amount | None = None) -> MappedAction:
        """Make ``action`` the current one (motions) or hand back the flight operation to run.

        With an ``amount`` (a definite one: ``amounts.amount_reason``) the motion is bounded; an amount whose
        target crosses a limit is refused (``MappedAction.refused``) and the current action stays."""
        with self._lock:
            if action == HOMEWARD and not self._halted:
                return self._apply_home(state)
            if amount is not None and action not in FLIGHT_ACTIONS and not self._halted:
                return self._apply_bounded(action, state, amount)
            return self._apply(action, state)

    def _apply_home(self, state: VehicleState) -> MappedAction:
        """Fly straight back to home at the present height; at home, hold there (a bounded motion: a stop or any
        command ends it, and it ends by itself)."""
        yaw = self._init_yaw(state)
        start = _point(state)
        if start is None:
            return MappedAction(HOMEWARD, None, yaw, refused="position unknown: home cannot be found")
        home = (state.home_north_m if _finite(state.home_north_m) else 0.0,
                state.home_east_m if _finite(state.home_east_m) else 0.0)
        north, east = home[0] - start[0], home[1] - start[1]
        away = math.hypot(north, east)
        if away <= ARRIVED_M:
            mapped = self._apply("stop", state)
            self.hold_point = home
            return MappedAction(mapped.action, None, yaw, amount="home")
        mapped = self._apply(HOMEWARD, state)
        self.bound = Bound("home", point=home, direction=(north / away, east / away))
        return MappedAction(mapped.action, None, yaw, amount=f"{away:.1f} m")

    def _apply_bounded(self, action: str, state: VehicleState, amount: Amount) -> MappedAction:
        yaw = self._init_yaw(state)
        label = amount.label
        if action in ("turn_left", "turn_right"):
            mapped = self._apply(action, state, turn_deg=float(amount.value))
            return MappedAction(mapped.action, None, mapped.yaw_target_deg, amount=label)
        s = self.settings
        if action in HORIZONTAL_MOTIONS:
            start = self.hold_point if self.action not in MOVING_OVER_GROUND and self.hold_point else _point(state)
            if start is None:
                return MappedAction(action, None, yaw, refused="position unknown: no distance can be measured")
            forward, right = {"go_forward": (1.0, 0.0), "go_back": (-1.0, 0.0),
                              "go_right": (0.0, 1.0), "go_left": (0.0, -1.0)}[action]
            north, east = body_to_ned(forward, right, yaw)
            target = (start[0] + north * amount.value, start[1] + east * amount.value)
            home = (state.home_north_m if _finite(state.home_north_m) else 0.0,
                    state.home_east_m if _finite(state.home_east_m) else 0.0)
            away = math.hypot(target[0] - home[0], target[1] - home[1])
            if away > s.fence_radius_m:
                return MappedAction(action, None, yaw, refused=(
                    f"{label} would end {away:.1f} m from home, beyond the fence ({s.fence_radius_m:g} m)"))
            bound = Bound(label, point=target, direction=(north, east))
        elif action in VERTICAL_MOTIONS:
            height = state.height_m if _finite(state.height_m) else None
            if height is None or not _finite(state.down_m):
                return MappedAction(action, None, yaw, refused="height unknown: no height can be measured")
            start_down = (self.hold_down_m if self.action not in VERTICAL_MOTIONS and self.hold_down_m is not None
                          else float(state.down_m))
            start_height = height - (start_down - float(state.down_m))
            if amount.height:
                goal = float(amount.value)
                if (action == "up") != (goal > start_height):
                    return MappedAction(action, None, yaw, refused=(
                        f"'{action} {label}': the vehicle is at {start_height:.1f} m, so that is "
                        f"{'down' if action == 'up' else 'up'}; say it again"))
            else:
                goal = start_height + (amount.value if action == "up" else -amount.value)
            if goal > s.ceiling_m:
                return MappedAction(action, None, yaw, refused=(
                    f"{label} would end at {goal:.1f} m, above the ceiling ({s.ceiling_m:g} m)"))
            if goal < s.floor_m:
                return MappedAction(action, None, yaw, refused=(
                    f"{label} would end at {goal:.1f} m, below the floor ({s.floor_m:g} m)"))
            bound = Bound(label, down_m=start_down - (goal - start_height),
                          direction=(0.0, -1.0 if action == "up" else 1.0))
        else:
            return MappedAction(action, None, yaw, refused=f"'{action}' takes no amount")
        mapped = self._apply(action, state)
        self.bound = bound
        return MappedAction(mapped.action, None, mapped.yaw_target_deg, amount=label)

    def _apply(self, action: str, state: VehicleState, turn_deg: float | None = None) -> MappedAction:
        if action not in ACTIONS:
            raise UnknownActionError(f"unknown action {action!r}; expected one of {', '.join(ACTIONS)}")
        self.paused = None  # a decided action replaces the pause
        self.bound = self.paused_bound = None   # any command ends a bounded motion
        yaw = self._init_yaw(state)
        if action in FLIGHT_ACTIONS:
            self.action = "stop"
            self.hold_point = self.hold_down_m = None   # the operation moves the vehicle: take it afresh
            return MappedAction(action, action, yaw)
        if self._halted:  # after Ctrl-C nothing moves the vehicle again
            self.action = "stop"
            return MappedAction("stop", None, yaw)
        step = self.settings.turn_step_deg if turn_deg is None else turn_deg
        if action == "turn_right":
            yaw = self.yaw_target_deg = wrap_deg(yaw + step)
        elif action == "turn_left":
            yaw = self.yaw_target_deg = wrap_deg(yaw - step)
        self._update_holds(self.action, action, state)
        self.action = action
        return MappedAction(action, None, yaw)

    def _update_holds(self, previous: str, action: str, state: VehicleState) -> None:
        """Keep a hold while the axis stays still; take the vehicle's position where an axis stops moving."""
        if action in MOVING_OVER_GROUND:
            self.hold_point = None
        elif previous in MOVING_OVER_GROUND or self.hold_point is None:
            self.hold_point = _point(state)
        if action in VERTICAL_MOTIONS:
            self.hold_down_m = None
        elif previous in VERTICAL_MOTIONS or self.hold_down_m is None:
            self.hold_down_m = state.down_m if _finite(state.down_m) else None

    def _switch_to_stop(self, reason: str, state: VehicleState | None = None) -> None:
        self.paused = None  # an automatic stop (link lost, floor, Ctrl-C) is not undone by a resume
        self.bound = self.paused_bound = None
        if self.action == "stop":
            return
        self.events.append(f"{self.action} -> stop: {reason}")
        if state is not None:
            self._update_holds(self.action, "stop", state)
        self.action = "stop"
        self._tell_watcher()

    def _tell_watcher(self) -> None:
        if self.on_change is not None:
            self.on_change()

    def setpoint(self, state: VehicleState) -> Setpoint:
        """The setpoint for now: the action's velocity, limited by floor, ceiling and fence."""
        with self._lock:
            return self._setpoint(state)

    def _setpoint(self, state: VehicleState) -> Setpoint:
        yaw = self._init_yaw(state)
        reasons: list[str] = []
        if self._halted:
            self._switch_to_stop("halted (Ctrl-C)")
        if state.last_heard_s is not None and not state.link_ok:
            self._switch_to_stop("link lost", state)
        height = state.height_m if _finite(state.height_m) else None
        clearance = state.ground_clearance_m if _finite(state.ground_clearance_m) else None
        above_ground = height if clearance is None or height is None else min(height, clearance)
        if self.action == "down" and (above_ground is None or above_ground <= self.settings.floor_m):
            what = "height unknown" if above_ground is None else (
                f"floor {self.settings.floor_m:g} m reached" + (" (rangefinder)" if above_ground != height else ""))
            self._switch_to_stop(what, state)
        h_speed, v_speed = self.settings.horizontal_speed_m_s, self.settings.vertical_speed_m_s
        if self.bound is not None:
            h_speed, v_speed = self._bounded_speeds(state, h_speed, v_speed)
        forward, right, down = {
            "go_forward": (h_speed, 0.0, 0.0), "go_back": (-h_speed, 0.0, 0.0),
            "go_right": (0.0, h_speed, 0.0), "go_left": (0.0, -h_speed, 0.0),
            "up": (0.0, 0.0, -v_speed), "down": (0.0, 0.0, v_speed),
        }.get(self.action, (0.0, 0.0, 0.0))
        if self.action == HOMEWARD and self.bound is not None:  # straight toward home, in the body frame
            forward, right = ned_to_body(self.bound.direction[0] * h_speed, self.bound.direction[1] * h_speed, yaw)
        if down < 0 and (height is None or height >= self.settings.ceiling_m):
            down = 0.0
            reasons.append(f"ceiling {self.settings.ceiling_m:g} m" if height is not None else "height unknown")
        if forward or right:
            reason = self._fence_reason(state, forward, right, yaw)
            if reason:
                forward = right = 0.0
                reasons.append(reason)
        limits = "; ".join(reasons)
        if limits != self.limit_reason:
            self.limit_reason = limits
            self._tell_watcher()
        if self.action not in MOVING_OVER_GROUND and self.hold_point is None:
            self.hold_point = _point(state)   # first setpoint after take-off, or position heard at last
        if self.action not in VERTICAL_MOTIONS and self.hold_down_m is None and _finite(state.down_m):
            self.hold_down_m = state.down_m
        point = self.hold_point if self.action not in MOVING_OVER_GROUND else None
        hold_down = self.hold_down_m if self.action not in VERTICAL_MOTIONS else None
        return Setpoint(forward, right, down, yaw, point[0] if point else None, point[1] if point else None,
                        hold_down)

    def _bounded_speeds(self, state: VehicleState, h_speed: float, v_speed: float) -> tuple[float, float]:
        """The speeds toward a bounded motion's target; at the target, a stop that holds the target itself."""
        bound = self.bound
        assert bound is not None
        if bound.point is not None:
            point = _point(state)
            if point is None:
                self._switch_to_stop("position unknown", state)
                return 0.0, 0.0
            left = ((bound.point[0] - point[0]) * bound.direction[0]
                    + (bound.point[1] - point[1]) * bound.direction[1])
        else:
            if not _finite(state.down_m):
                self._switch_to_stop("height unknown", state)
                return 0.0, 0.0
            left = (bound.down_m - float(state.down_m)) * bound.direction[1]
        if left > ARRIVED_M:
            slow = left * BOUND_GAIN_HZ
            return min(h_speed, slow), min(v_speed, slow)
        self._switch_to_stop(f"{bound.label} reached", state)
        if bound.point is not None:
            self.hold_point = bound.point
        else:
            self.hold_down_m = bound.down_m
        return 0.0, 0.0

    def _fence_reason(self, state: VehicleState, forward_m_s: float, right_m_s: float, yaw_deg: float) -> str:
        if not (_finite(state.north_m) and _finite(state.east_m)):
            return "position unknown"
        offset_north = state.north_m - (state.home_north_m if _finite(state.home_north_m) else 0.0)
        offset_east = state.east_m - (state.home_east_m if _finite(state.home_east_m) else 0.0)
        if math.hypot(offset_north, offset_east) < self.settings.fence_radius_m:
            return ""
        north_m_s, east_m_s = body_to_ned(forward_m_s, right_m_s, yaw_deg)
        outward = north_m_s * offset_north + east_m_s * offset_east > 0.0
        return f"fence {self.settings.fence_radius_m:g} m from home" if outward else ""

