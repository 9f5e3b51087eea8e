"""Issue 9 reproductions on the bundled boards, through the fault-injection interface: runs
continue across events() calls without restarting chips, start-up rides through 1 %
transient bus errors on every board, and a chip behind the MAX21100's I2C master sees about
the host bus's error rate, not a multiple of it."""

from __future__ import annotations

import math
import random

import pytest
from tests.support.noise import noise_only_specs

from imuhal.core.samples import (
    MagSample,
    PressureSample,
    Quantity,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import AllZeros, BusErrors
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles, default_profile_path
from imuhal.profile.loader import load_profile


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def test_many_short_events_calls_never_restart_the_barometer_mid_conversion(
        registry: Registry) -> None:
    """Issue 9 item 1."""
    profile = load_profile(default_profile_path(), registry)
    rng = random.Random(9)
    # datasheet white noise only: an ideal chip would repeat one raw word (flagged FROZEN)
    with open_emulated(profile, registry, error_specs=noise_only_specs(profile, registry),
                       calibrated=False) as p:
        events: list[Sample] = []
        for _ in range(100):
            events += [e for e in p.events(rng.uniform(0.005, 0.08)) if isinstance(e, Sample)]
        truth = p.board.truth_at
        pressures = [e for e in events if isinstance(e, PressureSample) and e.valid]
        temps = [e for e in events if isinstance(e, TemperatureSample) and e.valid
                 and e.device == "baro"]
        assert len(pressures) > 100
        # an MS5611 without bias: 1 Pa steps, 1.2 Pa noise; the board climbs at most a few
        # m/s (12 Pa/m)
        assert max(abs(e.pressure_pa - truth(e.t_ns).pressure_pa) for e in pressures) < 40
        assert max(abs(e.temperature_degc - truth(e.t_ns).temperature_degc)
                   for e in temps) < 0.5
        assert p.board.emulators["baro"].aborted_conversions == 0


@pytest.mark.parametrize("board", sorted(bundled_profiles()))
def test_startup_succeeds_40_of_40_times_with_1_percent_bus_errors(
        registry: Registry, board: str) -> None:
    """Issue 9 item 5."""
    profile = load_profile(bundled_profiles()[board], registry)
    devices = [n for n, d in profile.devices.items() if d.enabled]
    for seed in range(40):
        faults = [BusErrors(device=d, rate=0.01) for d in devices]
        with open_emulated(profile, registry, seed=seed, faults=faults) as p:
            assert all(d.present for d in p.devices.values())


def test_the_magnetometer_behind_the_imu_master_sees_the_host_error_rate(
        registry: Registry) -> None:
    """Issue 9 item 10."""
    profile = load_profile(default_profile_path(), registry)

    def valid_mag(*faults: BusErrors) -> tuple[int, int]:
        with open_emulated(profile, registry, faults=faults, calibrated=False) as p:
            events = list(p.events(10.5))
        valid = sum(isinstance(e, MagSample) and e.valid and e.t_ns > 0.5e9 for e in events)
        return valid, p.summary().bus_errors["mag"]

    clean, _ = valid_mag()
    glitchy, errors = valid_mag(BusErrors(device="imu", rate=0.01, start_s=0.5))
    # the issue: 26 of 75 Hz delivered at 1 %; now a few percent lost at most
    assert glitchy >= 0.95 * clean
    assert errors <= 0.02 * clean


@pytest.mark.parametrize("board", sorted(bundled_profiles()))
def test_each_imu_and_magnetometer_declares_the_full_scale_its_chip_has(
        registry: Registry, board: str) -> None:
    profile = load_profile(bundled_profiles()[board], registry)
    with open_emulated(profile, registry, scenario="tumble", calibrated=False) as p:
        list(p.events(3.0))
        declared = {(n, ch): fs for n, d in p.devices.items() for ch, fs in d.full_scale.items()
                    if fs is not None}
        chips = {key: p.board.emulators[key[0]].full_scale(key[1]) for key in declared}
    assert {ch for _, ch in declared} >= {Quantity.GYRO, Quantity.ACCEL}
    for key, fs in declared.items():
        # the data word's limit: at or a little above the chip's own (datasheet) full scale
        assert chips[key] <= fs <= 1.15 * chips[key], key
    assert not any("OUT_OF_RANGE" in flags for flags in p.summary().flagged.values())


def test_the_start_up_gyro_phase_carries_over_short_events_calls(registry: Registry) -> None:
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, scenario="static") as p:
        for _ in range(10):  # 0.1 s each; the phase needs 100 samples at 250 Hz
            list(p.events(0.1))
        gyro = p.devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert gyro is not None and gyro.procedure == "gyro-at-startup"
    assert not [w for w in p.warnings if "start-up gyro" in w]


def test_recovery_from_1_percent_bus_errors_is_proportionate(registry: Registry) -> None:
    """Issue 9 (proportionate recovery): at 1 % transient bus errors every error reset the
    MS5611 (losing its conversion in flight and a cycle) and reconfigured the MAX21100. A
    glitch now costs at most the sample it hit: the barometer and the IMU keep at least
    98 % of their samples, and a chip is reset only after two failures in a row."""
    profile = load_profile(default_profile_path(), registry)
    seconds = 20.0
    faults = [BusErrors(device=d, rate=0.01) for d in ("imu", "baro")]
    with open_emulated(profile, registry, seed=3, faults=faults, calibrated=False) as p:
        samples = [e for e in p.events(seconds) if isinstance(e, Sample) and e.valid]
        baro, imu = p.devices["baro"], p.devices["imu"]
        assert baro.bus_errors > 20 and imu.bus_errors > 20
        assert baro.driver.health.reconfigurations <= baro.bus_errors // 10
        assert imu.driver.health.reconfigurations <= imu.bus_errors // 10
    pressures = [s for s in samples if s.channel is Quantity.PRESSURE]
    gyros = [s for s in samples if s.device == "imu" and s.channel is Quantity.GYRO]
    assert len(pressures) >= 0.98 * 50 * seconds
    assert len(gyros) >= 0.98 * 250 * seconds


def test_every_sample_with_a_nan_value_carries_the_nan_flag(registry: Registry) -> None:
    """Issue 9 item 9: NaN samples carried flags 0 although a NaN flag exists. The drivers
    report what is no measurement (a stuck sensor, an ADC that read 0, a frozen converter)
    as NaN values with their reason; whatever the reason, a NaN or infinite value also
    carries NAN, and a sample with it is never valid."""
    from imuhal.emulation.faults import AllZeros, FrozenData, StuckDataReady
    from imuhal.pipeline.processing import values_of

    profile = load_profile(default_profile_path(), registry)
    faults = [StuckDataReady(device="mag", start_s=0.3, end_s=0.9),
              StuckDataReady(device="imu", start_s=1.0, end_s=1.5),
              AllZeros(device="baro", start_s=0.3, end_s=0.6),
              FrozenData(device="baro", start_s=1.0, end_s=1.8)]
    with open_emulated(profile, registry, seed=2, faults=faults, calibrated=False) as p:
        samples = [e for e in p.events(2.0) if isinstance(e, Sample)]
    not_finite = [s for s in samples if not all(map(math.isfinite, values_of(s)))]
    assert {s.device for s in not_finite} == {"imu", "mag", "baro"}
    assert all(s.flags & SampleFlag.NAN and not s.valid for s in not_finite)


def test_every_recovery_that_finds_the_wrong_chip_is_counted_as_a_device_error(
        registry: Registry) -> None:
    """gy91's BMP280 behind an all-0x00 bus for 2 s: each recovery reads the chip id as
    0x00 and fails with DeviceNotFoundError. Each failure is a device error (they used to
    leave only the warning, so the summary said 1 error): after the first failed recovery
    the retries come 2, 4, 8 ... ms apart up to 100 ms, about 25 in the window."""
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=1,
                       faults=[AllZeros(device="baro", start_s=2.0, end_s=4.0)]) as p:
        list(p.events(5.0))
    summary = p.summary()
    failed = [w for w in summary.warnings if w.startswith("baro: recovery failed")]
    assert len(failed) == 1 and "found 0x00" in failed[0]
    assert summary.bus_errors["baro"] == 0
    assert summary.device_errors["baro"] >= 20
    assert summary.device_errors["imu"] == summary.device_errors["mag"] == 0
