"""What an AHRS refuses to fuse: values no sensor can physically report.

A driver flags what its chip marks as overflow or saturated, but a value can still reach an
estimator that is impossible: a corrupted log row (``1e30`` rad/s in an ``imuhal estimate``
input), a third-party driver that forgot a check, NaN or infinity. One such gyro value
integrated for one step flips the attitude by an arbitrary angle and the error stays to the
end of the run. Every AHRS therefore checks each gyro and accelerometer value against a
configured physical full scale before fusing it, and counts what it rejects.

The defaults are the largest full scales of the chips imuhal drives (2000 deg/s gyro, 16 g
accelerometer) with a 10 % margin for calibration gains; set the board's own ranges to be
stricter.
"""

from __future__ import annotations

import math

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2

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
