"""The emulated board draws a chip's white noise in the band of the chip's own output rate
(``ChipEmulator.noise_period_s``), whatever the host's poll interval: a real chip's output
noise is set by its ODR and filters, not by how often it is read."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imuhal.core.quantities import Quantity
from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.sim.errors import SensorErrorSpec

SEED = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
DPS = math.pi / 180.0
UG = 9.80665e-6
GYRO_DENSITY = 0.005 * DPS      # rad/s/sqrt(Hz)
ACCEL_DENSITY = 300 * UG        # m/s^2/sqrt(Hz)
# White noise only: biases and scale errors would not change the spread, but keep the
# expected value exact.
SPEC = SensorErrorSpec.model_validate(
    {"gyro": {"noise_density": GYRO_DENSITY}, "accel": {"noise_density": ACCEL_DENSITY}})
ODR_PERIOD_NS = 4_000_000       # the seed profile's MAX21100 runs gyro and accel at 250 Hz
GYRO_FILTER_HZ = 14.0           # ... through its 14 Hz gyro filter (GYRO_CFG1 bandwidth)
ACCEL_FILTER_HZ = 250.0 / 48    # ... and its accelerometer output filter (ODR / 48)


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _configured_board(registry: Registry):  # type: ignore[no-untyped-def]
    """The seed board after its driver configured the IMU (0.1 s of the static scenario)."""
    pipeline = open_emulated(load_profile(SEED, registry), registry, scenario="static",
                             error_specs={"imu": SPEC}, seed=7)
    list(pipeline.events(0.1))
    board = EmulatedBoard.of(pipeline)
    imu = board.emulators["imu"]
    assert imu.noise_period_s(Quantity.GYRO) == ODR_PERIOD_NS / 1e9  # precondition
    return pipeline, board


def _handed(registry: Registry, intervals_ns: list[int], quantity: str
            ) -> tuple[np.ndarray, np.ndarray]:
    """What the board hands the IMU when the host polls it after each of ``intervals_ns``,
    and the truth at those instants (sensor frame): (measured, true), shape (n, 3)."""
    pipeline, board = _configured_board(registry)
    with pipeline:
        t_ns = board.clock.now_ns() + ODR_PERIOD_NS
        imu = board.emulators["imu"]
        board.update(t_ns, "imu")
        measured, true = [], []
        for dt in intervals_ns:
            t_ns += dt
            board.update(t_ns, "imu")
            physics = imu.physics
            measured.append(physics.specific_force_m_s2 if quantity == "accel"
                            else physics.angular_rate_rad_s)
            truth = board.truth_at(t_ns)
            # The seed IMU is mounted -Y-X-Z: its axes are (-y, -x, -z) of the body's.
            body = (truth.specific_force_body_m_s2 if quantity == "accel"
                    else truth.angular_rate_body_rad_s).tolist()
            true.append((-body[1], -body[0], -body[2]))
    return np.asarray(measured), np.asarray(true)


def test_noise_std_does_not_depend_on_the_host_poll_interval(registry: Registry) -> None:
    """Polled at 2x and at 0.5x the chip's 250 Hz ODR, the gyro noise std is the density
    in the chip's 14 Hz filter band (narrower than its 125 Hz Nyquist band) both times.
    With n = 3 x 4000 draws the sample std's relative standard error is 1/sqrt(2n) = 0.65 %,
    so 3 % is a 4.6 sigma bound; the bug (band from the poll interval) gave sqrt(2) too much
    and sqrt(2) too little."""
    n = 4000
    expected = GYRO_DENSITY * math.sqrt(GYRO_FILTER_HZ)
    stds = {}
    for factor, interval_ns in (("2x", ODR_PERIOD_NS // 2), ("0.5x", ODR_PERIOD_NS * 2)):
        measured, true = _handed(registry, [interval_ns] * n, "gyro")
        stds[factor] = float(np.std(measured - true))
    for factor, std in stds.items():
        assert abs(std / expected - 1.0) < 0.03, (factor, std, expected)
    assert abs(stds["2x"] / stds["0.5x"] - 1.0) < 0.05, stds


def test_a_poll_a_microsecond_after_the_previous_gives_no_spike(registry: Registry) -> None:
    """Polls at the ODR, each followed 1 us later by another: the accelerometer noise of
    the quick polls stays that of the chip's 5.2 Hz output filter (0.0067 m/s^2 std). 6 sigma
    over 3 x 300 draws is exceeded with probability 2e-6; the bug's 500 kHz band gave
    2 m/s^2 std (spikes of several g)."""
    intervals = [ODR_PERIOD_NS - 1_000, 1_000] * 300
    measured, true = _handed(registry, intervals, "accel")
    quick = (measured - true)[1::2]
    sigma = ACCEL_DENSITY * math.sqrt(ACCEL_FILTER_HZ)
    assert np.abs(quick).max() < 6 * sigma, (np.abs(quick).max(), sigma)


def test_a_chip_without_an_output_rate_gets_the_poll_interval_floored_at_its_fastest(
        registry: Registry) -> None:
    """After a silent reset (the fault-injection hook) the IMU is powered down and outputs
    at no rate (``noise_period_s`` None):
    the band falls back to the poll interval, but never wider than the Nyquist band of the
    chip's fastest output (MAX21100: 8 kHz). Polls 1 us apart then draw the 4 kHz band's
    std (bound as in the poll-interval test: 3 x 3000 draws, 3.2 % is 4.6 sigma)."""
    pipeline = open_emulated(load_profile(SEED, registry), registry, scenario="static",
                             error_specs={"imu": SPEC}, seed=7)
    with pipeline:
        board = EmulatedBoard.of(pipeline)
        imu = board.emulators["imu"]
        imu.silent_reset()  # power-on register state: gyro and accel powered down
        assert imu.noise_period_s(Quantity.GYRO) is None  # precondition
        t_ns = 1_000_000_000
        board.update(t_ns, "imu")
        rates = []
        for _ in range(3000):
            t_ns += 1_000
            board.update(t_ns, "imu")
            rates.append(imu.physics.angular_rate_rad_s)
    expected = GYRO_DENSITY * math.sqrt(0.5 / imu.min_output_period_s)
    std = float(np.std(np.asarray(rates) - np.mean(rates, axis=0)))
    assert abs(std / expected - 1.0) < 0.032, (std, expected)


def test_the_chips_low_pass_filter_narrows_the_noise_band(registry: Registry) -> None:
    """The GY-91's MPU-9250 outputs at 200 Hz (Nyquist 100 Hz) through its 41 Hz gyro
    filter (DLPF_CFG 3): the gyro noise std is the density in 41 Hz, not in 100 Hz (0.64x
    less). 3 x 3000 draws: the sample std's relative standard error is 0.75 %, so 4 % is a
    5.3 sigma bound; the Nyquist band would be 56 % off."""
    gy91 = SEED.parent / "gy91.yaml"
    spec = SensorErrorSpec.model_validate({"gyro": {"noise_density": GYRO_DENSITY}})
    pipeline = open_emulated(load_profile(gy91, registry), registry, scenario="static",
                             error_specs={"imu": spec}, seed=7)
    list(pipeline.events(0.1))
    board = EmulatedBoard.of(pipeline)
    imu = board.emulators["imu"]
    assert imu.noise_period_s(Quantity.GYRO) == pytest.approx(0.005)  # precondition
    assert imu.noise_bandwidth_hz(Quantity.GYRO) == 41.0
    with pipeline:
        t_ns = board.clock.now_ns()
        rates = []
        for _ in range(3000):
            t_ns += 5_000_000
            board.update(t_ns, "imu")
            rates.append(imu.physics.angular_rate_rad_s)
    std = float(np.std(np.asarray(rates) - np.mean(rates, axis=0)))
    expected = GYRO_DENSITY * math.sqrt(41.0)
    assert abs(std / expected - 1.0) < 0.04, (std, expected)


def test_the_noise_band_follows_a_filter_written_mid_run(registry: Registry) -> None:
    """The board keeps what the chip said about its rate and filter between writes: after
    the host writes a wider gyro filter (GYRO_CFG1 bandwidth code 8: 50 Hz, was 14 Hz) the
    noise is drawn in the new band. 3 x 3000 draws: 4 % is a 5.3 sigma bound (as in the
    filter test); the old band would be 47 % off."""
    from imuhal.bus.registers import RegisterView
    from imuhal_chips.max2110x.registers import SPI_CONVENTION, Reg

    pipeline, board = _configured_board(registry)
    imu = board.emulators["imu"]
    view = RegisterView(pipeline.devices["imu"].driver.link, SPI_CONVENTION)
    with pipeline:
        t_ns = board.clock.now_ns() + ODR_PERIOD_NS
        board.update(t_ns, "imu")  # the old band, remembered
        cfg1 = view.read_u8(Reg.GYRO_CFG1)
        view.write(Reg.GYRO_CFG1, (cfg1 & ~(0x0F << 2)) | (8 << 2))
        assert imu.noise_bandwidth_hz(Quantity.GYRO) == 50.0  # precondition
        rates = []
        for _ in range(3000):
            t_ns += ODR_PERIOD_NS
            board.update(t_ns, "imu")
            rates.append(imu.physics.angular_rate_rad_s)
    std = float(np.std(np.asarray(rates) - np.mean(rates, axis=0)))
    expected = GYRO_DENSITY * math.sqrt(50.0)
    assert abs(std / expected - 1.0) < 0.04, (std, expected)
