"""End of utterance: where speech starts and ends in a continuous stream, in quiet rooms and in noise.

``segment_utterances(chunks)`` takes any chunk stream (WAV, stdin, microphone: see
``gcs_voice.audio.sources``) and yields each spoken utterance with its start and end time, for the
``recognize`` command and the live bridge alike. Settings are data (``vad.toml``).

Two detectors share one interface:

- ``silero`` (default): the Silero VAD network, run on 32 ms windows with its recurrent state carried
  from window to window, then hysteresis (a start and a lower end threshold, minimum speech, minimum
  silence, pre-roll). An energy threshold cannot tell a voice from kitchen clatter at 12 dB SNR and
  merges the utterances (29 segments for 60); the network can. Its ONNX model ships inside the
  faster-whisper wheel (already a dependency) and runs with onnxruntime on one thread: deterministic.
- ``energy``: a noise floor and a hangover; no model needed. It is the fallback when the Silero model
  or onnxruntime is missing, and fine in a quiet room.
"""

from __future__ import annotations

import tomllib
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, fields
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.audio.sources import AudioChunk

__all__ = ["Utterance", "RoomLevel", "SpeechListener", "VadSettings", "EnergySettings", "SileroSettings", "load_vad_settings",
           "segment_utterances", "frame_dbfs", "SileroVad", "silero_model_path"]

VAD_SETTINGS_PATH = Path(__file__).resolve().parent / "vad.toml"
#: Silero works on 512-sample windows at 16 kHz, each seen with the 64 samples before it.
SILERO_WINDOW = 512
SILERO_CONTEXT = 64


@dataclass(frozen=True)
class Utterance:
    """One spoken utterance: 16 kHz mono s16le PCM and where it was in the source, in seconds."""

    pcm: bytes
    start_s: float
    end_s: float
    #: how far the voice stood above the room, in dB (None: no room heard before it): the recogniser's accuracy
    #: falls with it, and a pilot can do something about it (speak up, or nearer the microphone)
    snr_db: float | None = None

    @property
    def duration_s(self) -> float:
        return len(self.pcm) / 2 / SAMPLE_RATE


@dataclass(frozen=True)
class EnergySettings:
    frame_s: float = 0.02
    min_speech_dbfs: float = -45.0
    noise_margin_db: float = 12.0
    noise_adapt: float = 0.05
    start_s: float = 0.06
    hangover_s: float = 0.45
    pre_roll_s: float = 0.25


@dataclass(frozen=True)
class SileroSettings:
    start_threshold: float = 0.3
    end_threshold: float = 0.2
    min_speech_s: float = 0.1
    min_silence_s: float = 0.3
    pre_roll_s: float = 0.2
    post_pad_s: float = 0.1
    #: audio the listener (``on_speech``: the stop spotter) hears before the detected start (at least pre_roll_s)
    listen_pre_roll_s: float = 0.2
    #: how far back the network's state may remember (0: forever, the state drifts in long noise)
    memory_s: float = 0.0


@dataclass(frozen=True)
class VadSettings:
    method: str = "silero"
    min_utterance_s: float = 0.15
    max_utterance_s: float = 8.0
    #: a voice less than this far above the room, not understood, is told so (gcs_voice.session.listen)
    loud_room_snr_db: float = 10.0
    #: ... when Whisper scoring's margin says a command was near (gcs_voice.session.listen.loud_room_hint)
    loud_room_min_margin: float = -3.0
    energy: EnergySettings = field(default_factory=EnergySettings)
    silero: SileroSettings = field(default_factory=SileroSettings)

    @property
    def hangover_s(self) -> float:
        """Silence after the last speech before an utterance is handed on (latency the segmenter adds)."""
        return self.silero.min_silence_s if self.method == "silero" else self.energy.hangover_s


def _section(cls: type, values: dict[str, Any], path: Path = VAD_SETTINGS_PATH) -> Any:
    known = {f.name for f in fields(cls)}
    unknown = set(values) - known
    if unknown:
        from gcs_voice.errors import AudioError

        raise AudioError(f"{path}: unknown setting(s) {', '.join(sorted(unknown))} for {cls.__name__}")
    return cls(**{k: float(v) for k, v in values.items()})


def load_vad_settings(path: Path = VAD_SETTINGS_PATH, method: str | None = None) -> VadSettings:
    """The segmenter's settings from ``vad.toml``; ``method`` overrides the file's choice."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    chosen = method or str(data.get("method", "silero"))
    if chosen not in ("silero", "energy"):
        from gcs_voice.errors import AudioError

        raise AudioError(f"unknown VAD method {chosen!r} (silero or energy)")
    return VadSettings(method=chosen, min_utterance_s=float(data.get("min_utterance_s", 0.15)),
                       max_utterance_s=float(data.get("max_utterance_s", 8.0)),
                       loud_room_snr_db=float(data.get("loud_room_snr_db", 10.0)),
                       loud_room_min_margin=float(data.get("loud_room_min_margin", -3.0)),
                       energy=_section(EnergySettings, data.get("energy", {}), path),
                       silero=_section(SileroSettings, data.get("silero", {}), path))


def frame_dbfs(pcm: bytes) -> float:
    """RMS level of s16le PCM in dB relative to full scale (-120 for silence)."""
    x = np.frombuffer(pcm, "<i2").astype(np.float64) / 32768.0
    rms = float(np.sqrt(np.mean(x * x))) if x.size else 0.0
    return 20.0 * np.log10(max(rms, 1e-6))


def silero_model_path() -> Path | None:
    """The Silero VAD ONNX file inside the installed faster-whisper package (None when absent)."""
    try:
        import importlib.util

        spec = importlib.util.find_spec("faster_whisper")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    assets = Path(list(spec.submodule_search_locations)[0]) / "assets"
    found = sorted(assets.glob("silero_vad*.onnx"))
    return found[-1] if found else None


@lru_cache(maxsize=1)
def _silero_session(path: str) -> Any:
    import onnxruntime

    opts = onnxruntime.SessionOptions()
    opts.inter_op_num_threads = 1
    opts.intra_op_num_threads = 1
    opts.log_severity_level = 4
    return onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"], sess_options=opts)


class SileroVad:
    """Speech probability per 32 ms window of a stream, from a network whose memory is bounded.

    Silero is a recurrent network. Carried across minutes of noise, its state drifts until speech no
    longer registers: in kitchen noise at 12 dB, speech that peaks at P=0.9 from a fresh state peaks
    below the start threshold after some minutes (the segmenter goes deaf). With ``memory_s`` > 0 two
    copies of the state run side by side, each started afresh every ``2 * memory_s`` seconds, half a period
    apart, and the answer comes from the copy that has run longer: every probability then depends on
    between ``memory_s`` and ``2 * memory_s`` seconds of the stream, never on what came before, so the
    segmenter hears speech the same after an hour of noise as after one minute. ``memory_s`` = 0 carries
    one state forever (the network as it was trained and shipped; for comparison).
    """

    def __init__(self, model: Path | None = None, memory_s: float = 0.0) -> None:
        path = model or silero_model_path()
        if path is None:
            from gcs_voice.errors import ModelError

            raise ModelError("the Silero VAD model was not found (it ships with faster-whisper)")
        self.session = _silero_session(str(path))
        #: windows between the restarts of one copy of the state (0: never restarted)
        self.period = 2 * max(0, round(memory_s * SAMPLE_RATE / SILERO_WINDOW))
        self.reset()

    def reset(self) -> None:
        self.states = [self._zero_state() for _ in range(2 if self.period else 1)]
        self.context = np.zeros(SILERO_CONTEXT, dtype=np.float32)
        self.windows = 0

    @staticmethod
    def _zero_state() -> tuple[np.ndarray, np.ndarray]:
        return np.zeros((1, 1, 128), dtype=np.float32), np.zeros((1, 1, 128), dtype=np.float32)

    def probability(self, window: np.ndarray) -> float:
        """P(speech) of one 512-sample float window in [-1, 1]."""
        x = np.concatenate([self.context, window.astype(np.float32)])[None, :]
        self.context = x[0, -SILERO_CONTEXT:]
        i, self.windows = self.windows, self.windows + 1
        if not self.period:
            out, h, c = self.session.run(None, {"input": x, "h": self.states[0][0], "c": self.states[0][1]})
            self.states[0] = (h, c)
            return float(np.asarray(out).reshape(-1)[0])
        half = self.period // 2
        ages = (i % self.period, (i - half) % self.period)  # windows each copy has run since its restart
        running = (0,) if i < half else (0, 1)  # the second copy starts half a period in
        answering = 0 if i < half else int(ages[1] > ages[0])  # the copy that has run longer
        answer = 0.0
        for k in running:
            if ages[k] == 0:
                self.states[k] = self._zero_state()
            out, h, c = self.session.run(None, {"input": x, "h": self.states[k][0], "c": self.states[k][1]})
            self.states[k] = (h, c)
            if k == answering:
                answer = float(np.asarray(out).reshape(-1)[0])
        return answer


#: Told each piece of an utterance while it is still being spoken (PCM), and None when it is over.
SpeechListener = Callable[[bytes | None], None]

#: the room is the audio outside speech over about this long (windows the detector does not call speech)
ROOM_S = 10.0
#: below this mean square (-90 dBFS) audio is digital silence (push-to-talk released, the bridge's own sound
#: muted out): no room at all, not a quiet one
DIGITAL_SILENCE = 1e-9


class RoomLevel:
    """The level of the room (the audio outside speech, lately) and of a voice over it: the utterance's SNR."""

    def __init__(self, window_s: float) -> None:
        self.powers: deque[float] = deque(maxlen=max(1, round(ROOM_S / window_s)))

    def hear(self, power: float) -> None:
        """One window outside speech, by its mean square."""
        if power > DIGITAL_SILENCE:
            self.powers.append(power)

    def snr_db(self, speech_power: float) -> float | None:
        """How far a voice of mean square ``speech_power`` (the room included) stands above the room, in dB."""
        if not self.powers:
            return None
        room = float(np.mean(self.powers))
        return round(10.0 * float(np.log10(max(speech_power - room, room * 1e-3) / room)), 1)


def _power(window: np.ndarray) -> float:
    return float(np.mean(np.square(window, dtype=np.float64)))


def segment_utterances(chunks: Iterable[AudioChunk], settings: VadSettings | None = None,
                       on_speech: SpeechListener | None = None,
                       on_tentative: Callable[[Utterance], None] | None = None) -> Iterator[Utterance]:
    """Yield utterances as soon as their end is heard (after the method's minimum silence).

    ``on_speech`` hears the audio of an utterance as it arrives, before the utterance is complete (the
    stop spotter uses it not to wait for the silence that ends it), then None at its end; with Silero it
    starts ``listen_pre_roll_s`` before the detected start (the room before the word).
    ``on_tentative`` (Silero only) gets the utterance as it WILL be yielded if no speech follows, as soon
    as its content is final (``post_pad_s`` after the last speech), before the rest of the minimum silence:
    a recogniser can decide it while the silence runs out. Speech that resumes makes a longer utterance,
    so a tentative one is used only if the yielded utterance has the same PCM.
    """
    s = settings or load_vad_settings()
    listen = on_speech or (lambda pcm: None)
    tentative = on_tentative or (lambda utt: None)
    if s.method == "silero":
        try:
            vad = SileroVad(memory_s=s.silero.memory_s)
        except Exception as exc:  # noqa: BLE001 - no model or no onnxruntime: the energy VAD still works
            warnings.warn(f"Silero VAD unavailable ({exc}); using the energy VAD", RuntimeWarning, stacklevel=2)
        else:
            yield from _silero_segments(chunks, s, vad, listen, tentative)
            return
    yield from _energy_segments(chunks, s, listen)


def _windows(chunks: Iterable[AudioChunk], size_bytes: int) -> Iterator[bytes]:
    pending = b""
    for chunk in chunks:
        pending += chunk.pcm
        while len(pending) >= size_bytes:
            yield pending[:size_bytes]
            pending = pending[size_bytes:]
    if pending:
        yield pending + bytes(size_bytes - len(pending))  # the last partial window, padded with silence


def _silero_segments(chunks: Iterable[AudioChunk], s: VadSettings, vad: SileroVad,
                     listen: SpeechListener, tentative: Callable[[Utterance], None]) -> Iterator[Utterance]:
    p = s.silero
    win_s = SILERO_WINDOW / SAMPLE_RATE
    pre_windows = max(0, round(p.pre_roll_s / win_s))
    post_windows = max(0, round(p.post_pad_s / win_s))
    silence_windows = max(1, round(p.min_silence_s / win_s))
    min_speech_windows = max(1, round(p.min_speech_s / win_s))
    max_windows = max(1, int(s.max_utterance_s / win_s))
    history: deque[bytes] = deque(maxlen=pre_windows + 1)  # the current window and the pre-roll before it
    # what the listener hears before the start: it may want more of the room than the recogniser
    lead: deque[bytes] = deque(maxlen=max(pre_windows, round(p.listen_pre_roll_s / win_s)) + 1)
    speech: list[bytes] = []
    start_i = 0  # index of the utterance's first window (pre-roll included)
    voiced = 0  # windows at or above the end threshold in this utterance
    voiced_power = 0.0  # their mean squares, summed
    silent_run = 0
    in_utt = False
    room = RoomLevel(win_s)

    def emit(frames: list[bytes], first: int) -> Utterance | None:
        pcm = b"".join(frames)
        if voiced < min_speech_windows or len(pcm) / 2 / SAMPLE_RATE < s.min_utterance_s:
            return None
        return Utterance(pcm, first * win_s, first * win_s + len(pcm) / 2 / SAMPLE_RATE,
                         room.snr_db(voiced_power / voiced))

    for i, window in enumerate(_windows(chunks, SILERO_WINDOW * 2)):
        samples = np.frombuffer(window, "<i2").astype(np.float32) / 32768.0
        prob = vad.probability(samples)
        history.append(window)
        lead.append(window)
        if not in_utt:
            if prob >= p.start_threshold:
                in_utt, speech, voiced, voiced_power, silent_run = True, list(history), 1, _power(samples), 0
                start_i = i - len(history) + 1
                listen(b"".join(lead))
            elif prob < p.end_threshold:
                room.hear(_power(samples))
            continue
        speech.append(window)
        listen(window)
        if prob >= p.end_threshold:
            voiced += 1
            voiced_power += _power(samples)
            silent_run = 0
        else:
            silent_run += 1
            if silent_run == max(1, post_windows) and silent_run < silence_windows:
                # What the end below will keep if no speech comes back: final from now on.
                early = emit(speech[: len(speech) - silent_run + min(silent_run, post_windows)], start_i)
                if early:
                    tentative(early)
        if silent_run >= silence_windows or len(speech) >= max_windows:
            keep = speech[: len(speech) - silent_run + min(silent_run, post_windows)]
            utt = emit(keep, start_i)
            listen(None)
            if utt:
                yield utt
            in_utt, speech = False, []
            history.clear()
    if in_utt and speech:
        utt = emit(speech[: len(speech) - silent_run + min(silent_run, post_windows)], start_i)
        listen(None)
        if utt:
            yield utt


def _energy_segments(chunks: Iterable[AudioChunk], s: VadSettings, listen: SpeechListener) -> Iterator[Utterance]:
    e = s.energy
    frame_bytes = int(SAMPLE_RATE * e.frame_s) * 2
    pre_roll: deque[bytes] = deque(maxlen=max(1, int(e.pre_roll_s / e.frame_s)))
    start_frames = max(1, round(e.start_s / e.frame_s))
    hang_frames = max(1, round(e.hangover_s / e.frame_s))
    max_frames = max(1, int(s.max_utterance_s / e.frame_s))
    noise_dbfs = None
    speech: list[bytes] = []
    in_utt, voiced_run, silent_run, start_s = False, 0, 0, 0.0
    pending = b""
    t_frames = 0  # frames seen so far
    room = RoomLevel(e.frame_s)
    voiced_powers: list[float] = []  # the powers of the utterance's voiced frames

    def emit(frames: list[bytes], start: float) -> Utterance | None:
        pcm = b"".join(frames)
        if len(pcm) / 2 / SAMPLE_RATE < s.min_utterance_s:
            return None
        return Utterance(pcm, start, start + len(pcm) / 2 / SAMPLE_RATE,
                         room.snr_db(float(np.mean(voiced_powers))) if voiced_powers else None)

    for chunk in chunks:
        pending += chunk.pcm
        while len(pending) >= frame_bytes:
            frame, pending = pending[:frame_bytes], pending[frame_bytes:]
            level = frame_dbfs(frame)
            if noise_dbfs is None:
                noise_dbfs = min(level, e.min_speech_dbfs)
            voiced = level > max(e.min_speech_dbfs, noise_dbfs + e.noise_margin_db)
            power = 10 ** (level / 10)
            if not voiced:
                noise_dbfs += e.noise_adapt * (level - noise_dbfs)
                if not in_utt:
                    room.hear(power)
            t_s = t_frames * e.frame_s
            t_frames += 1
            if not in_utt:
                pre_roll.append(frame)
                voiced_run = voiced_run + 1 if voiced else 0
                if voiced_run >= start_frames:
                    in_utt, silent_run, voiced_powers = True, 0, []
                    speech = list(pre_roll)
                    start_s = max(0.0, t_s + e.frame_s - len(speech) * e.frame_s)
                    pre_roll.clear()
                    listen(b"".join(speech))
                continue
            speech.append(frame)
            listen(frame)
            silent_run = 0 if voiced else silent_run + 1
            if voiced:
                voiced_powers.append(power)
            if silent_run >= hang_frames or len(speech) >= max_frames:
                keep = speech[: len(speech) - silent_run + min(silent_run, hang_frames // 2)]
                utt = emit(keep, start_s)
                listen(None)
                if utt:
                    yield utt
                in_utt, voiced_run, speech = False, 0, []
    if in_utt and speech:
        utt = emit(speech + ([pending] if pending else []), start_s)
        listen(None)
        if utt:
            yield utt
