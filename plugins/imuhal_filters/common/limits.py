"""What an AHRS refuses to fuse: values no sensor can physically report.

A driver flags what its chip marks as overflow or saturated, but a value can still reach an
estimator that is impossible: a corrupted log row (``1e30`` rad/s in an ``imuhal estimate``
input), a third-party driver that forgot a check, NaN or infinity. One such gyro value
integrated for one step flips the attitude by an arbitrary angle and the error stays to the
end of the run. Every AHRS therefore checks each gyro and accelerometer value against a
configured physical full scale before fusing it, and counts what it rejects.

In a pipeline the limits follow the streams the estimator is fed (``bind``: the chip's
configured full scale read back from its registers, with a 10 % margin for calibration
gains); a limit given by hand below the stream's full scale is an error. Without streams
(the Python API, an offline log) the defaults are the largest full scales of the chips
imuhal drives (2000 deg/s gyro, 16 g accelerometer) with the same margin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.quantities import Quantity
from imuhal.core.streams import StreamSpec
from imuhal.estimation.base import Estimator
from imuhal.estimation.streams import (
    bound_limit,
    bound_period,
    bound_rate,
    stream_of,
    updated,
)

DEFAULT_GYRO_FULL_SCALE_RAD_S = 1.1 * math.radians(2000.0)
DEFAULT_ACCEL_FULL_SCALE_M_S2 = 1.1 * 16.0 * STANDARD_GRAVITY_M_S2


def within_full_scale(vector: tuple[float, ...], full_scale: float | None) -> bool:
    """True when every component is finite and, if ``full_scale`` is set, |c| <= it."""
    for c in vector:
        if not math.isfinite(c):
            return False
        if full_scale is not None and abs(c) > full_scale:
            return False
    return True


def bound_settings(estimator: Estimator, streams: Sequence[StreamSpec], *,
                   period_key: str | None = None, rate_key: str | None = None) -> Any:
    """The estimator's settings with its limits and its period (``period_key``, s) or rate
    (``rate_key``, Hz) taken from the gyro and accelerometer streams it is fed
    (imuhal.estimation.streams: settings not given follow the stream; a given one that
    contradicts it raises StreamContradiction). The same settings object when nothing
    changes."""
    s: Any = estimator.settings
    hand = estimator.given_settings
    gyro = stream_of(streams, Quantity.GYRO)
    accel = stream_of(streams, Quantity.ACCEL)
    changes: dict[str, float | None] = {
        key: bound_limit(key, getattr(s, key), key in hand, spec)
        for key, spec in (("gyro_full_scale_rad_s", gyro), ("accel_full_scale_m_s2", accel))}
    if period_key is not None:
        changes[period_key] = bound_period(period_key, getattr(s, period_key),
                                           period_key in hand, gyro)
    if rate_key is not None:
        changes[rate_key] = bound_rate(rate_key, getattr(s, rate_key), rate_key in hand, gyro)
    return updated(s, changes)
