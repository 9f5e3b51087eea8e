"""Rest detection for the Freescale Kalman filters: the common detector, tick by tick.

The detector is ``common/rest.py``'s (VQF's rule, as madgwick, mahony and imufilter use it),
stepped once per fast gyro tick with the newest accelerometer reading. The Kalman filter
runs once per window of ``oversample_ratio`` ticks; a window is at rest when the detector
said so at every one of its ticks (a rest that begins or ends inside a window leaves that
window out). What the filter does with a window at rest is ``kalman.FreescaleKalman.step``'s
(``at_rest``): no accelerometer gates, and the window's mean gyro reading fused as a
measurement of the gyro offset.

The detector sees rates in rad/s and the accelerometer in g; its tests are a vector norm and
a per-axis bound, so a coordinate system's permuted, sign-flipped axes give the same
verdicts as body NED.
"""

from __future__ import annotations

import math

from imuhal_filters.common.fast_ahrs import rest_update
from imuhal_filters.common.quat import Vec
from imuhal_filters.common.rest import REST_BIAS, REST_START, RestSettings, rest_params


class WindowRest:
    """The rest detector's state and the verdict of the window being filled."""

    def __init__(self, settings: RestSettings) -> None:
        self._params = rest_params(settings)
        self.on = self._params[0] == 1.0
        self.state: tuple[float, ...] = REST_START
        self.at_rest = False
        """The detector's verdict at the last tick."""
        self.window_at_rest = self.on
        """Every tick of the window so far at rest (no tick yet counts as at rest)."""

    def tick(self, gyro_rad_s: Vec, accel_g: Vec | None, dt_s: float) -> None:
        """One fast tick: the gyro reading (rad/s, as measured) and the newest accelerometer
        reading (g; None: none fresh, which breaks the stillness) over ``dt_s``."""
        have_a = accel_g is not None
        ax, ay, az = accel_g if accel_g is not None else (0.0, 0.0, 0.0)
        self.state, self.at_rest = rest_update(self.state, self._params, gyro_rad_s[0],
                                               gyro_rad_s[1], gyro_rad_s[2], have_a, ax, ay,
                                               az, dt_s)
        self.window_at_rest = self.window_at_rest and self.at_rest

    def unmeasured_tick(self) -> None:
        """A tick over a counted loss: nothing says the board was still."""
        self.window_at_rest = False

    def take_window(self) -> bool:
        """Whether the window just closed was at rest; the next window starts."""
        verdict = self.window_at_rest
        self.window_at_rest = self.on
        return verdict

    def as_dict(self) -> dict[str, object]:
        return {"state": list(self.state), "at_rest": self.at_rest,
                "window_at_rest": self.window_at_rest}

    def load_dict(self, d: dict[str, object]) -> None:
        state = d["state"]
        assert isinstance(state, list)
        self.state = tuple(float(v) for v in state)
        self.at_rest = bool(d["at_rest"])
        self.window_at_rest = bool(d["window_at_rest"])

    @property
    def bias_rad_s(self) -> Vec:
        """The detector's own running bias (rad/s; what its later rate bound is taken from)."""
        b = self.state[REST_BIAS]
        return (b[0], b[1], b[2])


def deg_to_rad(v: Vec) -> Vec:
    """A reference-units gyro reading (deg/s) in rad/s."""
    return (math.radians(v[0]), math.radians(v[1]), math.radians(v[2]))
