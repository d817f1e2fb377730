"""``python -m tools``: the index of the tools' commands, one line each (the same lines as tools/README.md).

Each line: the command, what it measures or makes, and the docs/bench report it writes (if any). Every command
takes ``--help``.
"""

from __future__ import annotations

import sys

#: group -> what the group serves
GROUPS = {
    "speech": "speech accuracy, corpora, training",
    "listen": "live listening and audio: the segmenter, the echo, the stop spotter",
    "flight": "flight and link",
    "sim": "the bundled simulator",
}

#: (group.module, what it measures or makes, the report it writes or "")
COMMANDS: list[tuple[str, str, str]] = [
    ("speech.real_speech", "the real recordings of ../shared/speech split by speaker (dev/test), real noise mixed "
     "under them; prints the split's counts", ""),
    ("speech.make_corpus", "synthesises the synthetic corpus (espeak-ng and Piper voices: commands, near-commands, "
     "other speech, noise) into corpus/", ""),
    ("speech.make_demo_audio", "makes the demo's spoken commands (gcs_voice/session/demo_audio/*.wav); --check "
     "compares them with fresh ones", ""),
    ("speech.bench_real", "the voice front-end on real speakers, clean and in real noise: recognise, tune, report, "
     "frontier, guard, gate, second-ear, stays, spread, timing",
     "docs/bench/real.md, real_timing.md (spread: printed)"),
    ("speech.bench_accuracy", "recogniser + matcher accuracy on the synthetic corpus and the real voices, per noise: "
     "recognise, report, tune, paired", "docs/bench/accuracy.md"),
    ("speech.bench_spanish", "Spanish on synthetic speech, and the Spanish thresholds chosen on it",
     "docs/bench/spanish.md"),
    ("speech.bench_amounts", "commands with an amount (\"forward 3 metres\") on synthetic speech, clean and in noise",
     "docs/bench/amounts.md"),
    ("speech.bench_amounts_real", "amounts on real voices (a real command word, then a real spoken digit)",
     "docs/bench/amounts_real.md"),
    ("speech.bench_sphinx_real", "PocketSphinx (the fallback engine) on real speech, its settings swept",
     "docs/bench/sphinx_real.md"),
    ("speech.bench_asr_speed", "speed (and command accuracy) of the three recognisers on this machine",
     ""),
    ("speech.train_ear", "trains the domain ear (a classifier over Whisper base's encoder) from the dev speakers, "
     "synthetic voices and noise halves, and the over-voice ear (also the bridge's own cues as the echo canceller "
     "leaves them); --tiny: CI's check that the recipe learns", ""),
    ("speech.ear_rows", "Whisper's recognitions and the ear's features of the real recordings, cached for "
     "bench_ear", ""),
    ("speech.bench_ear", "the domain ear on held-out speakers, each noise's unheard half and noises it never heard; "
     "tune: its thresholds on dev", "docs/bench/ear.md"),
    ("listen.bench_stream", "continuous streams of real speech over real noise through `gcs-voice recognize "
     "--segment`: commands right, false actions, deaf stretches", "docs/bench/stream.md"),
    ("listen.bench_listen", "a whole noisy flight heard through the live microphone path, and the same clips "
     "decided offline", "docs/bench/listen.md"),
    ("listen.bench_echo", "a stop said over the bridge's own voice: how often the stop spotter still hears it",
     "docs/bench/echo.md, echo_bilingual.md"),
    ("listen.bench_settle", "a stop spotted over the bridge's voice, settled by the over-voice ear: real stops "
     "kept, the canceller's remains of the bridge's cues let go; --split dev: chooses the ear's cue weight",
     "docs/bench/settle.md"),
    ("listen.bench_feedback_echo", "a long session with the bridge's own speech mixed back into the microphone",
     "docs/bench/feedback_echo.md"),
    ("listen.bench_stop_spotter", "the stop spotter on real speech: hits, false alarms, decoding time",
     "docs/bench/stop.md"),
    ("listen.bench_room_stops", "stops in a noisy room on the live path (--listen-wav), per room level and feedback: "
     "stops for nothing, motions they cancel, real stops held within 300 ms", "docs/bench/room_stops.md"),
    ("listen.bench_stop_latency", "stop latency, end of speech to the stop setpoint, with both cores loaded",
     "docs/bench/latency.md (its stop section)"),
    ("listen.bench_spotter_overlap", "what comes before or under a real \"stop\" and whether the spotter hears it",
     "printed (a section of docs/bench/echo.md)"),
    ("listen.bench_spotter_spanish", "the stop spotter in Spanish: which stop words it listens for",
     "docs/bench/spotter_spanish.md"),
    ("listen.bench_deaf_edge", "a word said across the end of the deaf time: heard by the spotter, acted on?",
     ""),
    ("listen.sweep_vad", "chooses the Silero segmenter's start/end thresholds on dev streams",
     "its pick is in docs/bench/stream.md"),
    ("listen.sweep_vad_memory", "chooses how long the Silero segmenter may remember (memory_s) on dev streams",
     "its pick is in docs/bench/stream.md"),
    ("flight.bench_latency", "latency from the end of an utterance to the decision and to the first setpoint on "
     "the wire", "docs/bench/latency.md, feedback_latency.md"),
    ("flight.fly_home_sitl", "\"return home\" said to the ArduCopter or PX4 SITL of ../shared/sitl",
     "docs/bench/home.md"),
    ("flight.link_flight", "a fixed action sequence flown through ActionMapper + VehicleLink against any vehicle",
     "docs/bench/link.md (printed, --markdown)"),
    ("flight.link_tlog_stats", "a ground-station .tlog summarised: setpoint timing, encodings, modes, ACKs, gaps",
     "docs/bench/link.md (printed)"),
    ("flight.soak_two_stations", "two ground stations on one vehicle through MAVProxy, for a bounded time", ""),
    ("flight.readiness_replay", "what the bridge would send at each point of a recorded boot (.tlog)", ""),
    ("flight.record_sim_fixture", "records the replay fixture tests/fixtures/sim_ardupilot_guided_flight.tlog", ""),
    ("flight.measure_holds", "what the setpoint holds buy: stop error and height kept, with and without them", ""),
    ("sim.bench_sim", "the simulator's physics: step responses, hover, yaw, touchdowns, lockstep speed",
     "docs/bench/sim.md"),
    ("sim.bench_sim_mavlink", "gcs-sim's MAVLink side: lockstep speed with telemetry, stream rates, ACK latency",
     "docs/bench/sim_mavlink.md"),
    ("sim.fuzz_sim", "fuzzes a running gcs-sim on UDP and TCP, then checks that it still serves",
     "docs/bench/fuzz_sim.md"),
]


def index_lines() -> list[str]:
    """One line per command: ``python -m tools.GROUP.NAME — what — report``."""
    return [f"python -m tools.{module} — {what} — {report or 'no report'}" for module, what, report in COMMANDS]


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args and args[0] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    print("\n".join(index_lines()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
