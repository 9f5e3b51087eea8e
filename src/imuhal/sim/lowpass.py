"""A chip's digital low-pass as an emulator runs it on what a value fault adds to the input.

The IMU datasheets give their filters' 3 dB bandwidths only (MAX2110x GYRO_CFG1 and
ACC_CFG1, MPU-9250 CONFIG and ACCEL_CONFIG2); the emulators take each as the first-order
low-pass of that bandwidth, sampled at the output rate. The filter is digital, so it runs on
the ADC's words: a measurement beyond the range reaches it cut at the rail.

The emulators hand out the world they are given without the filter's lag (the bandwidth is
in their noise, docs/simulation.md), so a fault-free run's words are what they were. What a
value fault (``wild_value``, at the sensing element) changes in the ADC's word is a
disturbance the filter is linear in: this runs it through the filter, and the chip's output
is the undisturbed word plus what the filter still carries of it (the outputs after the
fault see it fade, as on the chip)."""

from __future__ import annotations

import math
from collections.abc import Sequence

_NEGLIGIBLE_COUNTS = 0.5
"""Below half a count the carried disturbance no longer changes a rounded output word."""


class DisturbedLowPass:
    """One channel's (three axes) first-order low-pass, run on a disturbance of its input."""

    __slots__ = ("_carried", "_t_ns")

    def __init__(self) -> None:
        self._carried: list[float] | None = None
        """Counts the filter output still carries of disturbances (None: nothing)."""
        self._t_ns = 0
        """The instant of the output ``_carried`` belongs to."""

    @property
    def active(self) -> bool:
        """The filter still carries a disturbance."""
        return self._carried is not None

    def reset(self) -> None:
        """The chip's filter restarted (a reset): it carries nothing."""
        self._carried = None

    def output(self, t_ns: int, undisturbed: Sequence[int], disturbed: Sequence[int] | None,
               bandwidth_hz: float, period_s: float, rail: int) -> tuple[int, int, int]:
        """The output words at ``t_ns`` of an input that, without the fault, would have
        been ``undisturbed`` (ADC counts, the filter's own output on the world) and is
        ``disturbed`` (None: the input is undisturbed), for a filter of ``bandwidth_hz``
        whose output period is ``period_s``; clipped at +/-``rail``."""
        tau_ns = 1e9 / (2.0 * math.pi * bandwidth_hz)
        carried = self._carried
        if carried is None:
            carried = [0.0, 0.0, 0.0]
        else:  # what it carried fades from the previous output to this one
            fade = math.exp(-max(0, t_ns - self._t_ns) / tau_ns)
            carried = [c * fade for c in carried]
        if disturbed is not None:  # the input held for an output period enters by 1 - a
            enters = 1.0 - math.exp(-period_s * 1e9 / tau_ns)
            carried = [c + enters * (d - u)
                       for c, d, u in zip(carried, disturbed, undisturbed, strict=True)]
        self._t_ns = t_ns
        if max(map(abs, carried)) < _NEGLIGIBLE_COUNTS:
            self._carried = None
            return (undisturbed[0], undisturbed[1], undisturbed[2])
        self._carried = carried
        x, y, z = (max(-rail, min(rail, round(u + c)))
                   for u, c in zip(undisturbed, carried, strict=True))
        return x, y, z
