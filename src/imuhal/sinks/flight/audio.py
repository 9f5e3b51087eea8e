"""Vario audio: climb as rising beeps, strong sink as a continuous low tone, silence between.

The curve (:class:`VarioAudioSettings`, the profile's ``audio:`` section) follows the seed
author's ESP32 GPS vario (har-in-air/ESP32_IMU_BARO_GPS_VARIO, ``config.h`` and
``vario_audio.cpp``): climb tones from the climb threshold (0.5 m/s), a pitch that rises
from 200 Hz over three octaves to 1600 Hz at the crossover climb rate (4 m/s) and one more
octave to 3200 Hz at 10 m/s; beeps whose period shrinks as the climb grows (its beep table:
16 ticks at 0-1 m/s down to 4 ticks at 9-10 m/s, on for 10 down to 2 ticks; the tick here is
40 ms); silence in the dead band between the sink threshold (-2.5 m/s) and the climb
threshold; below the sink threshold a continuous tone falling from 400 Hz to 200 Hz at
-10 m/s (the firmware beeps long there; the issue asks for a continuous tone).

:class:`ToneGenerator` turns a climb rate held for a duration into 16-bit PCM, phase-
continuous across calls; :class:`AudioSink` feeds it the run's climb estimates and writes a
WAV file (standard library ``wave``) and/or plays live through ``sounddevice``.
"""

from __future__ import annotations

import math
import wave
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from imuhal.core.atomic import AtomicFile
from imuhal.core.errors import ImuhalError, OutputError
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.sinks.base import Event, SinkPlugin

BEEP_TABLE_TICKS = ((16, 10), (14, 9), (12, 8), (10, 7), (9, 6), (8, 5), (7, 4), (6, 3),
                    (5, 2), (4, 2))
"""(period, on-time) in ticks per 1 m/s band of climb, 0-1 m/s first (the seed firmware's)."""


class VarioAudioSettings(BaseModel):
    """The audio curve; climb rates in m/s (up positive), frequencies in Hz."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    climb_threshold_m_s: float = 0.5
    sink_threshold_m_s: float = -2.5
    crossover_m_s: float = Field(4.0, gt=0)
    max_climb_m_s: float = Field(10.0, gt=0)
    min_hz: float = Field(200.0, gt=0)
    crossover_hz: float = Field(1600.0, gt=0)
    max_hz: float = Field(3200.0, gt=0)
    sink_hz: float = Field(400.0, gt=0)
    """Tone at the sink threshold; it falls linearly to ``min_hz`` at -``max_climb_m_s``."""
    tick_s: float = Field(0.040, gt=0)
    volume: float = Field(0.5, ge=0, le=1)
    sample_rate_hz: int = Field(16000, ge=8000, le=96000)

    @model_validator(mode="after")
    def _ordered(self) -> VarioAudioSettings:
        if not self.sink_threshold_m_s < self.climb_threshold_m_s < self.crossover_m_s \
                < self.max_climb_m_s:
            raise ValueError("audio thresholds must satisfy sink_threshold < climb_threshold "
                             "< crossover < max_climb")
        return self

    def climb_hz(self, climb_m_s: float) -> float:
        """Beep pitch at ``climb_m_s`` (at or above the climb threshold)."""
        c = min(climb_m_s, self.max_climb_m_s)
        if c <= self.crossover_m_s:
            f = self.min_hz + (c - self.climb_threshold_m_s) * (
                self.crossover_hz - self.min_hz) / (self.crossover_m_s - self.climb_threshold_m_s)
        else:
            f = self.crossover_hz + (c - self.crossover_m_s) * (
                self.max_hz - self.crossover_hz) / (self.max_climb_m_s - self.crossover_m_s)
        return min(max(f, self.min_hz), self.max_hz)

    def beep(self, climb_m_s: float) -> tuple[float, float]:
        """(period s, on-time s) of the beeps at ``climb_m_s``."""
        index = min(max(int(climb_m_s), 0), len(BEEP_TABLE_TICKS) - 1)
        period, on = BEEP_TABLE_TICKS[index]
        return period * self.tick_s, on * self.tick_s

    def sink_tone_hz(self, climb_m_s: float) -> float:
        """Continuous tone below the sink threshold."""
        span = -self.max_climb_m_s - self.sink_threshold_m_s
        frac = min(max((climb_m_s - self.sink_threshold_m_s) / span, 0.0), 1.0)
        return self.sink_hz + frac * (self.min_hz - self.sink_hz)


class ToneGenerator:
    """Phase-continuous PCM for a climb rate held for a while."""

    def __init__(self, settings: VarioAudioSettings | None = None) -> None:
        self.settings = settings or VarioAudioSettings()
        self._phase = 0.0  # of the oscillator, radians
        self._beep_t = 0.0  # time into the current beep period, s
        self._sample_t = 0.0  # fractional sample carried between calls

    def render(self, climb_m_s: float, duration_s: float) -> np.ndarray:
        """int16 samples for ``duration_s`` at ``climb_m_s``."""
        s = self.settings
        exact = duration_s * s.sample_rate_hz + self._sample_t
        n = int(exact)
        self._sample_t = exact - n
        if n <= 0:
            return np.zeros(0, dtype=np.int16)
        dt = 1.0 / s.sample_rate_hz
        if climb_m_s >= s.climb_threshold_m_s:
            f = s.climb_hz(climb_m_s)
            period, on = s.beep(climb_m_s)
            t = (self._beep_t + dt * np.arange(n)) % period
            gate = t < on
            self._beep_t = (self._beep_t + n * dt) % period
        elif climb_m_s < s.sink_threshold_m_s:
            f = s.sink_tone_hz(climb_m_s)
            gate = np.ones(n, dtype=bool)
            self._beep_t = 0.0
        else:
            self._beep_t = 0.0
            return np.zeros(n, dtype=np.int16)
        phase = self._phase + 2 * math.pi * f * dt * np.arange(n)
        self._phase = float((self._phase + 2 * math.pi * f * dt * n) % (2 * math.pi))
        wave_ = np.sin(phase) * gate * (s.volume * 32767)
        return wave_.astype(np.int16)


class AudioOutputSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    curve: VarioAudioSettings = Field(default_factory=VarioAudioSettings)
    """The tone curve (``imuhal run`` takes the profile's ``audio:`` section)."""
    wav: str | None = None
    """Write the sound to this WAV file when the run closes."""
    live: bool = False
    """Play through sounddevice (``imuhal[audio]``)."""
    source: str | None = None
    """The vertical estimator to sonify (default: the first seen)."""


class AudioSink(SinkPlugin):
    """Sonifies one vertical estimator's climb rate.

    Each estimate's climb is held until the next one, in the run's time. ``wav``: the sound
    is written there when the run closes (to a temporary file first, so a failed run never
    replaces a good file). ``live``: played through sounddevice.
    """

    name: ClassVar[str] = "vario-audio"
    description: ClassVar[str] = "vario tones from the climb rate: a WAV file or live sound"
    Settings = AudioOutputSettings

    def __init__(self, settings: AudioOutputSettings | Mapping[str, Any] | None = None
                 ) -> None:
        super().__init__(settings)
        self.settings: AudioOutputSettings
        s = self.settings
        self.generator = ToneGenerator(s.curve)
        self.curve = s.curve
        self.wav_path = Path(s.wav) if s.wav is not None else None
        self.source = s.source
        self._last: VerticalEstimate | None = None
        self.samples_written = 0
        self._stream = None
        self._wav: wave.Wave_write | None = None
        self._file: AtomicFile | None = None
        if self.wav_path is not None:
            # The safe-writing rules of every imuhal output: links followed, the umask's
            # mode, the old file kept until the run closes.
            try:
                self._file = AtomicFile(self.wav_path, binary=True)
            except OutputError as exc:
                raise ImuhalError(f"--audio-wav {exc}") from None
            if self._file.direct:
                # A WAV header is patched at the end: it needs a seekable, regular file.
                self._file.abort()
                self._file = None
                raise ImuhalError(f"--audio-wav {self.wav_path}: is a pipe or device; a WAV "
                                  "file must be a regular file - give a file path")
            assert self._file.file is not None
            self._wav = wave.open(self._file.file, "wb")  # noqa: SIM115 - open until close()
            self._wav.setnchannels(1)
            self._wav.setsampwidth(2)
            self._wav.setframerate(s.curve.sample_rate_hz)
        if s.live:
            self._stream = _open_live(s.curve.sample_rate_hz)

    def handle(self, event: Event) -> None:
        if not isinstance(event, VerticalEstimate):
            return
        if self.source is None:
            self.source = event.source
        if event.source != self.source:
            return
        if self._last is not None and event.t_ns > self._last.t_ns:
            pcm = self.generator.render(self._last.climb_m_s,
                                        (event.t_ns - self._last.t_ns) / 1e9)
            self._emit(pcm)
        self._last = event

    def _emit(self, pcm: np.ndarray) -> None:
        if not pcm.size:
            return
        self.samples_written += pcm.size
        if self._wav is not None:
            try:
                self._wav.writeframes(pcm.astype("<i2").tobytes())
            except OSError as exc:
                raise ImuhalError(f"--audio-wav {self.wav_path}: cannot be written: "
                                  f"{exc.strerror or exc}; free some space or choose another "
                                  "path") from None
        if self._stream is not None:
            self._stream.write(pcm.reshape(-1, 1))

    def close(self) -> None:
        if self._stream is not None:
            self._stream.stop()
            self._stream.close()
            self._stream = None
        if self._wav is not None and self._file is not None:
            self._wav.close()  # patches the header; the file stays open for the commit
            self._wav = None
            self._file.commit()
            self._file = None

    def abort(self) -> None:
        """Drop the temporary WAV; ``wav_path`` keeps what it had."""
        if self._wav is not None and self._file is not None:
            self._wav = None
            self._file.abort()
            self._file = None


def _open_live(sample_rate_hz: int):  # type: ignore[no-untyped-def]
    try:
        import sounddevice
    except (ImportError, OSError) as exc:
        raise ImuhalError(f"--audio needs sounddevice and PortAudio ({exc}); install "
                          "imuhal[audio], or write a file with --audio-wav FILE") from None
    try:
        stream = sounddevice.OutputStream(samplerate=sample_rate_hz, channels=1,
                                          dtype="int16")
        stream.start()
    except Exception as exc:  # PortAudioError: no device
        raise ImuhalError(f"--audio: no sound output device ({exc}); use --audio-wav FILE"
                          ) from None
    return stream
