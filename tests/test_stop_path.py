"""The stop path between the spotter and the vehicle: a stop heard again over the bridge's own voice is not a
new stop, and a stop after anything else was commanded always is.

The real spotter hears a real recorded stop; the bridge flies the bundled simulator on 127.0.0.1.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from e2e_support import SPEEDUP, require_parts
from gcs_voice.actions.mapper import ActionMapper
from gcs_voice.link import VehicleLink
from gcs_voice.session.bridge import Bridge, Request
from gcs_voice.session.events import EventBus
from gcs_voice.session.listen import StopPath
from gcs_voice.session.sim_process import BundledSim
from gcs_voice.settings import load_settings

pytestmark = pytest.mark.slow


def _spotter_stops(bus: EventBus) -> int:
    return sum(1 for e in bus.history if e.kind == "command" and e.data.get("origin") == "spotter")


def _wait_stops(bus: EventBus, n: int) -> None:
    """Until the bridge has sent ``n`` spotter stops (events, not a guess at how long it takes)."""
    done = threading.Event()

    def look(event) -> None:
        if _spotter_stops(bus) >= n:
            done.set()

    bus.subscribe(look)
    look(None)
    assert done.wait(30), [e.msg for e in bus.history]


@contextmanager
def _flying_forward(tmp_path: Path, bus: EventBus) -> Iterator[Bridge]:
    """A bridge flying the bundled simulator on 127.0.0.1, taken off and going forward; finished on leaving."""
    with BundledSim(speedup=SPEEDUP, room="open_field", log_path=tmp_path / "sim.log") as sim:
        link = VehicleLink(sim.connection, load_settings(), tlog_path=tmp_path / "s.tlog")
        link.open()
        try:
            link.wait_vehicle(30)
            link.request_telemetry()
            bridge = Bridge(link, ActionMapper(link.settings), bus, 1.5)
            runner = threading.Thread(target=bridge.run, daemon=True)
            runner.start()
            bridge.submit(Request("take_off", "script"))
            assert bridge.flying_ready.wait(120), [e.msg for e in bus.history]
            assert bridge.wait_idle(60)
            assert bridge.submit(Request("go_forward", "key")).done.wait(10)
            yield bridge
            bridge.finish()
            runner.join(60)
        finally:
            link.close()


def test_a_stop_heard_again_over_the_bridge_voice_is_sent_once_and_a_later_one_again(
        tmp_path: Path, real_speech_dir: Path) -> None:
    require_parts("sim_bridge.cli")
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.audio.sources import read_wav
    from tools.speech.real_speech import load_recordings

    spotter = load_stop_spotter(["en"])
    pcm = next(read_wav(r.path) for r in load_recordings(real_speech_dir, split="test")
               if r.action == "stop" and spotter.spot(read_wav(r.path)).fired
               and spotter.spot(read_wav(r.path), over_voice=True).fired)
    bus = EventBus()
    with _flying_forward(tmp_path, bus) as bridge:
        path = StopPath(spotter, bus)

        def say(over_voice: bool) -> None:
            path.feed(bridge, pcm, over_voice=over_voice)
            path.end(bridge, time.time())

        say(over_voice=False)            # the pilot's stop
        _wait_stops(bus, 1)
        say(over_voice=True)             # its end heard again over the bridge's "braking"
        assert bridge.submit(Request("go_left", "key")).done.wait(10)
        say(over_voice=True)             # a new stop over the bridge's "going left"
        _wait_stops(bus, 2)
    spotted = [e for e in bus.history if e.kind == "spotted"]
    assert [bool(e.data.get("repeat")) for e in spotted] == [False, True, False], [e.msg for e in spotted]
    assert _spotter_stops(bus) == 2, [e.msg for e in bus.history]
    assert "already holding, not sent again" in spotted[1].msg


def test_a_stop_spotted_while_a_paused_motion_waits_for_its_decision_only_holds_it(
        tmp_path: Path, real_speech_dir: Path) -> None:
    """The motion is paused while the utterance before is decided; the spotter then fires: the motion is held, not
    cancelled, and goes on when the decision finds no stop (issue 52: this cancelled motions in the room)."""
    require_parts("sim_bridge.cli")
    from gcs_voice.asr.stop_spotter import load_stop_spotter
    from gcs_voice.audio.sources import read_wav
    from gcs_voice.session.bridge import PAUSE, RESUME
    from tools.speech.real_speech import load_recordings

    spotter = load_stop_spotter(["en"])
    pcm = next(read_wav(r.path) for r in load_recordings(real_speech_dir, split="test")
               if r.action == "stop" and spotter.spot(read_wav(r.path)).fired)
    bus = EventBus()
    with _flying_forward(tmp_path, bus) as bridge:
        assert bridge.submit(Request(PAUSE, "voice")).done.wait(10)   # an utterance ended: being decided
        assert bridge.mapper.paused == "go_forward"
        path = StopPath(spotter, bus)
        path.provisional = True            # as with a domain ear to settle it
        path.feed(bridge, pcm)
        path.end(bridge, time.time())
        assert path.take_hold()            # a hold waits for the decision ...
        assert bridge.mapper.paused == "go_forward", [e.msg for e in bus.history]
        assert bridge.submit(Request(RESUME, "voice")).done.wait(10)  # ... which found no stop
        assert bridge.mapper.action == "go_forward", [e.msg for e in bus.history]
    spotted = [e for e in bus.history if e.kind == "spotted"]
    assert [bool(e.data.get("provisional")) for e in spotted] == [True], [e.msg for e in spotted]
    assert _spotter_stops(bus) == 0, [e.msg for e in bus.history]
