"""Keyboard commands beside the voice, for the live view: flight operations and an always-there stop.

Single keys, read from the terminal in cbreak mode (no Enter needed), restored on exit. Keys go
through the same bridge rules as voice (link lost, not armed, busy...).
"""

from __future__ import annotations

import sys
import threading

from gcs_voice.session.bridge import Bridge, Request

__all__ = ["KEY_ACTIONS", "start_key_thread"]

#: key -> action (space is stop: the one command that must always be at hand)
KEY_ACTIONS: dict[str, str] = {"t": "take_off", "l": "land", "h": "return_home", "a": "arm", "x": "disarm", " ": "stop"}
QUIT_KEYS = ("q", "\x03")  # q or Ctrl-C (cbreak keeps ISIG, but be safe)

#: set by the key thread while push-to-talk is open (Enter toggles); read by the microphone source
talk = threading.Event()


def _read_keys(bridge: Bridge) -> None:
    import termios
    import tty

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd, termios.TCSANOW)  # TCSAFLUSH (the default) would drop keys already typed
        while not bridge.finished:
            key = sys.stdin.read(1)
            if not key:
                return
            key = key.lower()
            if key in QUIT_KEYS:
                bridge.bus.emit("session", "quit key: stopping the vehicle and ending", phase="quit")
                bridge.finish(0)
                return
            if key in ("\n", "\r"):
                if talk.is_set():
                    talk.clear()
                else:
                    talk.set()
                bridge.bus.emit("warning", "push-to-talk " + ("open: speak" if talk.is_set() else "closed"))
                continue
            action = KEY_ACTIONS.get(key)
            if action:
                bridge.submit(Request(action, "key"))
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def start_key_thread(bridge: Bridge) -> threading.Thread:
    thread = threading.Thread(target=_read_keys, args=(bridge,), name="keys", daemon=True)
    thread.start()
    return thread
