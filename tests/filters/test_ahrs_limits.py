"""No AHRS fuses a value beyond its physical full scale, NaN or infinite (issue 9 item 8).

One gyro value of 1e30 rad/s used to flip the attitude by about 180 deg for the rest of the
run. It must be dropped, counted, and the attitude must stay right.
"""

from __future__ import annotations

import math

import pytest
from tests.filters.ahrs_cases import AHRS, at_rest, attitude, error_deg, make, run

from imuhal.core.samples import AccelSample, GyroSample, Sample


def _with_bad(samples: list[Sample], kind: type, value: float, at: int = 300) -> list[Sample]:
    """The stream with the ``at``-th sample of ``kind`` replaced by one reading ``value``."""
    out, seen = [], 0
    for s in samples:
        if isinstance(s, kind):
            if seen == at:
                s = (GyroSample(t_ns=s.t_ns, device=s.device, frame=s.frame,
                                gyro_rad_s=(value, 0.0, 0.0)) if kind is GyroSample else
                     AccelSample(t_ns=s.t_ns, device=s.device, frame=s.frame,
                                 accel_m_s2=(value, 0.0, -9.8)))
            seen += 1
        out.append(s)
    return out


def _rejected(est, channel: str) -> int:
    count = est.diagnostics()["beyond_full_scale"]
    return count[channel] if isinstance(count, dict) else count


@pytest.mark.parametrize("value", [1e30, -40.0, math.nan, math.inf])
@pytest.mark.parametrize("name", list(AHRS))
def test_an_impossible_gyro_value_is_dropped_counted_and_the_attitude_stays(
        name: str, value: float) -> None:
    q = attitude(20.0, -10.0, 70.0)
    est = make(name)
    out = run(est, iter(_with_bad(list(at_rest(q, 2.0)), GyroSample, value)))
    assert max(error_deg(name, e, q) for e in out if e.t_ns >= 1e9) < 1.0
    if math.isfinite(value):
        assert _rejected(est, "gyro") == 1


@pytest.mark.parametrize("name", list(AHRS))
def test_an_impossible_accelerometer_value_is_dropped_and_counted(name: str) -> None:
    q = attitude(-15.0, 5.0, 200.0)
    est = make(name)
    out = run(est, iter(_with_bad(list(at_rest(q, 2.0)), AccelSample, 1e12)))
    assert max(error_deg(name, e, q) for e in out if e.t_ns >= 1e9) < 1.0
    assert _rejected(est, "accel") == 1


def test_the_full_scale_is_a_setting() -> None:
    est = make("madgwick", {"gyro_full_scale_rad_s": 5.0})
    run(est, iter(_with_bad(list(at_rest(attitude(0, 0, 0), 1.6)), GyroSample, 6.0)))
    assert _rejected(est, "gyro") == 1
