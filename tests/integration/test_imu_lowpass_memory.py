"""An IMU's digital low-pass carries a wild input into the outputs after it, for as long as
its bandwidth says (issue 26 item 1; the availability the rule costs).

The seed RC vario's MAX21105 filters its gyro at 10 Hz (200 Hz ODR) and its accelerometer
at ODR / 48. A ``wild_value`` strikes the sensing element: the ADC cuts it at the rail and
the filter takes 1 - a of it into the output (in range) and fades it by a per output. The
emulator models that from the datasheet's bandwidth; the driver undoes the filter to see the
rail input and flags the outputs until what it can still add is below the part's specified
offset (3 deg/s, 60 mg: what a valid reading of the chip may be off anyway).
Each faulted run is compared with the same flight without the fault (seed 1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest

from imuhal.core.samples import Quantity, SampleFlag, VectorSample
from imuhal.drivers.validity import lowpass_coefficient
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import FaultSpec, WildValue
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

RUN_S = 2.0
WILD_AT_S = 1.2
GYRO_FULL_SCALE_RAD_S = math.radians(1000.0)
ACCEL_FULL_SCALE_M_S2 = 8 * 9.80665
GYRO_OFFSET_RAD_S = math.radians(3.0)
ACCEL_OFFSET_M_S2 = 0.060 * 9.80665

Run = dict[tuple[Quantity, int], VectorSample]
"""The IMU's gyro and accelerometer samples by (quantity, time stamp)."""


def _imu_samples(faults: Sequence[FaultSpec], seconds: float = RUN_S) -> tuple[Run, dict]:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, faults=list(faults)) as pipeline:
        samples = {(e.channel, e.t_ns): e for e in pipeline.events(seconds)
                   if isinstance(e, VectorSample) and e.device == "imu"
                   and e.channel in (Quantity.GYRO, Quantity.ACCEL)}
        memory = pipeline.devices["imu"].driver.filter_memory_outputs()  # type: ignore[attr-defined]
    return samples, memory


@pytest.fixture(scope="module")
def clean() -> Run:
    return _imu_samples([])[0]


@pytest.fixture(scope="module")
def one_wild_gyro() -> tuple[Run, dict]:
    return _imu_samples([WildValue(device="imu", channel="gyro", axis=2,
                                   value=1000 * GYRO_FULL_SCALE_RAD_S, start_s=WILD_AT_S)])


def _series(run: Run, quantity: Quantity) -> list[VectorSample]:
    return [run[k] for k in sorted(k for k in run if k[0] is quantity)]


def _off(sample: VectorSample, clean: Run) -> float:
    other = clean[(sample.channel, sample.t_ns)]
    return math.dist(sample.vector, other.vector)


def test_the_emulated_low_pass_fades_a_wild_gyro_word_as_its_bandwidth_says(
        clean: Run, one_wild_gyro: tuple[Run, dict]) -> None:
    """The outputs after the wild one differ from the clean flight's by a trace that fades
    by a = exp(-2 pi 10 Hz / 200 Hz) per output, from 1 - a of the way to the rail."""
    gyro = _series(one_wild_gyro[0], Quantity.GYRO)
    offs = [_off(s, clean) for s in gyro]
    first = next(i for i, off in enumerate(offs) if off > 0.01)
    a = lowpass_coefficient(10, 1 / 200)
    assert offs[first] == pytest.approx((1 - a) * GYRO_FULL_SCALE_RAD_S, rel=0.05)
    assert abs(gyro[first].vector[2]) < GYRO_FULL_SCALE_RAD_S  # in range: not at the rail
    for k in range(1, 8):
        assert offs[first + k] / offs[first + k - 1] == pytest.approx(a, rel=0.03)


def test_the_outputs_the_trace_can_still_reach_are_settling_then_valid_again(
        clean: Run, one_wild_gyro: tuple[Run, dict]) -> None:
    run, memory = one_wild_gyro
    gyro = _series(run, Quantity.GYRO)
    first = next(i for i, s in enumerate(gyro) if not s.valid)
    n = memory[Quantity.GYRO]
    assert n == 16  # ln(2 (1 - a) / 0.003) / ln(1 / a) at 10 Hz and 200 Hz
    assert [s.flags for s in gyro[first:first + n + 1]] == [SampleFlag.FILTER_SETTLING] * (n + 1)
    assert all(s.valid for s in gyro[first + n + 1:])
    worst = max(_off(s, clean) for s in gyro if s.valid)
    assert worst < GYRO_OFFSET_RAD_S


def test_at_ten_percent_wild_values_the_imu_is_valid_between_them_and_never_wrong(
        clean: Run) -> None:
    """The fault matrix's 10 % plan on the IMU (a wild word at 1000 times the full scale on
    one in ten outputs, gyro, accelerometer and temperature in turn: one per channel every
    150 ms) used to flag every output from 1 s on (the rule held 36 and 85 outputs)."""
    faults: list[FaultSpec] = []
    for i in range(int((RUN_S - 1.0) * 20)):
        channel = ("accel", "gyro", "temperature")[i % 3]
        full = {"accel": ACCEL_FULL_SCALE_M_S2, "gyro": GYRO_FULL_SCALE_RAD_S}.get(channel, 1e5)
        faults.append(WildValue(device="imu", channel=channel, axis=i % 3,
                                value=1000 * full, start_s=round(1.0 + (i + 0.5) / 20, 4)))
    run, _ = _imu_samples(faults)
    # of every 30 outputs, the gyro's 10 Hz filter holds 17 (the wild one and 16 after),
    # the accelerometer's ODR / 48 holds 27 (measured 78 and 18 of 183 valid, worst 1.3
    # deg/s and 29 mg off)
    for quantity, offset, share in ((Quantity.GYRO, GYRO_OFFSET_RAD_S, 0.35),
                                    (Quantity.ACCEL, ACCEL_OFFSET_M_S2, 0.08)):
        late = [s for s in _series(run, quantity) if s.t_ns > 1.1e9]
        valid = [s for s in late if s.valid]
        assert len(valid) > share * len(late), quantity
        assert max(_off(s, clean) for s in valid) < offset, quantity
