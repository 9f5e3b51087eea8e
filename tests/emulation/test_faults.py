"""The fault-injection interface: typed specs, from a profile or from Python, each acting on
its device between its start and end time, and each yielding what docs/reliability.md says.
Run on the seed paragliding board (MAX21100 + HMC5883L behind its master + MS5611 on SPI)."""

from __future__ import annotations

import itertools
import math
import textwrap
from pathlib import Path

import pytest
from tests.support.noise import noise_only_specs

from imuhal.core.errors import BusError, ConfigurationError, NackError, ProfileError
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
    BusErrors,
    BusOSError,
    ChipAbsent,
    ChipReset,
    CorruptByte,
    CorruptTrim,
    FaultSpec,
    FrozenData,
    LatePolls,
    StuckDataReady,
    TimingJitter,
    WildValue,
    WrongPressure,
)
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile, parse_profile

SPI_READ_WHO_AM_I = bytes([0x80 | 0x20])  # MAX21100: read bit + WHO_AM_I (0x20)


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed_text() -> str:
    return Path(default_profile_path()).read_text(encoding="utf-8")


def _faults_yaml(items: str) -> str:
    """``items`` as the seed profile's ``emulation: faults:`` list (it ends with emulation)."""
    return "  faults:\n" + textwrap.indent(textwrap.dedent(items), "    ")


def _open(registry: Registry, *faults: FaultSpec, noise: bool = False) -> Pipeline:
    """The seed board at rest, raw samples; chips with their datasheet white noise only
    (no bias: any deviation is the fault's; an ideal chip at rest would repeat one raw frame
    for ever, which its driver flags FROZEN), or their whole error model with ``noise``."""
    profile = load_profile(default_profile_path(), registry)
    specs = None if noise else noise_only_specs(profile, registry)
    return open_emulated(profile, registry, scenario="static", seed=5, faults=faults,
                         calibrated=False, sensor_errors=True, error_specs=specs)


def _at(p: Pipeline, t_s: float) -> None:
    """Move the board's clock to ``t_s`` without polling anything."""
    p.clock.sleep_until(round(t_s * 1e9))


def _raw_transfer(p: Pipeline) -> bytes:
    return p.board.buses["spi0"].transfer(0, SPI_READ_WHO_AM_I, 1)


# -- specs, from a profile ------------------------------------------------------------------

def test_a_profile_lists_typed_faults_under_emulation(registry: Registry) -> None:
    text = _seed_text() + _faults_yaml("""\
        - {kind: bus_errors, device: baro, rate: 0.01}
        - {kind: reset, device: imu, start_s: 2.5}
        - {kind: absent, device: mag, start_s: 1, end_s: 3}
        """)
    profile = parse_profile(text, "board.yaml", registry)
    assert profile.emulation.faults == [BusErrors(device="baro", rate=0.01),
                                        ChipReset(device="imu", start_s=2.5),
                                        ChipAbsent(device="mag", start_s=1, end_s=3)]


def test_fault_mistakes_in_a_profile_are_all_reported_with_their_location(
        registry: Registry) -> None:
    text = _seed_text() + _faults_yaml("""\
        - {kind: bus_errors, device: baro, rate: 2}
        - {kind: reset, device: imu, start_s: 2, end_s: 3}
        - {kind: frozen, device: gps}
        - {kind: corrupt_trim, device: imu}
        - {kind: melt, device: imu}
        """)
    with pytest.raises(ProfileError) as info:
        parse_profile(text, "board.yaml", registry)
    problems = info.value.problems
    assert any(p.startswith("board.yaml:") and "emulation.faults.0.rate" in p for p in problems)
    assert any("emulation.faults.1" in p and "remove end_s" in p for p in problems)
    assert any("emulation.faults.4" in p and "'melt'" in p for p in problems)
    # the structural errors stop the second pass; fix them and the reference errors show
    text = _seed_text() + _faults_yaml("""\
        - {kind: frozen, device: gps}
        - {kind: corrupt_trim, device: imu}
        """)
    with pytest.raises(ProfileError) as info:
        parse_profile(text, "board.yaml", registry)
    problems = info.value.problems
    assert any("emulation.faults.0.device" in p and "'gps'" in p for p in problems)
    assert any("emulation.faults.1.kind" in p and "max21100" in p for p in problems)


def test_profile_faults_act_on_the_emulated_board(registry: Registry) -> None:
    text = _seed_text() + "  faults: [{kind: absent, device: baro, start_s: 0.5}]\n"
    profile = parse_profile(text, "board.yaml", registry)
    with open_emulated(profile, registry, scenario="static", calibrated=False) as p:
        events = list(p.events(1.0))
    baro = [e.t_ns for e in events if isinstance(e, PressureSample)]
    assert baro and max(baro) < 0.6e9


def test_a_chip_fault_its_emulator_does_not_model_is_refused_from_python(
        registry: Registry) -> None:
    with pytest.raises(ConfigurationError, match="max21100 emulator does not model"):
        _open(registry, CorruptTrim(device="imu"))
    with pytest.raises(ConfigurationError, match="no emulated device 'gps'"):
        _open(registry, FrozenData(device="gps"))


def test_corrupt_byte_off_a_serial_line_is_refused_in_a_profile_and_from_python(
        registry: Registry) -> None:
    text = _seed_text() + "  faults: [{kind: corrupt_byte, device: baro, byte: 4}]\n"
    with pytest.raises(ProfileError) as info:
        parse_profile(text, "board.yaml", registry)
    assert any("emulation.faults.0.kind" in p and "serial line" in p
               for p in info.value.problems)
    with pytest.raises(ConfigurationError, match="corrupt_byte acts on a serial line"):
        _open(registry, CorruptByte(device="imu"))


# -- the bus line -----------------------------------------------------------------------------

def test_bus_errors_fail_transfers_only_inside_their_window(registry: Registry) -> None:
    p = _open(registry, BusErrors(device="imu", start_s=1.0, end_s=2.0, rate=1.0))
    _raw_transfer(p)
    _at(p, 1.0)
    with pytest.raises(BusError, match="injected"):
        _raw_transfer(p)
    _at(p, 2.0)
    assert _raw_transfer(p) == bytes([0xB2])


def test_bus_errors_at_a_rate_fail_about_that_fraction(registry: Registry) -> None:
    p = _open(registry, BusErrors(device="imu", start_s=1.0, rate=0.1))
    _at(p, 1.0)
    failed = 0
    for _ in range(2000):
        try:
            _raw_transfer(p)
        except BusError:
            failed += 1
    assert 150 < failed < 250


def test_os_error_is_a_plain_oserror_from_the_bus(registry: Registry) -> None:
    p = _open(registry, BusOSError(device="imu", start_s=1.0, end_s=1.1))
    _at(p, 1.05)
    with pytest.raises(OSError) as info:
        _raw_transfer(p)
    assert not isinstance(info.value, BusError)


@pytest.mark.parametrize(("fault", "byte"), [(AllOnes, 0xFF), (AllZeros, 0x00)])
def test_all_ones_and_all_zeros_replace_every_byte_read(registry: Registry, fault: type,
                                                        byte: int) -> None:
    p = _open(registry, fault(device="imu", start_s=1.0, end_s=2.0))
    _at(p, 1.5)
    assert p.board.buses["spi0"].transfer(0, bytes([0x80 | 0x20]), 4) == bytes([byte]) * 4


def test_an_unplugged_chip_nacks_then_comes_back_in_its_reset_state(registry: Registry) -> None:
    p = _open(registry, ChipAbsent(device="baro", start_s=1.0, end_s=2.0))
    baro = p.board.emulators["baro"]
    resets = baro.resets
    _at(p, 1.5)
    with pytest.raises(NackError, match="unplugged"):
        p.board.buses["spi0"].transfer(1, b"\x00", 3)
    _at(p, 2.0)
    p.board.buses["spi0"].transfer(1, b"\x00", 3)
    assert baro.resets == resets + 1


# -- the chip ---------------------------------------------------------------------------------

def test_a_reset_fault_resets_the_chip_once_at_its_time(registry: Registry) -> None:
    p = _open(registry, ChipReset(device="baro", start_s=1.0))
    baro = p.board.emulators["baro"]
    list(p.events(0.9))
    before = baro.resets
    list(p.events(1.0))
    assert baro.resets == before + 1


def test_stuck_data_ready_holds_the_chip_between_start_and_end(registry: Registry) -> None:
    p = _open(registry, StuckDataReady(device="baro", start_s=1.0, end_s=1.5))
    events = list(p.events(2.0))
    assert p.board.emulators["baro"].stuck_data_ready is False
    valid = [e.t_ns for e in events if isinstance(e, PressureSample) and e.valid]
    assert not [t for t in valid if 1.05e9 < t < 1.5e9]
    assert [t for t in valid if t > 1.6e9]


def test_frozen_data_repeats_the_same_raw_word(registry: Registry) -> None:
    p = _open(registry, FrozenData(device="baro", start_s=1.0, end_s=2.0), noise=True)
    events = list(p.events(2.5))
    # a conversion started before 1.0 s may end after it: from the next one on
    in_window = [e for e in events if isinstance(e, PressureSample) and 1.03e9 < e.t_ns < 2.0e9]
    after = {e.pressure_pa for e in events if isinstance(e, PressureSample) and e.t_ns > 2.1e9}
    # the same raw word until the driver's frozen-data check flags it (values NaN)
    assert len({e.pressure_pa for e in in_window if e.valid}) <= 1
    assert any(e.flags & SampleFlag.FROZEN for e in in_window)
    assert len(after) > 2  # noise moves it again


def test_corrupt_trim_flips_prom_bits_the_driver_then_rejects(registry: Registry) -> None:
    p = _open(registry, CorruptTrim(device="baro", start_s=0.05))
    list(p.events(0.1))
    assert "PROM C" in " ".join(p.board.faults.log.events)
    # the corrupted PROM is read at the next probe: its CRC no longer matches
    with pytest.raises(Exception, match="CRC"):
        p.devices["baro"].driver.probe()


# -- the host's timing and the world ----------------------------------------------------------

def test_late_polls_delay_every_poll_of_the_device_in_the_window(registry: Registry) -> None:
    p = _open(registry, LatePolls(device="imu", start_s=1.0, end_s=1.1, delay_s=0.05))
    events = list(p.events(1.5))
    gyro = [e.t_ns for e in events if isinstance(e, GyroSample)]
    gaps = [b - a for a, b in itertools.pairwise(gyro)]
    assert max(gaps) >= 50_000_000
    assert p.board.faults.log.injected["imu"]["late_polls"] >= 1


def test_jitter_spreads_the_poll_times(registry: Registry) -> None:
    p = _open(registry, TimingJitter(device="baro", start_s=0.0, max_delay_s=0.004))
    events = list(p.events(1.0))
    baro = [e.t_ns for e in events if isinstance(e, PressureSample)]
    gaps = {b - a for a, b in itertools.pairwise(baro)}
    assert len(gaps) > 5


def test_a_wild_value_strikes_one_measurement_of_one_axis_and_fades_through_the_low_pass(
        registry: Registry) -> None:
    """The wild value is what the sensing element measures for one measurement: the ADC
    cuts it at the rail, and the MAX21100's gyro low-pass (14 Hz at 250 Hz, kept share
    a = exp(-2 pi 14 / 250)) takes 1 - a of it into that output, in range, and fades it by
    a per output after; the other axes never see it."""
    p = _open(registry, WildValue(device="imu", channel="gyro", axis=1, value=1e30,
                                  start_s=1.0))
    events = list(p.events(2.0))
    gyro = [e for e in events if isinstance(e, GyroSample)]
    full_scale = p.board.emulators["imu"].full_scale(GyroSample.channel)
    a = math.exp(-2 * math.pi * 14 / 250)
    struck = [i for i, e in enumerate(gyro) if abs(e.gyro_rad_s[1]) > 0.1 * full_scale]
    first = gyro[struck[0]]
    assert 1.0e9 <= first.t_ns < 1.02e9
    assert first.gyro_rad_s[1] == pytest.approx((1 - a) * full_scale, rel=0.02)
    later = gyro[struck[0] + 3]
    periods = round((later.t_ns - first.t_ns) / 4e6)
    assert later.gyro_rad_s[1] == pytest.approx((1 - a) * a ** periods * full_scale, rel=0.05)
    assert all(abs(e.gyro_rad_s[0]) < 0.01 for e in gyro)


def test_a_wrong_pressure_is_offset_from_the_truth_inside_its_window(registry: Registry) -> None:
    p = _open(registry, WrongPressure(device="baro", offset_pa=300.0, start_s=1.0, end_s=1.05))
    events = list(p.events(2.0))
    pressures = [e for e in events if isinstance(e, PressureSample)]
    typical = sorted(e.pressure_pa for e in pressures)[len(pressures) // 2]
    wrong = [e for e in pressures if abs(e.pressure_pa - typical) > 200]
    assert 1 <= len(wrong) <= 3
    assert all(1.0e9 <= e.t_ns < 1.2e9 for e in wrong)
    assert all(abs(e.pressure_pa - typical - 300) < 10 for e in wrong)
    temps = [e for e in events if isinstance(e, TemperatureSample)]
    assert temps


def test_the_same_seed_injects_the_same_faults(registry: Registry) -> None:
    def run() -> tuple[dict[str, dict[str, int]], list[Sample]]:
        p = _open(registry, BusErrors(device="baro", rate=0.05),
                  TimingJitter(device="imu", max_delay_s=0.001))
        events = [e for e in p.events(1.0) if isinstance(e, Sample)]
        return p.board.faults.log.injected, events
    assert run() == run()
