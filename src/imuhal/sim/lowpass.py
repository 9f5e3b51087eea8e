"""A chip's digital low-pass as an emulator runs it on what the ADC's rail and value faults
change in the input.

The IMU datasheets give their filters' 3 dB bandwidths only (MAX2110x GYRO_CFG1 and
ACC_CFG1, MPU-9250 CONFIG and ACCEL_CONFIG2); the emulators take each as the first-order
low-pass of that bandwidth, sampled at the output rate. The filter is digital: it runs on
the ADC's words, so whatever cuts or replaces a word before it (the ADC's rail on an honest
over-range measurement, a ``wild_value`` at the sensing element) is filtered like anything
else, and the outputs after it carry what is left of it.

The emulators hand out the world they are given without the filter's lag (the bandwidth is
in their noise, docs/simulation.md). The filter is linear, so the chip's output is the
filtered world plus the filtered residual, the residual being the ADC word minus the word
the world would have made without a rail or a fault. The scenarios' motion lies well
inside the filters' passbands (its content is a few hertz at most, against 5 to 41 Hz), where
the filtered world is the world within the chip's stated noise, so only the residual is run
through the filter here: a run whose words never reach the rail and carry no fault is word
for word what it was, and after a clip or a wild word the outputs read off by what the
filter still carries, as on the chip."""

from __future__ import annotations

import math
from collections.abc import Sequence

_NEGLIGIBLE_COUNTS = 0.5
"""Below half a count the carried residual no longer changes a rounded output word."""


class DisturbedLowPass:
    """One channel's (three axes) first-order low-pass, run on the residual of its input."""

    __slots__ = ("_carried", "_t_ns")

    def __init__(self) -> None:
        self._carried: list[float] | None = None
        """Counts the filter output still carries of residuals (None: nothing)."""
        self._t_ns = 0
        """The instant of the output ``_carried`` belongs to."""

    @property
    def active(self) -> bool:
        """The filter still carries a residual."""
        return self._carried is not None

    def reset(self) -> None:
        """The chip's filter restarted (a reset): it carries nothing."""
        self._carried = None

    def output(self, t_ns: int, world: Sequence[int], adc: Sequence[int],
               bandwidth_hz: float, period_s: float, low: int, high: int
               ) -> tuple[int, int, int]:
        """The output words at ``t_ns`` of a channel whose world makes the words ``world``
        (ADC counts before the rail, the error model's noise included) and whose ADC gave
        ``adc`` (cut at the rail, and whatever a value fault put there), for a filter of
        ``bandwidth_hz`` whose output period is ``period_s``; the words lie in
        [``low``, ``high``]."""
        tau_ns = 1e9 / (2.0 * math.pi * bandwidth_hz)
        carried = self._carried
        if carried is None:  # nothing carried: the residual enters for one output period
            carried = [0.0, 0.0, 0.0]
            elapsed_ns = period_s * 1e9
        else:
            elapsed_ns = max(0, t_ns - self._t_ns)
        # the residual held since the previous output (the filter's input between two
        # outputs the emulator latched; none again at the same instant): what was carried
        # keeps exp(-elapsed / tau), the residual takes the rest
        keep = math.exp(-elapsed_ns / tau_ns)
        carried = [keep * c + (1.0 - keep) * (d - u)
                   for c, d, u in zip(carried, adc, world, strict=True)]
        self._t_ns = t_ns
        if max(map(abs, carried)) < _NEGLIGIBLE_COUNTS:
            self._carried = None
            carried = [0.0, 0.0, 0.0]
        else:
            self._carried = carried
        x, y, z = (max(low, min(high, u + round(c))) for u, c in zip(world, carried, strict=True))
        return x, y, z


def world_counts(values: Sequence[float], per_count: float, limit: int) -> tuple[int, int, int]:
    """``values`` (SI) in counts of ``per_count``, rounded, not cut at the rail (a value that
    is not finite, or beyond 64 times the ``limit``, at 64 times the limit of its sign: far
    past the rail, where only the sign matters)."""
    far = 64 * limit
    x, y, z = (round(max(-far, min(far, v / per_count))) if math.isfinite(v)
               else (far if v > 0 else -far) for v in values)
    return x, y, z
