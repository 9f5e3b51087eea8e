"""Sub-LSB dither on an emulator's inputs, standing in for a real chip's own noise.

An ideal emulator held at a constant input repeats one raw frame for ever, which a real
sensor never does and which drivers rightly flag FROZEN. Tests whose subject is not noise
call ``Dither`` before each poll: it re-sets the inputs the test last gave the emulator
(``emulator.physics``), each value moved by just under half an LSB (``emulator.resolution``)
up or down at random. That plus the chip's own rounding keeps every reading within one LSB
of the input, and a value that does not sit exactly on a count changes its raw word between
the two moves (``amplitude`` just over a half also moves values that sit on a count, for
tests whose tolerance is one whole LSB inclusive). Temperatures are left alone by default
(some chips truncate them, and the other channels suffice). Seeded: deterministic.
"""

from __future__ import annotations

import random
from dataclasses import replace

from imuhal.core.samples import Quantity
from imuhal.emulation import ChipEmulator, PhysicalInputs

CHANNEL_OF_FIELD = {
    "specific_force_m_s2": Quantity.ACCEL,
    "angular_rate_rad_s": Quantity.GYRO,
    "magnetic_field_ut": Quantity.MAG,
    "pressure_pa": Quantity.PRESSURE,
    "temperature_degc": Quantity.TEMPERATURE,
}
HALF = 0.5 - 1e-9
"""Just under half an LSB, so a rounded reading stays strictly within one LSB."""
DITHERED = frozenset({Quantity.ACCEL, Quantity.GYRO, Quantity.MAG, Quantity.PRESSURE})


class Dither:
    def __init__(self, emulator: ChipEmulator, *, seed: int = 0,
                 channels: frozenset[Quantity] = DITHERED, amplitude: float = HALF,
                 spread: float = 0.0) -> None:
        self.emulator = emulator
        self.amplitude = amplitude
        """Size of the up-or-down move, in LSB (just under a half by default)."""
        self.spread = spread
        """Each move shrinks by a random fraction up to this (0: every move is exactly
        ``amplitude``). For a chip whose raw word resolves far finer than its output (the
        MS5611's D1, about 0.02 Pa per count under a 1 Pa output), so the word takes many
        values, as under the chip's own noise, not two."""
        self.channels = channels
        self._rng = random.Random(seed)
        self._base: PhysicalInputs = emulator.physics
        self._applied: PhysicalInputs | None = None

    def _step(self, channel: Quantity) -> float | None:
        if channel not in self.channels:
            return None
        try:
            return self.emulator.resolution(channel)
        except (ValueError, NotImplementedError, KeyError, TypeError):
            return None

    def _move(self, lsb: float) -> float:
        size = self.amplitude * (1.0 - self.spread * self._rng.random())
        return self._rng.choice((-size, size)) * lsb

    def __call__(self) -> None:
        """Re-set the inputs, dithered; a test that set new inputs since the last call sets
        the new base."""
        if self.emulator.physics is not self._applied:
            self._base = self.emulator.physics
        changes: dict[str, object] = {}
        # Only the register chips' own inputs; earth-frame position/velocity and plugin
        # quantities are not quantised by these chips.
        for name, channel in CHANNEL_OF_FIELD.items():
            value = getattr(self._base, name)
            lsb = self._step(channel) if value is not None else None
            if value is None or lsb is None:
                continue
            if isinstance(value, tuple):
                changes[name] = tuple(v + self._move(lsb) for v in value)
            else:
                changes[name] = value + self._move(lsb)
        self._applied = replace(self._base, **changes)  # type: ignore[arg-type]
        self.emulator.set_physics(self._applied)
