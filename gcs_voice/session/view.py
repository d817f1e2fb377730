"""The live terminal view (rich): vehicle state, what was heard and done, what was refused and why.

Fed by two things only: bus events (folded into ``ViewState``) and a ``status()`` callable returning
the vehicle's current telemetry, polled at the refresh rate. It never commands anything, so a view
that fails is dropped by the EventBus and the flight goes on.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gcs_voice.session.events import Event, heard_words

__all__ = ["ViewState", "LiveView", "render", "KEY_HELP"]

KEY_HELP = "keys: t take off · l land · h home · a arm · x disarm · space stop · q quit"
REFRESH_HZ = 8


@dataclass
class ViewState:
    """What the panels show, folded from events (thread-safe by a lock)."""

    last_heard: dict[str, Any] | None = None
    last_command: dict[str, Any] | None = None
    #: an utterance has ended and its decision is pending (the ``thinking`` event), until it is heard
    thinking: dict[str, Any] | None = None
    rejected: deque = field(default_factory=lambda: deque(maxlen=5))
    warnings: deque = field(default_factory=lambda: deque(maxlen=6))
    vehicle_texts: deque = field(default_factory=lambda: deque(maxlen=4))
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __call__(self, event: Event) -> None:
        record = event.to_dict()
        with self.lock:
            if event.kind == "thinking":
                self.thinking = record
            elif event.kind == "heard":
                self.last_heard = record
                self.thinking = None
            elif event.kind == "command":
                self.last_command = record
            elif event.kind == "rejected":
                self.rejected.appendleft(record)
            elif event.kind in ("refused", "warning", "error", "link", "flight", "late", "spotted", "takeover"):
                self.warnings.appendleft(record)
            elif event.kind == "vehicle":
                self.vehicle_texts.appendleft(record)


def _clock(t: float) -> str:
    return time.strftime("%H:%M:%S", time.localtime(t))


def _fmt(value: Any, unit: str = "", digits: int = 1) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}{unit}"
    return f"{value}{unit}"


def render(state: ViewState, status: dict[str, Any], listening: str = "") -> Any:
    """Build the rich renderable for one frame (pure: easy to test by rendering to a string)."""
    from rich.console import Group
    from rich.panel import Panel
    from rich.table import Table
    from rich.text import Text

    link = status.get("link", "waiting")
    link_style = {"ok": "bold green", "lost": "bold red"}.get(link, "yellow")
    vehicle = Table.grid(padding=(0, 2))
    for _ in range(4):
        vehicle.add_column()
    vehicle.add_row("link", Text(str(link).upper(), style=link_style), "autopilot", _fmt(status.get("autopilot")))
    vehicle.add_row("mode", _fmt(status.get("mode")), "armed",
                    Text("ARMED", style="bold red") if status.get("armed") else Text("disarmed"))
    vehicle.add_row("altitude", _fmt(status.get("alt_m"), " m", 2), "heading", _fmt(status.get("heading_deg"), " deg", 0))
    vehicle.add_row("speed", _fmt(status.get("speed_m_s"), " m/s", 2), "action", _fmt(status.get("action")))
    vehicle.add_row("battery", _fmt(status.get("battery_pct"), " %", 0), "", "")
    if status.get("ready"):  # disarmed: what the vehicle still waits for ("waiting for: position (EKF)")
        style = "green" if status["ready"] == "ready to arm" else "yellow"
        vehicle.add_row("vehicle", Text(str(status["ready"]), style=style), "", "")

    with state.lock:
        heard, command, thinking = state.last_heard, state.last_command, state.thinking
        rejected, warnings, texts = list(state.rejected), list(state.warnings), list(state.vehicle_texts)

    voice = Table.grid(padding=(0, 1))
    voice.add_column(style="dim")
    voice.add_column()
    if heard:
        voice.add_row("heard", Text(f"\"{heard_words(heard)}\"  ({heard.get('engine', '?')}, "
                                    f"{heard.get('lang') or '?'})", style="bold"))
    if command:
        said = f"{command['phrase']} -> " if command.get("phrase") else ""
        how = (f"  score {command['score']:.2f}" if isinstance(command.get("score"), (int, float))
               else f"  ({command.get('origin', '?')})")
        amount = f" {command['amount']}" if command.get("amount") else ""   # "go_forward 3 m"
        voice.add_row("did", Text(f"{said}{command.get('action')}{amount}{how}", style="bold cyan"))
    if thinking:
        voice.add_row("now", Text(f"thinking… (utterance ended {_clock(thinking['t'])})", style="italic yellow"))
    if not heard and not command and not thinking:
        voice.add_row("", Text("say a command" + (f" ({listening})" if listening else "")))
    elif listening:
        voice.add_row("mic", listening)

    rej = Table.grid(padding=(0, 1))
    rej.add_column(style="dim")
    rej.add_column()
    for r in rejected:
        hint = f" ({r['hint']})" if r.get("hint") else ""  # a loud room: the pilot can help (listen.VoicePipeline.hear)
        rej.add_row(_clock(r["t"]), Text(f"\"{r.get('text', '')}\" - {r.get('reason', '')}{hint}", style="yellow"))
    warn = Table.grid(padding=(0, 1))
    warn.add_column(style="dim")
    warn.add_column()
    for w in warnings:
        style = ("red" if w["kind"] in ("refused", "error", "late", "takeover") or w.get("state") == "lost"
                 else "bold cyan" if w["kind"] == "spotted" else "white")
        warn.add_row(_clock(w["t"]), Text(w["msg"], style=style))
    for v in texts:
        warn.add_row(_clock(v["t"]), Text(f"vehicle: {v.get('text', v['msg'])}", style="magenta"))

    return Group(
        Panel(vehicle, title="vehicle", border_style=link_style),
        Panel(voice, title="voice"),
        Panel(rej if rejected else Text("none", style="dim"), title="rejected (no action)"),
        Panel(warn if (warnings or texts) else Text("none", style="dim"), title="events and warnings"),
        Text(KEY_HELP, style="dim"),
    )


class LiveView:
    """Runs rich.live.Live in its own thread until ``stop()``; subscribe ``state`` to the EventBus."""

    def __init__(self, status: Callable[[], dict[str, Any]], listening: Callable[[], str] = lambda: "") -> None:
        self.state = ViewState()
        self._status = status
        self._listening = listening
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="live-view", daemon=True)
        self._thread.start()

    def _frame(self) -> Any:
        return render(self.state, self._status(), self._listening())

    def _run(self) -> None:
        from rich.live import Live

        with Live(self._frame(), refresh_per_second=REFRESH_HZ, screen=False, transient=False) as live:
            while not self._stop.wait(1.0 / REFRESH_HZ):
                live.update(self._frame())

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
