"""Audio in: WAV files, raw PCM on stdin and the microphone, all as 16 kHz mono int16 chunks.

As in wyoming's ``wav_to_chunks``, every source yields the same :class:`AudioChunk`, so a WAV file
looks exactly like a microphone to the utterance segmenter (``gcs_voice.audio.vad``) and the recognisers.
WAV files may have any rate and channel count and 8/16/24/32-bit integer or 32/64-bit float
samples; they are mixed to mono and resampled with numpy. Every unusable input is an AudioError.
"""

from __future__ import annotations

import queue
import struct
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from gcs_voice.audio import SAMPLE_RATE
from gcs_voice.errors import AudioError

__all__ = ["AudioChunk", "read_wav", "read_pcm", "pcm_bytes", "resample", "wav_to_chunks",
           "pcm_to_chunks", "microphone_chunks", "CHUNK_S", "MICROPHONE_BLOCK_S"]

#: Chunk length files and pipes are read in (100 ms: the segmenter re-cuts them into its own windows).
CHUNK_S = 0.1
#: A live microphone's block: one Silero window (512 samples), so the segmenter sees each window as soon as
#: it is spoken; a 100 ms block held up to 100 ms of the end of speech before anything could look at it.
MICROPHONE_BLOCK_S = 512 / SAMPLE_RATE
_FORMAT_PCM, _FORMAT_FLOAT, _FORMAT_EXTENSIBLE = 0x0001, 0x0003, 0xFFFE


@dataclass(frozen=True)
class AudioChunk:
    """16 kHz mono s16le PCM and when it starts, in seconds from the start of the source."""

    pcm: bytes
    start_s: float

    @property
    def duration_s(self) -> float:
        return len(self.pcm) / 2 / SAMPLE_RATE


def _parse_wav(data: bytes, name: str) -> tuple[int, int, int, int, bytes]:
    """(format, channels, rate, bits, sample bytes) from a RIFF/WAVE file."""
    if len(data) < 12 or data[:4] != b"RIFF" or data[8:12] != b"WAVE":
        raise AudioError(f"{name}: not a WAV file (no RIFF/WAVE header)")
    pos, fmt, samples = 12, None, None
    while pos + 8 <= len(data):
        chunk_id, size = data[pos:pos + 4], struct.unpack("<I", data[pos + 4:pos + 8])[0]
        body = data[pos + 8:pos + 8 + size]
        if chunk_id == b"fmt ":
            if len(body) < 16:
                raise AudioError(f"{name}: broken WAV fmt chunk")
            tag, channels, rate, _, _, bits = struct.unpack("<HHIIHH", body[:16])
            if tag == _FORMAT_EXTENSIBLE and len(body) >= 26:
                tag = struct.unpack("<H", body[24:26])[0]
            fmt = (tag, channels, rate, bits)
        elif chunk_id == b"data":
            samples = body
            if fmt is not None:
                break
        pos += 8 + size + (size & 1)
    if fmt is None:
        raise AudioError(f"{name}: WAV file without a fmt chunk")
    if samples is None:
        raise AudioError(f"{name}: WAV file without a data chunk")
    return (*fmt, samples)


def _to_float(tag: int, bits: int, raw: bytes, name: str) -> np.ndarray:
    if tag == _FORMAT_PCM and bits == 8:
        return (np.frombuffer(raw, np.uint8).astype(np.float32) - 128.0) / 128.0
    if tag == _FORMAT_PCM and bits == 16:
        return np.frombuffer(raw, "<i2").astype(np.float32) / 32768.0
    if tag == _FORMAT_PCM and bits == 24:
        b = np.frombuffer(raw, np.uint8).reshape(-1, 3).astype(np.int32)
        v = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
        v = np.where(v >= 1 << 23, v - (1 << 24), v)
        return v.astype(np.float32) / float(1 << 23)
    if tag == _FORMAT_PCM and bits == 32:
        return (np.frombuffer(raw, "<i4").astype(np.float64) / 2147483648.0).astype(np.float32)
    if tag == _FORMAT_FLOAT and bits in (32, 64):
        return np.nan_to_num(np.frombuffer(raw, "<f4" if bits == 32 else "<f8").astype(np.float32))
    kind = {_FORMAT_PCM: "integer", _FORMAT_FLOAT: "float"}.get(tag, f"format 0x{tag:04x}")
    raise AudioError(f"{name}: unsupported WAV sample format ({kind}, {bits} bit); "
                     f"use 8/16/24/32-bit integer or 32/64-bit float PCM")


def resample(samples: np.ndarray, from_rate: int, to_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Band-limited resampling by FFT (the spectrum is truncated or zero-padded: no aliasing)."""
    if from_rate == to_rate or samples.size == 0:
        return samples.astype(np.float32)
    n_out = max(1, int(round(samples.size * to_rate / from_rate)))
    spectrum = np.fft.rfft(samples.astype(np.float64))
    n_bins = n_out // 2 + 1
    if n_bins <= spectrum.size:
        spectrum = spectrum[:n_bins]
    else:
        spectrum = np.concatenate([spectrum, np.zeros(n_bins - spectrum.size, spectrum.dtype)])
    return (np.fft.irfft(spectrum, n_out) * (n_out / samples.size)).astype(np.float32)


def pcm_bytes(samples: np.ndarray) -> bytes:
    """Float samples in [-1, 1] -> s16le bytes (clipped)."""
    return (np.clip(samples, -1.0, 1.0) * 32767.0).round().astype("<i2").tobytes()


def read_wav(path: str | Path) -> bytes:
    """A WAV file as 16 kHz mono s16le PCM bytes; AudioError if missing, not WAV, empty or unsupported."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise AudioError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise AudioError(f"{path}: is a folder, not a WAV file") from None
    except OSError as exc:
        raise AudioError(f"{path}: cannot read: {exc.strerror or exc}") from None
    tag, channels, rate, bits, raw = _parse_wav(data, str(path))
    if channels < 1 or rate < 1000 or bits < 8 or bits % 8:
        raise AudioError(f"{path}: broken WAV header ({channels} channels, {rate} Hz, {bits} bit)")
    frame_bytes = channels * bits // 8
    raw = raw[: len(raw) // frame_bytes * frame_bytes]
    if not raw:
        raise AudioError(f"{path}: empty WAV file (no samples)")
    samples = _to_float(tag, bits, raw, str(path)).reshape(-1, channels).mean(axis=1)
    if tag == _FORMAT_PCM and bits == 16 and channels == 1 and rate == SAMPLE_RATE:
        return bytes(raw)
    return pcm_bytes(resample(samples, rate, SAMPLE_RATE))


def read_pcm(stream: BinaryIO | None = None, name: str = "stdin") -> bytes:
    """Raw 16 kHz mono s16le PCM from a binary stream (stdin by default)."""
    stream = stream if stream is not None else sys.stdin.buffer
    data = stream.read()
    if not data:
        raise AudioError(f"{name}: no audio (expected raw 16 kHz mono s16le PCM)")
    if data[:4] == b"RIFF":
        raise AudioError(f"{name}: got a WAV file; give its path instead of '-', or send raw PCM")
    if len(data) % 2:
        raise AudioError(f"{name}: odd number of bytes: not 16-bit PCM")
    return data


def pcm_to_chunks(pcm: bytes, chunk_s: float = CHUNK_S) -> Iterator[AudioChunk]:
    """Cut PCM bytes into chunks, like a microphone would deliver them."""
    step = max(2, int(SAMPLE_RATE * chunk_s) * 2)
    for offset in range(0, len(pcm), step):
        yield AudioChunk(pcm[offset:offset + step], offset / 2 / SAMPLE_RATE)


def wav_to_chunks(path: str | Path, chunk_s: float = CHUNK_S) -> Iterator[AudioChunk]:
    """A WAV file as a chunk stream (so tests and replays look exactly like the microphone)."""
    return pcm_to_chunks(read_wav(path), chunk_s)


def paced_chunks(pcm: bytes, chunk_s: float = MICROPHONE_BLOCK_S,
                 on_start: Callable[[float], object] | None = None) -> Iterator[AudioChunk]:
    """Recorded PCM as a microphone gives it: each block once it has been "spoken" (wall-clock pace).

    ``on_start`` gets the UNIX time of the first sample, so that times in the recording map to the clock."""
    t0 = time.time()
    if on_start is not None:
        on_start(t0)
    for chunk in pcm_to_chunks(pcm, chunk_s):
        wait_s = t0 + chunk.start_s + len(chunk.pcm) / 2 / SAMPLE_RATE - time.time()
        if wait_s > 0:
            time.sleep(wait_s)
        yield chunk


def microphone_chunks(device: int | str | None = None, chunk_s: float = MICROPHONE_BLOCK_S) -> Iterator[AudioChunk]:
    """Chunks from a microphone through sounddevice (callback into a queue, as vosk's test_microphone.py).

    Runs until the consumer stops iterating. No PortAudio or no input device is an AudioError.
    """
    try:
        import sounddevice as sd
    except (ImportError, OSError) as exc:
        raise AudioError(f"microphone unavailable: {exc} (install libportaudio2)") from None
    chunks: queue.Queue[bytes] = queue.Queue()
    blocksize = int(SAMPLE_RATE * chunk_s)

    def on_audio(indata, frames, time_info, status) -> None:  # noqa: ARG001 (sounddevice's signature)
        chunks.put(bytes(indata))

    try:
        stream = sd.RawInputStream(samplerate=SAMPLE_RATE, blocksize=blocksize, device=device,
                                   dtype="int16", channels=1, callback=on_audio)
    except Exception as exc:  # sounddevice.PortAudioError, ValueError for a bad device
        raise AudioError(f"microphone unavailable: {str(exc).splitlines()[0]}") from None
    samples = 0
    with stream:
        while True:
            pcm = chunks.get()
            yield AudioChunk(pcm, samples / SAMPLE_RATE)
            samples += len(pcm) // 2
