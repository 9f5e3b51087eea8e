"""A chip's own filter carries a wrong measurement into the outputs after it (issue 26 item 1).

The GY-91's BMP280 runs its IIR filter (coefficient 4); one wild pressure (-200 kPa, the
ADC at its rail) used to leave the chip flagged once and then 17 outputs in range, valid,
up to 57 kPa off. The driver now undoes the filter to see what the chip measured and flags
the outputs the filter can still carry it as FILTER_SETTLING; the IMUs' low-pass filters
get the same rule after an input at the rail (tests/integration/test_imu_lowpass_memory.py).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import pytest

from imuhal.core.samples import PressureSample, Quantity, Sample, SampleFlag
from imuhal.drivers.validity import iir_memory_outputs, lowpass_settling_outputs
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import AllOnes, CorruptTrim, FaultSpec, WildValue
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

WILD_AT_S = 3.0
RUN_S = 6.0
PRESSURE_TOLERANCE_PA = 60.0
"""The BMP280 error model's bias and noise for seed 1 stay within 25 Pa of the truth on a
clean run; a filtered-in -200 kPa measurement is off by kilopascals for 0.3 s."""


def _gy91_events(faults: Sequence[FaultSpec]) -> Iterator[tuple[Any, Any]]:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=1, faults=list(faults)) as pipeline:
        scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        for event in pipeline.events(RUN_S):
            yield event, scenario.truth(event.t_ns / 1e9)


WILD_PRESSURE = WildValue(device="baro", channel="pressure", value=-200_000.0,
                          start_s=WILD_AT_S)


@pytest.fixture(scope="module")
def wild_run() -> list[tuple[Any, Any]]:
    return list(_gy91_events([WILD_PRESSURE]))


@pytest.fixture(scope="module")
def clean_run() -> list[tuple[Any, Any]]:
    return list(_gy91_events([]))


def _pressures(run: list[tuple[Any, Any]]) -> list[tuple[PressureSample, Any]]:
    return [(e, truth) for e, truth in run
            if isinstance(e, PressureSample) and e.device == "baro"]


def test_no_valid_pressure_carries_a_wild_value_through_the_bmp280_iir(
        wild_run: list[tuple[Any, Any]]) -> None:
    """Issue 26 item 1: every valid pressure after one wild one stays within the error
    model of the truth; the wild one and the 49 outputs its filter can carry are flagged."""
    pressures = _pressures(wild_run)
    wrong = [(s.t_ns / 1e9, s.pressure_pa - truth.pressure_pa) for s, truth in pressures
             if s.valid and abs(s.pressure_pa - truth.pressure_pa) > PRESSURE_TOLERANCE_PA]
    assert wrong == []
    measured = [s for s, _ in pressures if s.flags & (SampleFlag.SATURATED
                                                       | SampleFlag.OUT_OF_RANGE)]
    settling = [s for s, _ in pressures if s.flags & SampleFlag.FILTER_SETTLING]
    assert len(measured) == 1 and measured[0].t_ns >= WILD_AT_S * 1e9
    assert len(settling) == iir_memory_outputs(4, 20) == 49
    assert all(0 < s.t_ns - measured[0].t_ns <= 50 * 40_000_000 for s in settling)
    assert sum(s.valid for s, _ in pressures) > 0.9 * RUN_S * 25 - 50


def test_the_vario_does_not_follow_a_filtered_in_wild_pressure(
        wild_run: list[tuple[Any, Any]], clean_run: list[tuple[Any, Any]]) -> None:
    """The vario's altitude after the wild pressure stays within 1 m of the same flight's
    without it (it went 70 m off when the filtered outputs were fused)."""
    def altitudes(run: list[tuple[Any, Any]]) -> dict[int, float]:
        return {e.t_ns: e.altitude_m for e, _ in run if isinstance(e, VerticalEstimate)}
    wild, clean = altitudes(wild_run), altitudes(clean_run)
    common = [t for t in wild if t in clean and t >= WILD_AT_S * 1e9]
    # the 49 settling outputs (1.2 s at the gy91's 40 Hz) are a gap the vario restarts
    # after, withholding its estimates until it knows the climb rate again (UNSETTLED,
    # docs/reliability.md): about half of the 3 s's 120 outputs remain
    assert len(common) > 60
    assert max(abs(wild[t] - clean[t]) for t in common) < 1.0


def test_a_wild_gyro_value_makes_the_mpu9250_low_pass_outputs_after_it_settle() -> None:
    """A 100 rad/s wild gyro value (beyond the +/-500 dps range): the DLPF (41 Hz at
    200 Hz) takes 1 - a = 0.72 of the rail into an output in range; the driver sees the
    rail input by undoing the filter and flags that output and the 3 its trace can still
    reach by the part's specified offset (5 deg/s, 1 % of the full scale) FILTER_SETTLING;
    the one after is valid again."""
    wild = WildValue(device="imu", channel="gyro", value=100.0, start_s=WILD_AT_S)
    gyro = [e for e, _ in _gy91_events([wild])
            if isinstance(e, Sample) and e.device == "imu" and e.channel is Quantity.GYRO]
    flagged = [i for i, s in enumerate(gyro) if s.flags]
    first = flagged[0]
    n = lowpass_settling_outputs(41, 200, 5 / 500)
    assert n == 3
    assert [s.flags for s in gyro[first:first + n + 1]] == [SampleFlag.FILTER_SETTLING] * (n + 1)
    assert flagged == list(range(first, first + n + 1))


@pytest.mark.parametrize("coefficient", [2, 4, 8, 16])
def test_the_iir_memory_is_where_a_full_scale_error_falls_below_one_lsb(
        coefficient: int) -> None:
    n = iir_memory_outputs(coefficient, 20)
    keep = (coefficient - 1) / coefficient
    assert keep ** n * 2 ** 20 < 1 <= keep ** (n - 1) * 2 ** 20


def test_no_filter_has_no_memory() -> None:
    assert iir_memory_outputs(0, 20) == 0
    assert lowpass_settling_outputs(1e9, 200, 0.01) == 0


def test_a_bmp280_whose_trimming_reads_differently_after_a_reprobe_is_refused() -> None:
    """Issue 26 item 1, the combined run's constant error: the BMP280's trimming has no CRC,
    so a corrupted read at the re-probe after an all-0xFF spell compensated every later
    pressure wrong (seed 6 flips dig_P2 bit 3: 128 valid pressures up to 477 Pa off; a
    higher bit gave the 7.5 kPa seen). The driver compares it with its start-up read."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    faults = [CorruptTrim(device="baro", start_s=2.0), AllOnes(device="baro", start_s=3.0,
                                                                end_s=3.5)]
    with open_emulated(profile, registry, seed=6, faults=faults) as pipeline:
        scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        errors = [abs(e.pressure_pa - scenario.truth(e.t_ns / 1e9).pressure_pa)
                  for e in pipeline.events(RUN_S)
                  if isinstance(e, PressureSample) and e.valid]
        warnings = list(pipeline.warnings)
    assert errors and max(errors) < PRESSURE_TOLERANCE_PA
    assert any("trimming P2 reads differently from start-up" in w for w in warnings)
