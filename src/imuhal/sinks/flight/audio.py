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
continuous across calls, every tone start and stop a short raised-cosine ramp (no clicks),
an optional sink alarm (a two-tone warble); :class:`AudioSink` feeds it the run's climb
estimates through an optional damping low-pass, silent at power-up until the vario has
settled, and writes a WAV file (standard library ``wave``) and/or plays live through
``sounddevice``.
"""

from __future__ import annotations

import itertools
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
    ramp_s: float = Field(0.005, gt=0, le=0.02)
    """Every tone starts and stops with a raised-cosine ramp this long (no clicks); a beep's
    fade-out ends at the end of its on-time."""
    damping_s: float = Field(0.0, ge=0, le=10)
    """Time constant of a first-order low-pass on the climb rate before it is sonified
    (0: the vario's own output). After a step in climb the tone follows 63 % of it after
    ``damping_s`` (XC Tracer: damping 0-10; LXNAV: vario filter 0.1-5 s)."""
    sink_alarm_m_s: float | None = None
    """At or below this climb rate (e.g. -5): the sink alarm, a two-tone warble, instead of
    the sink tone (None: no alarm)."""
    sink_alarm_hz: tuple[float, float] = (700.0, 1100.0)
    """The warble's two pitches, alternating every ``sink_alarm_period_s`` / 2."""
    sink_alarm_period_s: float = Field(0.25, gt=0)
    settle_s: float = Field(1.0, ge=0)
    """Silent at power-up until the climb has stayed in the dead band this long (the vario
    filter settling on the ground beeps otherwise) ..."""
    settle_max_s: float = Field(10.0, ge=0)
    """... or until this long after the first climb estimate (a start in the air)."""

    @model_validator(mode="after")
    def _ordered(self) -> VarioAudioSettings:
        if not self.sink_threshold_m_s < self.climb_threshold_m_s < self.crossover_m_s \
                < self.max_climb_m_s:
            raise ValueError("audio thresholds must satisfy sink_threshold < climb_threshold "
                             "< crossover < max_climb")
        if self.sink_alarm_m_s is not None and not (
                self.sink_alarm_m_s < self.climb_threshold_m_s):  # NaN fails here too
            raise ValueError(f"audio sink_alarm_m_s {self.sink_alarm_m_s} must be below "
                             f"climb_threshold_m_s {self.climb_threshold_m_s} (a sink rate, "
                             "e.g. -5)")
        if any(f <= 0 for f in self.sink_alarm_hz):
            raise ValueError("audio sink_alarm_hz: both pitches must be positive")
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
    """Phase-continuous PCM for a climb rate held for a while.

    The oscillator's phase runs on across calls and pitch changes, and the amplitude never
    jumps: a gate (beep on/off, tone on/off) moves an envelope level at most 1/``ramp_s``
    per second, shaped as a raised cosine, so every tone start and stop is a smooth ramp.
    A beep's gate closes ``ramp_s`` before the end of its on-time, so the fade-out ends
    there and the cadence is the table's.
    """

    def __init__(self, settings: VarioAudioSettings | None = None) -> None:
        self.settings = settings or VarioAudioSettings()
        self._phase = 0.0  # of the oscillator, radians
        self._beep_t = 0.0  # time into the current beep (or warble) period, s
        self._sample_t = 0.0  # fractional sample carried between calls
        self._level = 0.0  # envelope before shaping, 0..1
        self._hz = self.settings.min_hz  # pitch of a tone fading out

    def render(self, climb_m_s: float | None, duration_s: float) -> np.ndarray:
        """int16 samples for ``duration_s`` at ``climb_m_s`` (None: silence, as in the dead
        band; a sounding tone fades out)."""
        s = self.settings
        exact = duration_s * s.sample_rate_hz + self._sample_t
        n = int(exact)
        self._sample_t = exact - n
        if n <= 0:
            return np.zeros(0, dtype=np.int16)
        dt = 1.0 / s.sample_rate_hz
        t = self._beep_t + dt * np.arange(n)
        hz: float | np.ndarray
        if climb_m_s is not None and climb_m_s >= s.climb_threshold_m_s:
            hz = s.climb_hz(climb_m_s)
            period, on = s.beep(climb_m_s)
            gate = (t % period) < max(on - s.ramp_s, dt)
            self._beep_t = (self._beep_t + n * dt) % period
        elif climb_m_s is not None and s.sink_alarm_m_s is not None and \
                climb_m_s <= s.sink_alarm_m_s:
            low, high = s.sink_alarm_hz
            hz = np.where((t % s.sink_alarm_period_s) < s.sink_alarm_period_s / 2, low, high)
            gate = np.ones(n, dtype=bool)
            self._beep_t = (self._beep_t + n * dt) % s.sink_alarm_period_s
        elif climb_m_s is not None and climb_m_s < s.sink_threshold_m_s:
            hz = s.sink_tone_hz(climb_m_s)
            gate = np.ones(n, dtype=bool)
            self._beep_t = 0.0
        else:
            # Silence: the next climb starts with a fresh beep; a tone still sounding fades
            # out at its own pitch.
            hz = self._hz
            gate = np.zeros(n, dtype=bool)
            self._beep_t = 0.0
        if not gate.any() and self._level == 0.0:
            return np.zeros(n, dtype=np.int16)
        envelope = self._envelope(gate)
        step = 2 * math.pi * dt * (np.broadcast_to(hz, (n,)))
        phase = self._phase + np.concatenate(([0.0], np.cumsum(step[:-1])))
        self._phase = float((phase[-1] + step[-1]) % (2 * math.pi))
        self._hz = float(np.broadcast_to(hz, (n,))[-1])
        shaped = 0.5 - 0.5 * np.cos(math.pi * envelope)
        return (np.sin(phase) * shaped * (s.volume * 32767)).astype(np.int16)

    def _envelope(self, gate: np.ndarray) -> np.ndarray:
        """The level following ``gate`` at the slew rate of one ramp: segment by segment
        (a call holds a few gate changes at most)."""
        ramp_n = max(1, round(self.settings.ramp_s * self.settings.sample_rate_hz))
        out = np.empty(gate.size)
        change = np.nonzero(np.diff(gate.astype(np.int8)))[0] + 1
        bounds = [0, *change.tolist(), gate.size]
        level = self._level
        for a, b in itertools.pairwise(bounds):
            target = 1.0 if gate[a] else 0.0
            k = np.arange(1, b - a + 1) / ramp_n
            seg = np.minimum(level + k, target) if target > level else \
                np.maximum(level - k, target)
            out[a:b] = seg
            level = float(seg[-1])
        self._level = level
        return out


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
        self._damped_m_s = 0.0  # the climb sonified, after the damping low-pass
        self._first_ns: int | None = None
        self._quiet_since_ns: int | None = None  # start of the climb's stay in the dead band
        self.settled_at_ns: int | None = None
        """When the tones came on (None: still silent, the vario settling)."""
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
        if self._last is not None and event.t_ns <= self._last.t_ns:
            return
        if self._last is not None:
            dt_s = (event.t_ns - self._last.t_ns) / 1e9
            heard = self._damped_m_s if self.settled_at_ns is not None else None
            self._emit(self.generator.render(heard, dt_s))
            tau = self.curve.damping_s
            alpha = 1.0 - math.exp(-dt_s / tau) if tau > 0 else 1.0
            self._damped_m_s += alpha * (event.climb_m_s - self._damped_m_s)
        else:
            self._damped_m_s = event.climb_m_s
            self._first_ns = event.t_ns
        self._last = event
        if self.settled_at_ns is None:
            self._settle(event.t_ns)

    def _settle(self, t_ns: int) -> None:
        """Unmute once the climb has stayed in the dead band for ``settle_s`` (the vario
        filter has settled on the ground), or ``settle_max_s`` after the first estimate."""
        c = self.curve
        assert self._first_ns is not None
        if c.sink_threshold_m_s <= self._damped_m_s < c.climb_threshold_m_s:
            if self._quiet_since_ns is None:
                self._quiet_since_ns = t_ns
        else:
            self._quiet_since_ns = None
        quiet = self._quiet_since_ns is not None and \
            t_ns - self._quiet_since_ns >= c.settle_s * 1e9
        if quiet or t_ns - self._first_ns >= c.settle_max_s * 1e9:
            self.settled_at_ns = t_ns

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


def _open_live(sample_rate_hz: int):
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
