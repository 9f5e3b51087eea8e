"""Accelerometer magnitude gate and the unit change the reference filters expect.

The seed's AHRS and the ESP32 vario firmware trust the accelerometer as a gravity reference only
while ``|a|`` is near 1 g; outside the window they integrate the gyro alone. imuhal carries
specific force in m/s^2; the reference kernels want the accelerometer "gravity positive" (a
level board at rest reads (0, 0, +1) in NED body axes), in g. Both conversions live here so
every AHRS uses the same constant and the same strict comparisons.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from pydantic import AfterValidator, Field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.estimation.base import EstimatorSettings
from imuhal_filters.common.fast_ahrs import accel_gate, soft_gate_distrust
from imuhal_filters.common.quat import IDENTITY, Quat, Vec


def gravity_positive_g(specific_force_m_s2: Vec) -> Vec:
    """Specific force (m/s^2, body NED) -> gravity-positive accelerometer reading (g)."""
    k = -1.0 / STANDARD_GRAVITY_M_S2
    fx, fy, fz = specific_force_m_s2
    return (fx * k, fy * k, fz * k)


def specific_force_m_s2(gravity_positive: Vec) -> Vec:
    """Gravity-positive accelerometer reading (g) -> specific force (m/s^2): the inverse."""
    k = -STANDARD_GRAVITY_M_S2
    ax, ay, az = gravity_positive
    return (ax * k, ay * k, az * k)


def _ordered_bounds(bounds: tuple[float, float]) -> tuple[float, float]:
    if not 0.0 <= bounds[0] < bounds[1]:
        raise ValueError(f"give (lower, upper) in g with 0 <= lower < upper, e.g. (0.6, 1.4); "
                         f"got ({bounds[0]:g}, {bounds[1]:g})")
    return bounds


GateBounds = Annotated[tuple[float, float], AfterValidator(_ordered_bounds)]
"""An ``accel_gate_g`` setting: (lower, upper) in g, checked when the settings are read."""


@dataclass(frozen=True, slots=True)
class AccelGate:
    """Open (accelerometer trusted) while ``lower_g < |a| < upper_g``, strictly, as in the seeds.

    ``AccelGate(0.0, math.inf)`` never closes for a finite, non-zero reading.
    """

    lower_g: float
    upper_g: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.lower_g < self.upper_g):
            raise ValueError(
                f"accelerometer gate needs 0 <= lower < upper, got ({self.lower_g}, {self.upper_g})"
            )

    @classmethod
    def from_bounds(cls, bounds: tuple[float, float] | None) -> AccelGate:
        return cls(0.0, math.inf) if bounds is None else cls(float(bounds[0]), float(bounds[1]))

    def is_open(self, accel_g: Vec) -> bool:
        """True when the magnitude of ``accel_g`` (any sign convention, in g) is in the window
        (the compiled kernels' :func:`~imuhal_filters.common.fast_ahrs.accel_gate`)."""
        return accel_gate(True, *accel_g, *IDENTITY, self.lower_g, self.upper_g, 0.0)[0]

    def gates(self, accel_g: Vec | None, width_g: float | None, q: Quat
              ) -> tuple[bool, float]:
        """This hard gate and the soft gate of ``width_g`` (g; None: none) for one
        gravity-positive reading (g; None: none this step) at attitude ``q`` (body -> NED):
        whether the gate is open (closed without a reading) and the weight of the
        correction (:func:`~imuhal_filters.common.fast_ahrs.accel_gate`: from the
        unmodelled acceleration, the reading minus the gravity ``q`` predicts)."""
        if accel_g is None:
            return False, 1.0
        return accel_gate(True, *accel_g, *q, self.lower_g, self.upper_g,
                          0.0 if width_g is None else width_g)


def soft_gate_weight(accel_g: Vec, width_g: float | None) -> float:
    """How much of its correction an AHRS applies for an accelerometer reading (any sign
    convention, in g, turn-compensated): 1 / (1 + (| |a| - 1 | / width)^2).

    A hard window (``AccelGate``) trusts a reading at 1.39 g fully and one at 1.41 g not at
    all; this weight fades the correction smoothly as the reading departs from 1 g, so a
    launch, a pull-up or hand-held shaking, whose accelerations the turn compensation does not
    know, tilt the filter much less, and the correction is back in full as soon as the board
    moves steadily again. ``width_g`` None: weight 1 always.
    """
    if width_g is None:
        return 1.0
    ax, ay, az = accel_g
    return 1.0 / soft_gate_distrust(math.sqrt(ax ** 2 + ay ** 2 + az ** 2), width_g)


class SoftGateSettings(EstimatorSettings):
    """The soft accelerometer gate of the complementary filters (madgwick, mahony)."""

    accel_soft_gate_g: float | None = Field(0.05, gt=0.0)
    """Fade the accelerometer correction as the (turn-compensated) reading departs from the
    gravity the attitude predicts: weight 1 / (1 + (u / this)^2), u = |a - R(q)^T g| in g,
    the acceleration nothing models (a horizontal push at first order, where |a| would see
    it at second); None: full correction always (the references). 0.05 g chosen on the
    emulated ``thermal`` launch and ``rc-flight`` (docs/estimators.md)."""
