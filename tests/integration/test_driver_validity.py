"""In-driver validity (issue 9): a sample a driver emits as valid is physically plausible for
its chip. Faults come through the fault-injection interface (imuhal.emulation.faults) on the
bundled boards; chips carry their datasheet error models unless a test says otherwise."""

from __future__ import annotations

import math
from typing import Any

import pytest
import yaml

from imuhal.core.samples import (
    GyroSample,
    PressureSample,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import (
    AllOnes,
    AllZeros,
    ChipReset,
    FaultSpec,
    FrozenData,
    StuckDataReady,
    WildValue,
)
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile

SEED = "seed-paraglider-vario.yaml"
GY91 = "gy91.yaml"
DEVICES = [(SEED, "imu"), (SEED, "mag"), (SEED, "baro"),
           (GY91, "imu"), (GY91, "mag"), (GY91, "baro")]
"""MAX21100, HMC5883L (behind the MAX21100's master), MS5611; MPU-9250, AK8963, BMP280."""
NOT_A_MEASUREMENT = SampleFlag.STALE | SampleFlag.BLANK | SampleFlag.FROZEN


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _run(registry: Registry, board: str, seconds: float, *faults: FaultSpec,
         scenario: str = "static", settings: dict[str, dict[str, Any]] | None = None
         ) -> tuple[list[Sample], Pipeline]:
    """Raw (uncalibrated) samples of ``board`` flying ``scenario`` for ``seconds``, with
    each device's driver ``settings`` changed as given."""
    path = bundled_profiles()[board]
    if settings:
        doc = yaml.safe_load(path.read_text())
        for device, values in settings.items():
            doc["devices"][device]["settings"].update(values)
        profile = parse_profile(yaml.safe_dump(doc, sort_keys=False), board, registry)
    else:
        profile = load_profile(path, registry)
    with open_emulated(profile, registry, scenario=scenario, seed=11, faults=faults,
                       calibrated=False) as p:
        samples = [e for e in p.events(seconds) if isinstance(e, Sample)]
    return samples, p


def _of(samples: list[Sample], device: str, t0_s: float = 0.0,
        t1_s: float = math.inf) -> list[Sample]:
    return [s for s in samples if s.device == device and t0_s * 1e9 <= s.t_ns < t1_s * 1e9]


# -- all-0xFF and all-0x00 frames ------------------------------------------------------------

@pytest.mark.parametrize("kind", [AllOnes, AllZeros], ids=["all-0xFF", "all-0x00"])
@pytest.mark.parametrize(("board", "device"), DEVICES)
def test_an_undriven_bus_never_yields_a_valid_sample(registry: Registry, board: str,
                                                     device: str, kind: type) -> None:
    """Issue 9 item 2."""
    samples, _ = _run(registry, board, 3.5, kind(device=device, start_s=1.0, end_s=2.0))
    during = _of(samples, device, 1.0, 2.0)
    assert not [s for s in during if s.valid]
    # what is emitted during the fault says why it is not a measurement
    assert all(s.flags & NOT_A_MEASUREMENT for s in during)
    assert [s for s in _of(samples, device, 2.5) if s.valid]  # the chip is back afterwards


def test_an_unplugged_magnetometer_behind_the_max21100_gives_no_field(
        registry: Registry) -> None:
    """Issue 9 item 2: the HMC5883L behind the MAX21100's master, unplugged, read as a valid
    0.16 uT field; its data frame is all 0xFF (BLANK) and its configuration reads back
    wrong, so the driver hands it to the pipeline's recovery."""
    samples, p = _run(registry, SEED, 3.0, AllOnes(device="mag", start_s=1.0, end_s=2.0))
    assert not [s for s in _of(samples, "mag", 1.0, 2.0) if s.valid]
    assert p.devices["mag"].driver.health.resets_detected >= 1


def test_the_max21100_reading_all_ones_is_never_free_fall_nor_twice_the_rate(
        registry: Registry) -> None:
    """Issue 9 item 2: data-ready on every poll and -1 counts (about 0 m/s^2) at twice the
    configured rate."""
    samples, _ = _run(registry, SEED, 2.0, AllOnes(device="imu", start_s=1.0, end_s=2.0))
    during = [s for s in _of(samples, "imu", 1.0, 2.0) if isinstance(s, GyroSample)]
    assert not [s for s in during if s.valid]
    assert len(during) <= 250  # never faster than gyro_odr_hz


# -- frozen data -----------------------------------------------------------------------------

@pytest.mark.parametrize(("board", "device"), DEVICES)
def test_frozen_data_is_flagged_once_it_repeats_longer_than_noise_allows(
        registry: Registry, board: str, device: str) -> None:
    """The chip keeps presenting the same raw words as new: the first ones are plausible
    (noise could repeat them), then every one is flagged FROZEN (at most 1.6 s at the
    slowest default rate, the BMP280's 25 Hz behind its IIR filter)."""
    samples, _ = _run(registry, board, 5.5, FrozenData(device=device, start_s=1.0, end_s=5.0))
    assert [s for s in _of(samples, device, 0.5, 1.0) if s.valid]
    late = _of(samples, device, 3.0, 5.0)
    assert late and not [s for s in late if s.valid]
    # frozen frames, and stale slots while the driver restarts the chip to cure it
    assert all(s.flags & (SampleFlag.FROZEN | SampleFlag.STALE) for s in late)
    assert any(s.flags & SampleFlag.FROZEN for s in late)


def test_a_hung_bmp280_is_not_valid_while_the_board_climbs(registry: Registry) -> None:
    """Issue 9 item 3: a GY-91 BMP280 in normal mode whose conversions hang reported one
    pressure, valid, for the rest of the run while the board climbed."""
    samples, p = _run(registry, GY91, 20.0, FrozenData(device="baro", start_s=2.0),
                      scenario="elevator")
    truth = p.board.truth_at
    assert abs(truth(20_000_000_000).altitude_m - truth(2_000_000_000).altitude_m) > 5
    after = [s for s in _of(samples, "baro", 4.0) if isinstance(s, PressureSample)]
    assert after and not [s for s in after if s.valid]
    assert all(s.flags & SampleFlag.FROZEN for s in after if not s.flags & SampleFlag.STALE)


# -- stuck sensors and silent resets ---------------------------------------------------------

@pytest.mark.parametrize(("board", "device"), DEVICES)
def test_a_stuck_sensor_is_flagged_and_restarted_by_its_driver(
        registry: Registry, board: str, device: str) -> None:
    """Issue 9 item 10. No new data while the chip keeps its configuration: the slots are
    flagged and the driver restarts the chip itself (a soft reset cures the MAX21100,
    HMC5883L and BMP280; the MPU-9250, AK8963 and MS5611 stay stuck until the fault ends)."""
    samples, p = _run(registry, board, 3.0,
                      StuckDataReady(device=device, start_s=1.0, end_s=2.0))
    assert p.devices[device].driver.health.reconfigurations >= 1
    assert [s for s in _of(samples, device, 1.0, 2.0)
            if s.flags & (SampleFlag.STALE | SampleFlag.FROZEN)]
    assert [s for s in _of(samples, device, 2.5) if s.valid]


@pytest.mark.parametrize(("board", "device"), DEVICES)
def test_a_silent_reset_is_repaired_and_only_real_measurements_are_valid(
        registry: Registry, board: str, device: str) -> None:
    samples, p = _run(registry, board, 3.0, ChipReset(device=device, start_s=1.0))
    driver = p.devices[device].driver
    if driver.name != "ms5611":  # the MS5611 has no configuration to lose
        assert driver.health.resets_detected == 1
    after = _of(samples, device, 2.0)
    assert after and all(s.valid for s in after)
    # no sample in between is a leftover of the reset chip (blank, frozen or stale) marked valid
    assert all(not s.flags or s.flags & NOT_A_MEASUREMENT or s.flags & SampleFlag.NAN
               for s in _of(samples, device, 1.0, 2.0))


# -- ranges ----------------------------------------------------------------------------------

@pytest.mark.parametrize("board", [SEED, GY91])
def test_an_imu_die_temperature_beyond_its_operating_range_is_never_valid(
        registry: Registry, board: str) -> None:
    """Issue 9 item 10."""
    samples, _ = _run(registry, board, 2.0,
                      WildValue(device="imu", channel="temperature", value=150.0,
                                start_s=1.0, hold_s=0.3))
    hot = [s for s in _of(samples, "imu", 1.0, 1.3) if isinstance(s, TemperatureSample)
           and not math.isnan(s.temperature_degc)]
    assert hot and all(s.temperature_degc > 85 for s in hot[1:])
    assert all(s.flags & SampleFlag.OUT_OF_RANGE for s in hot if s.temperature_degc > 85)


@pytest.mark.parametrize(("board", "device"), [(b, d) for b, d in DEVICES if d != "baro"])
def test_each_driver_declares_its_configured_full_scale(registry: Registry, board: str,
                                                        device: str) -> None:
    """The pipeline flags a value beyond the driver's declared full scale OUT_OF_RANGE; the
    declaration matches what the chip can report (its emulator, written from the datasheet
    side), so a correct value is never flagged and a word beyond the range always is."""
    _, p = _run(registry, board, 0.2)
    driver, emulator = p.devices[device].driver, p.board.emulators[device]
    for channel in driver.channels:
        declared = driver.full_scale(channel)
        if channel.value == "temperature":
            assert declared is None  # die temperatures are range-checked by the driver
            continue
        assert declared == pytest.approx(emulator.full_scale(channel), rel=1e-3)


# -- healthy chips are never flagged ---------------------------------------------------------

QUIETEST: dict[str, dict[str, dict[str, Any]]] = {
    SEED: {"imu": {"gyro_range_dps": 2000, "gyro_lpf_hz": 2, "accel_range_g": 16},
           "mag": {"range_gauss": 8.1}},
    GY91: {"imu": {"gyro_range_dps": 2000, "accel_range_g": 16, "gyro_lpf_hz": 5,
                   "accel_lpf_hz": 5},
           "mag": {"resolution_bits": 14},
           "baro": {"pressure_oversampling": 1, "temperature_oversampling": 1,
                    "iir_coefficient": 16}},
}
"""Each board's settings with the fewest counts per unit of noise: where a real sensor's
words repeat most often."""


@pytest.mark.slow
@pytest.mark.parametrize("board", [SEED, GY91, "seed-rc-vario.yaml"])
@pytest.mark.parametrize("quiet", [False, True], ids=["default", "quietest"])
def test_healthy_chips_with_datasheet_noise_at_rest_are_never_flagged(
        registry: Registry, board: str, quiet: bool) -> None:
    if quiet and board not in QUIETEST:
        pytest.skip("the seed RC board has the seed paraglider's chips")
    seconds = 40.0 if quiet else 20.0
    samples, p = _run(registry, board, seconds, settings=QUIETEST[board] if quiet else None)
    assert len(samples) > 200 * seconds
    assert not [s for s in samples if s.flags & NOT_A_MEASUREMENT]
    assert all(d.driver.health.reconfigurations == 0 for d in p.devices.values())
