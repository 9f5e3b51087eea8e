"""Sensor error models: what turns true physical values into what a real chip measures.

Everything here works in the chip's own sensor frame and in SI units (the unit of the
quantity: m/s^2 for accelerometers, rad/s for gyroscopes, uT for magnetometers, Pa, degC).

Vector sensors (per axis, ``true`` the true vector, ``T`` the chip temperature)::

    raw = W @ (I + C) @ diag(1 + s) @ true        # W soft iron (mag only), C cross-axis, s scale
          + h                                     # hard iron (mag only)
          + b + b_T * (T - T_ref) + b_rw(t)       # constant, thermal and random-walk bias
          + n                                     # white noise

* ``noise_density`` is the datasheet's noise spectral density (unit/sqrt(Hz)); each sample
  gets Gaussian noise of std ``noise_density * sqrt(bandwidth_hz)`` with the bandwidth
  defaulting to the Nyquist band ``1 / (2 * sample_period_s)`` (set ``bandwidth_hz`` to the
  chip's low-pass filter bandwidth when it has one; e.g. 0.01 dps/sqrt(Hz) in 92 Hz gives the
  MPU-9250's 0.1 dps RMS). ``sample_period_s`` is the chip's own output period: the
  emulated board takes it from the emulator's configuration
  (:meth:`~imuhal.sim.chip.ChipEmulator.noise_period_s`), not from the host's poll interval.
* ``noise_std`` is a per-sample std for chips specified by RMS noise at their output rate.
* ``bias_random_walk`` (unit/sqrt(s), i.e. unit/s/sqrt(Hz)): the bias performs a Wiener
  process, std ``bias_random_walk * sqrt(t)`` after t seconds.
* ``*_std`` fields draw a per-device value from the seed (turn-on bias, scale factor,
  cross-axis), the way each part off the reel differs from the datasheet's typical one.

Calibration (design.md section 6) inverts this: corrected = M diag(s) (raw - b) for inertial
sensors, corrected = S (raw - h) for magnetometers, so S = W^-1.

Scalar sensors: ``raw = true + bias + drift * t + walk(t) + temp_coeff * (T - T_ref) + n``
with ``noise_std`` per sample (barometers specify RMS noise per oversampling setting).

A :class:`SensorErrorModel` is seeded and reproducible: the same seed and the same sequence
of ``apply`` calls give the same output. Each channel draws from its own stream, so
enabling the magnetometer does not change the gyro noise.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from imuhal.sim.inputs import PhysicalInputs

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]

_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_ZERO33: Mat3 = (_ZERO3, _ZERO3, _ZERO3)
_IDENTITY: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class VectorErrorSpec(_Spec):
    """Errors of a 3-axis sensor, in its SI unit (see the module docstring)."""

    noise_density: float = Field(0.0, ge=0)
    """White noise spectral density, unit/sqrt(Hz)."""
    noise_std: float = Field(0.0, ge=0)
    """White noise std per sample, whatever the rate (for chips specified by RMS noise);
    added in quadrature to the density's share."""
    bandwidth_hz: float | None = Field(None, gt=0)
    """Noise bandwidth; None: the Nyquist band of the sample period."""
    bias: Vec3 = _ZERO3
    """Constant bias (unit)."""
    bias_std: float = Field(0.0, ge=0)
    """Std of a per-device turn-on bias drawn from the seed, per axis (unit)."""
    bias_random_walk: float = Field(0.0, ge=0)
    """Bias random walk, unit/sqrt(s)."""
    bias_temp_coeff: Vec3 = _ZERO3
    """Bias change per degC away from ``reference_temperature_degc`` (unit/degC)."""
    scale_factor_error: Vec3 = _ZERO3
    """Per-axis scale error as a fraction (0.01 = reads 1 % high)."""
    scale_factor_std: float = Field(0.0, ge=0)
    """Std of a per-device scale error drawn from the seed (fraction)."""
    cross_axis: Mat3 = _ZERO33
    """Misalignment / cross-axis sensitivity C (fractions); the diagonal must be zero."""
    cross_axis_std: float = Field(0.0, ge=0)
    """Std of per-device off-diagonal cross-axis terms drawn from the seed (fraction)."""
    reference_temperature_degc: float = 25.0

    @model_validator(mode="after")
    def _diagonal_free(self) -> VectorErrorSpec:
        if any(self.cross_axis[i][i] != 0.0 for i in range(3)):
            raise ValueError("cross_axis must have a zero diagonal: per-axis gain errors "
                             "belong in scale_factor_error")
        return self


class MagErrorSpec(VectorErrorSpec):
    """A magnetometer's errors: the sensor's own, plus the board's hard and soft iron."""

    hard_iron_ut: Vec3 = _ZERO3
    """Field of magnetised parts on the board, in the sensor frame (uT)."""
    soft_iron: Mat3 = _IDENTITY
    """W: how soft iron near the sensor distorts the field (identity: none)."""

    @model_validator(mode="after")
    def _invertible(self) -> MagErrorSpec:
        if abs(float(np.linalg.det(np.asarray(self.soft_iron)))) < 1e-6:
            raise ValueError("soft_iron must be invertible (calibration applies its inverse)")
        return self


class ScalarErrorSpec(_Spec):
    """Errors of a scalar sensor (pressure in Pa, temperature in degC)."""

    noise_std: float = Field(0.0, ge=0)
    """White noise std per sample (unit)."""
    bias: float = 0.0
    bias_std: float = Field(0.0, ge=0)
    drift_per_hour: float = 0.0
    """Linear drift (unit/hour)."""
    random_walk: float = Field(0.0, ge=0)
    """unit/sqrt(s)."""
    temp_coeff: float = 0.0
    """Change per degC away from ``reference_temperature_degc`` (unit/degC)."""
    reference_temperature_degc: float = 25.0


class SensorErrorSpec(_Spec):
    """Errors of every channel a chip has; None: that channel is passed through unchanged."""

    accel: VectorErrorSpec | None = None
    gyro: VectorErrorSpec | None = None
    mag: MagErrorSpec | None = None
    pressure: ScalarErrorSpec | None = None
    temperature: ScalarErrorSpec | None = None


class _Normals:
    """Standard normal draws from one seeded stream, fetched in blocks (cheap per call)."""

    __slots__ = ("_buf", "_i", "_rng")

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buf: list[float] = []
        self._i = 0

    def __call__(self) -> float:
        if self._i >= len(self._buf):
            self._buf = self._rng.standard_normal(1024).tolist()
            self._i = 0
        x = self._buf[self._i]
        self._i += 1
        return x

    def peek(self, count: int) -> list[float]:
        """The next ``count`` draws without consuming them (:meth:`skip` does): the buffer
        grows by whole blocks from the generator, so the draws and their order stay those
        of one call after another."""
        need = self._i + count
        if need > len(self._buf):
            fresh = self._rng.standard_normal(1024 * -(-(need - len(self._buf)) // 1024))
            self._buf = self._buf[self._i:] + fresh.tolist()
            self._i = 0
        return self._buf[self._i:self._i + count]

    def skip(self, count: int) -> None:
        """Consume ``count`` draws :meth:`peek` returned."""
        self._i += count

    def three(self) -> tuple[float, float, float]:
        """The next three draws, as three calls would return them (one call per vector
        sample instead of three)."""
        i = self._i
        if i + 3 > len(self._buf):
            return self(), self(), self()
        self._i = i + 3
        b = self._buf
        return b[i], b[i + 1], b[i + 2]


class _VectorChannel:
    def __init__(self, spec: VectorErrorSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        # Per-device draws first, in a fixed order, so they depend only on the seed.
        s = np.asarray(spec.scale_factor_error) + rng.normal(0.0, 1.0, 3) * spec.scale_factor_std
        c = np.asarray(spec.cross_axis, dtype=float)
        c = c + (rng.normal(0.0, 1.0, (3, 3)) * spec.cross_axis_std) * (1.0 - np.eye(3))
        b = np.asarray(spec.bias) + rng.normal(0.0, 1.0, 3) * spec.bias_std
        k = (np.eye(3) + c) @ np.diag(1.0 + s)
        offset = np.zeros(3)
        if isinstance(spec, MagErrorSpec):
            k = np.asarray(spec.soft_iron, dtype=float) @ k
            offset = np.asarray(spec.hard_iron_ut, dtype=float)
        self.gain: tuple[float, ...] = tuple(float(x) for x in k.ravel())
        self.offset = (float(offset[0]), float(offset[1]), float(offset[2]))
        self.turn_on_bias = (float(b[0]), float(b[1]), float(b[2]))
        self.walk = [0.0, 0.0, 0.0]
        self.normal = _Normals(rng)
        # Spec figures read at every sample, copied out of the (slower to read) model once.
        self._t_ref = spec.reference_temperature_degc
        self._temp_coeff = spec.bias_temp_coeff
        self._random_walk = spec.bias_random_walk
        self._density_sq = spec.noise_density * spec.noise_density
        self._std_sq = spec.noise_std * spec.noise_std
        self._sigma_period = math.nan  # the period ``_sigma`` was worked out for (none yet)
        self._sigma = 0.0

    def bias_at(self, temperature: float | None) -> Vec3:
        """The total bias (constant + thermal + random walk) now."""
        b = self.turn_on_bias
        dt = 0.0 if temperature is None else temperature - self._t_ref
        tc = self._temp_coeff
        return (b[0] + tc[0] * dt + self.walk[0], b[1] + tc[1] * dt + self.walk[1],
                b[2] + tc[2] * dt + self.walk[2])

    def step(self, elapsed_s: float) -> None:
        rw = self._random_walk
        if rw and elapsed_s > 0:
            k = rw * math.sqrt(elapsed_s)
            nx, ny, nz = self.normal.three()
            self.walk[0] += k * nx
            self.walk[1] += k * ny
            self.walk[2] += k * nz

    def noise_sigma(self, period_s: float) -> float:
        sp = self.spec
        if not sp.noise_density:
            return sp.noise_std
        bw = sp.bandwidth_hz or 0.5 / period_s
        return math.sqrt(self._density_sq * bw + self._std_sq)

    def apply(self, v: Vec3, temperature: float | None, period_s: float) -> Vec3:
        g = self.gain
        x, y, z = v
        # bias_at and noise_sigma written out (the same operations): this runs for every
        # vector channel at every poll.
        b = self.turn_on_bias
        dt = 0.0 if temperature is None else temperature - self._t_ref
        tc = self._temp_coeff
        w = self.walk
        ox, oy, oz = self.offset
        mx = g[0] * x + g[1] * y + g[2] * z + ox + (b[0] + tc[0] * dt + w[0])
        my = g[3] * x + g[4] * y + g[5] * z + oy + (b[1] + tc[1] * dt + w[1])
        mz = g[6] * x + g[7] * y + g[8] * z + oz + (b[2] + tc[2] * dt + w[2])
        if period_s != self._sigma_period:  # the period rarely changes: sigma kept for it
            self._sigma = self.noise_sigma(period_s)
            self._sigma_period = period_s
        sigma = self._sigma
        if sigma:
            nx, ny, nz = self.normal.three()
            return (mx + sigma * nx, my + sigma * ny, mz + sigma * nz)
        return (mx, my, mz)


    def plan(self, elapsed: np.ndarray, xyz: np.ndarray, temperature: np.ndarray | None,
             period_s: float) -> _ChannelPlan:
        """:meth:`step` then :meth:`apply` at each of n calls (``elapsed``: the time each
        call's walk moves by; ``xyz`` the true vectors, (n, 3); ``temperature`` the true
        temperatures or None), by the same operations in the same order on arrays and on
        the same draws of this channel's stream, without changing the channel: the
        measured vectors (n, 3) and what :meth:`_ChannelPlan.commit` sets after m calls."""
        n = len(elapsed)
        rw = self._random_walk
        steps = (elapsed > 0) if rw else np.zeros(n, dtype=bool)
        sigma = self.noise_sigma(period_s) if period_s != self._sigma_period else self._sigma
        draws = 3 * steps.astype(np.int64) + (3 if sigma else 0)
        ends = np.cumsum(draws)
        d = np.asarray(self.normal.peek(int(ends[-1]) if n else 0), dtype=float)
        starts = ends - draws
        increments = np.zeros((n, 3))
        if rw and steps.any():
            k = rw * np.sqrt(elapsed[steps])
            at = starts[steps][:, None] + np.arange(3)
            increments[steps] = k[:, None] * d[at]
        walks = np.add.accumulate(np.vstack([np.asarray(self.walk, dtype=float)[None, :],
                                             increments]), axis=0)[1:]
        g = self.gain
        x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        b = self.turn_on_bias
        dt = 0.0 if temperature is None else temperature - self._t_ref
        tc = self._temp_coeff
        ox, oy, oz = self.offset
        out = np.empty((n, 3))
        out[:, 0] = g[0] * x + g[1] * y + g[2] * z + ox + (b[0] + tc[0] * dt + walks[:, 0])
        out[:, 1] = g[3] * x + g[4] * y + g[5] * z + oy + (b[1] + tc[1] * dt + walks[:, 1])
        out[:, 2] = g[6] * x + g[7] * y + g[8] * z + oz + (b[2] + tc[2] * dt + walks[:, 2])
        if sigma:
            noise = d[(ends - 3)[:, None] + np.arange(3)]
            out = out + sigma * noise
        return _ChannelPlan(self, out, ends, walks, (period_s, sigma))

    def commit(self, draws: int, walk: list[float], sigma: tuple[float, float]) -> None:
        self.normal.skip(draws)
        self.walk = walk
        self._sigma_period, self._sigma = sigma


class _ChannelPlan:
    """One channel's share of a :class:`ErrorPlan`."""

    __slots__ = ("channel", "ends", "out", "sigma", "walks")

    def __init__(self, channel: _VectorChannel | _ScalarChannel, out: np.ndarray,
                 ends: np.ndarray, walks: np.ndarray, sigma: tuple[float, float]) -> None:
        self.channel = channel
        self.out = out
        self.ends = ends
        """The draws of the channel's stream used by the first 1, 2, ... calls."""
        self.walks = walks
        """The channel's random walk after each call."""
        self.sigma = sigma

    def commit(self, m: int) -> None:
        """Leave the channel as the first ``m`` calls (m >= 1) would have."""
        # a vector channel's walk comes back as a list, a scalar one's as a float
        self.channel.commit(int(self.ends[m - 1]), self.walks[m - 1].tolist(), self.sigma)


class _ScalarChannel:
    def __init__(self, spec: ScalarErrorSpec, rng: np.random.Generator) -> None:
        self.spec = spec
        self.turn_on_bias = spec.bias + float(rng.normal()) * spec.bias_std
        self.walk = 0.0
        self.normal = _Normals(rng)
        # Spec figures read at every sample, copied out of the model once.
        self._t_ref = spec.reference_temperature_degc
        self._drift_per_hour = spec.drift_per_hour
        self._temp_coeff = spec.temp_coeff
        self._random_walk = spec.random_walk
        self._noise_std = spec.noise_std

    def bias_at(self, t_s: float, temperature: float | None) -> float:
        dt = 0.0 if temperature is None else temperature - self._t_ref
        return (self.turn_on_bias + self._drift_per_hour * t_s / 3600.0 + self.walk
                + self._temp_coeff * dt)

    def step(self, elapsed_s: float) -> None:
        if self._random_walk and elapsed_s > 0:
            self.walk += self._random_walk * math.sqrt(elapsed_s) * self.normal()

    def apply(self, t_s: float, v: float, temperature: float | None) -> float:
        return self.finish(t_s, v, temperature, *self.draw())

    def draw(self) -> tuple[float, float]:
        """What :meth:`apply` takes from the channel's state at a call: (the random walk,
        the noise draw or 0.0 where the channel has no noise)."""
        return self.walk, self.normal() if self._noise_std else 0.0

    def finish(self, t_s: float, v: float, temperature: float | None, walk: float,
               noise: float) -> float:
        """:meth:`apply` on what :meth:`draw` took (the same operations)."""
        dt = 0.0 if temperature is None else temperature - self._t_ref
        out = v + (self.turn_on_bias + self._drift_per_hour * t_s / 3600.0 + walk
                   + self._temp_coeff * dt)
        if self._noise_std:
            out += self._noise_std * noise
        return out

    def plan(self, t_s: np.ndarray, elapsed: np.ndarray, v: np.ndarray,
             temperature: np.ndarray | None) -> _ChannelPlan:
        """:meth:`step` then :meth:`apply` at each of n calls, on arrays (see
        :meth:`_VectorChannel.plan`)."""
        n = len(t_s)
        rw = self._random_walk
        steps = (elapsed > 0) if rw else np.zeros(n, dtype=bool)
        noisy = 1 if self._noise_std else 0
        draws = steps.astype(np.int64) + noisy
        ends = np.cumsum(draws)
        d = np.asarray(self.normal.peek(int(ends[-1]) if n else 0), dtype=float)
        increments = np.zeros(n)
        if rw and steps.any():
            increments[steps] = rw * np.sqrt(elapsed[steps]) * d[(ends - draws)[steps]]
        walks = np.add.accumulate(np.concatenate([[self.walk], increments]))[1:]
        dt = 0.0 if temperature is None else temperature - self._t_ref
        out = v + (self.turn_on_bias + self._drift_per_hour * t_s / 3600.0 + walks
                   + self._temp_coeff * dt)
        if noisy:
            out = out + self._noise_std * d[ends - 1]
        return _ChannelPlan(self, out, ends, walks, (0.0, 0.0))

    def commit(self, draws: int, walk: float, sigma: tuple[float, float]) -> None:
        self.normal.skip(draws)
        self.walk = walk


_CHANNELS = ("accel", "gyro", "mag", "pressure", "temperature")


class SensorErrorModel:
    """Applies a :class:`SensorErrorSpec` to the true inputs of one chip, reproducibly.

    ``apply`` must be called with non-decreasing times; random walks advance by the time
    elapsed since the previous call (the first call is their start).
    """

    def __init__(self, spec: SensorErrorSpec | dict[str, Any], seed: int = 0) -> None:
        self.spec = spec if isinstance(spec, SensorErrorSpec) else \
            SensorErrorSpec.model_validate(spec)
        self.seed = seed
        streams = np.random.SeedSequence(int(seed)).spawn(len(_CHANNELS))
        rngs = dict(zip(_CHANNELS, (np.random.default_rng(s) for s in streams), strict=True))
        sp = self.spec
        self._accel = None if sp.accel is None else _VectorChannel(sp.accel, rngs["accel"])
        self._gyro = None if sp.gyro is None else _VectorChannel(sp.gyro, rngs["gyro"])
        self._mag = None if sp.mag is None else _VectorChannel(sp.mag, rngs["mag"])
        self._pressure = None if sp.pressure is None else \
            _ScalarChannel(sp.pressure, rngs["pressure"])
        self._temperature = None if sp.temperature is None else \
            _ScalarChannel(sp.temperature, rngs["temperature"])
        self._channels = tuple(ch for ch in (self._accel, self._gyro, self._mag,
                                             self._pressure, self._temperature)
                               if ch is not None)
        # Only channels with a random walk draw anything when time moves on.
        self._walking = tuple(ch for ch in self._channels if ch._random_walk)
        self._last_t: float | None = None
        self.period_channels: tuple[str, ...] = tuple(
            name for name in ("accel", "gyro", "mag")
            if (ch_spec := getattr(sp, name)) is not None and ch_spec.noise_density
            and ch_spec.bandwidth_hz is None)
        """The vector channels whose noise depends on the sample period (a density without
        a fixed ``bandwidth_hz``): the ones ``apply_values``' ``periods_s`` matters for."""
        self.scalar_only = self._accel is None and self._gyro is None and self._mag is None
        """True for a model of pressure and temperature alone (:meth:`apply_later`)."""
        self._plan: ErrorPlan | None = None
        """The calls planned ahead (:meth:`plan_values`), of which ``used`` are taken."""

    def apply(self, t_s: float, inputs: PhysicalInputs, sample_period_s: float) -> PhysicalInputs:
        """Measured values for true ``inputs`` sampled at ``t_s`` every ``sample_period_s``."""
        accel, gyro, mag, pressure, measured_temp = self.apply_values(
            t_s, inputs.specific_force_m_s2, inputs.angular_rate_rad_s,
            inputs.magnetic_field_ut, inputs.pressure_pa, inputs.temperature_degc,
            sample_period_s)
        # Built directly rather than with dataclasses.replace, which costs more than all the
        # arithmetic above (this runs for every chip at every poll).
        return PhysicalInputs(specific_force_m_s2=accel, angular_rate_rad_s=gyro,
                              magnetic_field_ut=mag, pressure_pa=pressure,
                              temperature_degc=measured_temp,
                              position_ned_m=inputs.position_ned_m,
                              velocity_ned_m_s=inputs.velocity_ned_m_s, other=inputs.other)

    def apply_values(self, t_s: float, accel: Vec3 | None, gyro: Vec3 | None,
                     mag: Vec3 | None, pressure: float | None, temp: float | None,
                     sample_period_s: float, periods_s: dict[str, float] | None = None,
                     ) -> tuple[Vec3 | None, Vec3 | None, Vec3 | None, float | None,
                                float | None]:
        """:meth:`apply` on the values themselves (sensor frame, SI; None: not simulated):
        the measured (accel, gyro, mag, pressure, temperature). ``periods_s``: a channel's
        own sample period (s) by name ("accel", "gyro", "mag") where it differs from
        ``sample_period_s``. The emulated board calls this and builds the chip's inputs
        once."""
        if self._plan is not None:
            self._sync()
        accel_p, gyro_p, mag_p = self._periods(sample_period_s, periods_s)
        self._move_to(t_s)
        measured_temp = temp  # ``temp`` stays the true one: thermal bias terms depend on it
        if self._accel is not None and accel is not None:
            accel = self._accel.apply(accel, temp, accel_p)
        if self._gyro is not None and gyro is not None:
            gyro = self._gyro.apply(gyro, temp, gyro_p)
        if self._mag is not None and mag is not None:
            mag = self._mag.apply(mag, temp, mag_p)
        if self._pressure is not None and pressure is not None:
            pressure = self._pressure.apply(t_s, pressure, temp)
        if self._temperature is not None and temp is not None:
            measured_temp = self._temperature.apply(t_s, temp, None)
        return accel, gyro, mag, pressure, measured_temp

    def _move_to(self, t_s: float) -> None:
        """A call at ``t_s``: time moves on (never back), the random walks with it."""
        if self._last_t is not None and t_s < self._last_t:
            raise ValueError(f"time went backwards: {t_s} s after {self._last_t} s")
        elapsed = 0.0 if self._last_t is None else t_s - self._last_t
        self._last_t = t_s
        for ch in self._walking:
            ch.step(elapsed)

    @staticmethod
    def _periods(sample_period_s: float, periods_s: dict[str, float] | None
                 ) -> tuple[float, float, float]:
        """The (accel, gyro, mag) sample periods of a call, checked."""
        if sample_period_s <= 0:
            raise ValueError(f"sample_period_s must be positive, got {sample_period_s}")
        accel_p = gyro_p = mag_p = sample_period_s
        if periods_s:
            for name, p in periods_s.items():
                if name not in ("accel", "gyro", "mag"):
                    raise ValueError(f"periods_s: unknown vector channel {name!r} "
                                     "(known: accel, gyro, mag)")
                if not p > 0:
                    raise ValueError(f"periods_s[{name!r}] must be positive, got {p}")
            accel_p = periods_s.get("accel", accel_p)
            gyro_p = periods_s.get("gyro", gyro_p)
            mag_p = periods_s.get("mag", mag_p)
        return accel_p, gyro_p, mag_p

    def plan_values(self, t_s: np.ndarray, accel: np.ndarray | None, gyro: np.ndarray | None,
                    mag: np.ndarray | None, pressure: np.ndarray | None,
                    temp: np.ndarray | None, sample_period_s: float,
                    periods_s: dict[str, float] | None = None) -> ErrorPlan | None:
        """:meth:`apply_values` at each of n coming calls, all in one numpy pass: ``t_s``
        (n,) non-decreasing times, vectors (n, 3) and scalars (n,) as arrays (None: not
        simulated), every call with the same periods. The same floats as the n calls one
        after another (the same operations in the same order, the same draws of each
        channel's stream), and nothing changes until calls are taken: the caller takes
        the first m of them by setting ``ErrorPlan.used`` to m, and the model then stands
        as after those m calls. Any other use of the model (``apply_values``, ``bias``, a
        new plan) first settles what was taken and drops the rest. None where the calls
        cannot be planned (no times, time going backwards, a channel with nothing to
        measure)."""
        self._sync()
        n = len(t_s)
        accel_p, gyro_p, mag_p = self._periods(sample_period_s, periods_s)
        given = {id(self._accel): accel, id(self._gyro): gyro, id(self._mag): mag,
                 id(self._pressure): pressure, id(self._temperature): temp}
        if (not n or any(given[id(ch)] is None for ch in self._channels)
                or (self._last_t is not None and float(t_s[0]) < self._last_t)
                or bool(np.any(np.diff(t_s) < 0))):
            return None
        first = t_s[0] if self._last_t is None else self._last_t
        elapsed = t_s - np.concatenate([[first], t_s[:-1]])
        plans: list[_ChannelPlan] = []
        out: list[np.ndarray | None] = [accel, gyro, mag, pressure, temp]
        for k, (ch, period) in enumerate(((self._accel, accel_p), (self._gyro, gyro_p),
                                          (self._mag, mag_p))):
            if ch is not None:
                plan = ch.plan(elapsed, out[k], temp, period)  # type: ignore[arg-type]  # checked above: a modelled channel has its input
                plans.append(plan)
                out[k] = plan.out
        if self._pressure is not None:
            plans.append(self._pressure.plan(t_s, elapsed, pressure, temp))  # type: ignore[arg-type]  # checked above
            out[3] = plans[-1].out
        if self._temperature is not None:
            plans.append(self._temperature.plan(t_s, elapsed, temp, None))  # type: ignore[arg-type]  # checked above
            out[4] = plans[-1].out
        self._plan = ErrorPlan(t_s, out, plans)
        return self._plan

    def apply_later(self, t_s: float) -> Callable[[float, float], tuple[float, float]] | None:
        """:meth:`apply_values` for a chip measuring pressure and temperature only, in two
        halves: this call moves the model on as the call would (time, random walks, noise
        draws), the function returned gives the measured (pressure, temperature) for the
        true ones, the same floats as the call, whenever it is called. None for a model
        with a vector channel (whose draws depend on which vectors a truth carries)."""
        if not self.scalar_only:
            return None
        self._sync()
        self._move_to(t_s)
        pressure_ch, temperature_ch = self._pressure, self._temperature
        p_draw = None if pressure_ch is None else pressure_ch.draw()
        t_draw = None if temperature_ch is None else temperature_ch.draw()

        def finish(pressure: float, temp: float) -> tuple[float, float]:
            measured_p = pressure if pressure_ch is None or p_draw is None else \
                pressure_ch.finish(t_s, pressure, temp, *p_draw)
            measured_t = temp if temperature_ch is None or t_draw is None else \
                temperature_ch.finish(t_s, temp, None, *t_draw)
            return measured_p, measured_t
        return finish

    def _sync(self) -> None:
        """Settle the calls taken from the plan (if any) and drop the rest of it."""
        plan = self._plan
        if plan is None:
            return
        self._plan = None
        m = plan.used
        if m:
            for channel in plan.channels:
                channel.commit(m)
            self._last_t = float(plan.t_s[m - 1])

    # ------------------------------------------------------------------ truth of the errors
    def bias(self, channel: str, temperature_degc: float | None = None,
             t_s: float | None = None) -> Vec3 | float | None:
        """The current total bias of ``channel`` (for checking estimators' bias estimates);
        hard iron is not included (see ``hard_iron``). None: channel not modelled."""
        self._sync()
        ch = getattr(self, f"_{channel}", None) if channel in _CHANNELS else None
        if ch is None:
            if channel not in _CHANNELS:
                raise ValueError(f"unknown channel {channel!r} (known: {', '.join(_CHANNELS)})")
            return None
        if isinstance(ch, _ScalarChannel):
            return ch.bias_at(t_s if t_s is not None else (self._last_t or 0.0), temperature_degc)
        return ch.bias_at(temperature_degc)


class ErrorPlan:
    """The measured values of n planned calls (:meth:`SensorErrorModel.plan_values`):
    ``values`` (accel, gyro, mag, pressure, temperature) as arrays, each None where not
    simulated, row i the i-th call's. ``used``: how many of the calls were taken."""

    __slots__ = ("channels", "t_s", "used", "values")

    def __init__(self, t_s: np.ndarray, values: list[np.ndarray | None],
                 channels: list[_ChannelPlan]) -> None:
        self.t_s = t_s
        self.values = values
        self.channels = channels
        self.used = 0


def error_spec_of(emulator: type[Any], **overrides: Any) -> SensorErrorSpec | None:
    """The error spec a chip emulator declares (``error_spec``: its datasheet figures, kept
    with the chip's plugin), with any top-level channel replaced by ``overrides``
    (e.g. ``mag=None``). None when the emulator declares none (an ideal chip)."""
    spec = getattr(emulator, "error_spec", None)
    if spec is None:
        return None
    if isinstance(spec, SensorErrorSpec):
        if not overrides:
            return spec
        spec = spec.model_dump()
    return SensorErrorSpec.model_validate({**spec, **overrides})


_NOISE_FIELDS = ("noise_density", "noise_std", "bandwidth_hz")


def noise_only(spec: SensorErrorSpec | None) -> SensorErrorSpec | None:
    """``spec`` with its noise kept and every other error (bias, drift, scale, cross-axis,
    iron, temperature coefficients) off: an "ideal" chip that still converts like a real
    one. A noiseless chip at rest repeats one raw frame for ever, which drivers rightly
    flag FROZEN, so an emulated calibration without errors keeps the noise."""
    if spec is None:
        return None
    channels: dict[str, Any] = {}
    for name in type(spec).model_fields:
        sub = getattr(spec, name)
        if sub is not None:
            kept = {k: getattr(sub, k) for k in _NOISE_FIELDS if k in type(sub).model_fields}
            channels[name] = type(sub)(**kept)
    return SensorErrorSpec(**channels)


def device_seed(seed: int, device: str) -> int:
    """A per-device seed derived from a run seed, stable across runs and Python versions."""
    return int(np.random.SeedSequence([int(seed), zlib.crc32(device.encode())])
               .generate_state(1)[0])
