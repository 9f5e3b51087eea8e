"""vario-kf3 behind an AHRS slower than the barometer (the Freescale filters emit at 31 Hz on
the seed board, the MS5611 runs at 50 Hz): a barometer interval without an attitude estimate
reuses the previous interval's acceleration instead of predicting none.

A lift that accelerates at 1 m/s^2 for 2 s from rest, noise-free: ISA pressure at 50 Hz,
estimates carrying the vertical acceleration at 25 Hz (every other interval is empty).
"""

from __future__ import annotations

from imuhal.core.atmosphere import pressure_pa_at_altitude
from imuhal.core.samples import PressureSample
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal_filters.vario.kf3_estimator import VarioKf3Estimator

ACCEL_M_S2 = 1.0
START_S, END_S = 1.0, 3.0


def _climb_at_end(attitude_every_ns: int) -> tuple[float, dict[str, int]]:
    vario = VarioKf3Estimator({})
    last: VerticalEstimate | None = None
    for ms in range(0, int(END_S * 1000) + 1, 4):  # a 250 Hz clock
        t_ns = ms * 1_000_000
        t = max(0.0, ms / 1000 - START_S)
        if t_ns % attitude_every_ns == 0:
            vario.process(AttitudeEstimate(
                t_ns=t_ns, source="ahrs", q_body_to_ned=(1.0, 0.0, 0.0, 0.0),
                linear_accel_ned_m_s2=(0.0, 0.0, -ACCEL_M_S2 if ms / 1000 >= START_S else 0.0)))
        if ms % 20 == 0:
            altitude = 100.0 + 0.5 * ACCEL_M_S2 * t * t
            for e in vario.process(PressureSample(t_ns=t_ns, device="baro",
                                                  pressure_pa=pressure_pa_at_altitude(altitude))):
                if isinstance(e, VerticalEstimate):  # the start-up's first 0.8 s withheld
                    last = e
    assert last is not None
    return last.climb_m_s, vario.diagnostics()


def test_a_slower_ahrs_tracks_the_climb_as_closely_as_one_at_the_barometer_rate() -> None:
    true_climb = ACCEL_M_S2 * (END_S - START_S)
    slow, counts = _climb_at_end(40_000_000)   # 25 Hz
    fast, _ = _climb_at_end(4_000_000)         # 250 Hz
    assert counts["intervals_accel_held"] > 50
    assert abs(slow - true_climb) < 0.05
    assert abs(slow - fast) < 0.03
