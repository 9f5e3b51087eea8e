"""The generic conformance sweep over the driver/emulator pairs that opt in to it.

For every enumerable setting value (DriverSettings.choices(), one field varied at a time from
the defaults), the real driver configures its emulator over an emulated bus; a physical value
set on the emulator must come back through the driver within one LSB of the chip's
resolution at that setting, and a value beyond full scale must be flagged, never passed as
valid. Chips behind another chip's master are swept directly on I2C (the path behind a
master has its own tests).

The resolution and full scale come from an independent table written from the datasheets
(tests/data/chips/conformance_sweep.json), never from the emulator or the driver, so the
sweep checks both against the datasheet rather than against each other. Only emulators
whose class sets ``conformance_sweep = True`` are swept: a third-party plugin installed in
the same environment cannot break imuhal's own suite.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from tests.support.dither import Dither
from tests.support.testchip import TC3Driver, TC3Emulator

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Quantity, SampleFlag, ScalarSample, VectorSample
from imuhal.drivers.base import Driver
from imuhal.drivers.settings import BUS_CONTEXT, BUS_FEATURES_CONTEXT
from imuhal.emulation import ChipEmulator, EmulatedBus, PhysicalInputs
from imuhal.plugins.manager import Registry, load_registry

REGISTRY: Registry = load_registry()
TABLE: dict[str, Any] = json.loads(
    (Path(__file__).parent.parent / "data" / "chips" / "conformance_sweep.json").read_text())


def swept(registry: Registry) -> list[str]:
    """The emulators the sweep covers: those whose class opts in."""
    return [n for n in registry.emulators.names() if registry.emulators.get(n).conformance_sweep]


SWEPT = swept(REGISTRY)
DIRECTION = (0.41037, -0.28963, 0.19021)
"""Fraction of full scale set on each axis: inside the range, all axes different, between
counts (so the dither below moves the raw words), and summing below 1 (the AK8963 overflows
when |x|+|y|+|z| reaches its 4912 uT range)."""
SCALAR_VALUES = {Quantity.PRESSURE: 90_123.3, Quantity.TEMPERATURE: 23.4}
"""Between whole pascals, so the dither in _run moves an emulator that rounds to them."""
SETTLE_SAMPLES = 20
"""Samples per channel before comparing: on-chip filters (BMP280 IIR) settle on a constant."""
MAX_SIMULATED_NS = 60_000_000_000


def _variants() -> list[tuple[str, str, Any]]:
    out = []
    for name in SWEPT:
        driver = REGISTRY.drivers.get(name)
        out.append((name, "(defaults)", None))
        for field, values in driver.Settings.choices().items():
            out += [(name, field, v) for v in values]
    return out


def _open(name: str, settings: dict[str, Any]) -> tuple[Driver, ChipEmulator, SimulatedClock]:
    driver_cls = REGISTRY.drivers.get(name)
    clock = SimulatedClock()
    emulator = REGISTRY.emulators.get(name)(clock=clock)
    kind = BusKind.I2C if BusKind.I2C in driver_cls.bus_kinds else BusKind.SPI
    bus = EmulatedBus("emul://sweep", kind)
    bus.attach(0x42, emulator)
    driver = driver_cls(bus.link(0x42), settings, device="dut", clock=clock)
    return driver, emulator, clock


def _setting_value(driver: Driver, name: str) -> Any:
    if not hasattr(driver.settings, name):
        raise AssertionError(f"{driver.name} has no setting {name!r}: update "
                             "tests/data/chips/conformance_sweep.json to its new name")
    return getattr(driver.settings, name)


def _setting(driver: Driver, entry: dict[str, Any], key: str) -> str:
    """The driver's configured value of the table entry's setting, as the table's key."""
    value = float(_setting_value(driver, entry[key]))
    table = entry.get("lsb_per_unit_by_value") or entry["lsb_si_by_value"]
    return next(k for k in table if float(k) == value)


def expected_lsb(driver: Driver, channel: Quantity) -> float:
    """One output step (SI) of ``channel`` at the driver's settings, from the table."""
    entry = TABLE[driver.name][channel.value]
    if "lsb_si" in entry:
        step = entry["lsb_si"]
    elif "filtered_by" in entry and _setting_value(driver, entry["filtered_by"]):
        step = entry["filtered_lsb_si"]
    elif "lsb_si_by_value" in entry:
        step = entry["lsb_si_by_value"][_setting(driver, entry, "setting")]
    else:
        step = entry["unit_si"] / entry["lsb_per_unit_by_value"][
            _setting(driver, entry, "setting")]
    return step * entry.get("lsb_scale", 1.0) + entry.get("allowance_si", 0.0)


def expected_full_scale(driver: Driver, channel: Quantity) -> float:
    """The largest magnitude (SI) ``channel`` reports at the driver's settings, from the table."""
    entry = TABLE[driver.name][channel.value]
    if "full_scale_si" in entry:
        return float(entry["full_scale_si"])
    return entry["full_scale_counts"] * entry["unit_si"] / entry["lsb_per_unit_by_value"][
        _setting(driver, entry, "setting")]


def _physics(driver: Driver, x_fraction: float) -> PhysicalInputs:
    channels = driver.channels

    def vec(ch: Quantity) -> tuple[float, float, float] | None:
        if ch not in channels:
            return None
        fs = expected_full_scale(driver, ch)
        return (x_fraction * fs, DIRECTION[1] * fs, DIRECTION[2] * fs)

    return PhysicalInputs(
        specific_force_m_s2=vec(Quantity.ACCEL),
        angular_rate_rad_s=vec(Quantity.GYRO),
        magnetic_field_ut=vec(Quantity.MAG),
        pressure_pa=SCALAR_VALUES[Quantity.PRESSURE],
        temperature_degc=SCALAR_VALUES[Quantity.TEMPERATURE],
    )


def _run(driver: Driver, clock: SimulatedClock, emulator: ChipEmulator) -> dict[Quantity, Any]:
    """Poll as the pipeline would until every channel gave SETTLE_SAMPLES samples, the
    inputs dithered by under half an LSB as a real chip's noise would (a constant input
    read back unchanged for ever is a frozen chip)."""
    dither = Dither(emulator, seed=20)
    last: dict[Quantity, Any] = {}
    counts = dict.fromkeys(driver.channels, 0)
    t = driver.start(clock.now_ns())
    while min(counts.values()) < SETTLE_SAMPLES and clock.now_ns() < MAX_SIMULATED_NS:
        clock.sleep_until(t)
        dither()
        result = driver.poll(clock.now_ns())
        for s in result.samples:
            last[s.channel] = s
            counts[s.channel] = counts.get(s.channel, 0) + 1
        t = max(result.next_poll_ns, clock.now_ns() + 1)
    return last


def _settings(name: str, field: str, value: Any) -> dict[str, Any] | None:
    if value is None:
        return {}
    settings = {field: value}
    try:
        # checked as a profile would be, on the sweep's plain bus (no bus features)
        REGISTRY.drivers.get(name).Settings.model_validate(
            settings, context={BUS_CONTEXT: "emul://sweep", BUS_FEATURES_CONTEXT: frozenset()})
    except ValueError:
        # not combinable with the other defaults (e.g. an ODR above a filter), or needing a
        # bus feature (read: auto, tested behind its master in test_max2110x_auto_read.py)
        return None
    return settings


@pytest.mark.parametrize(("name", "field", "value"), _variants())
def test_a_physical_value_reads_back_within_one_lsb(name: str, field: str, value: Any) -> None:
    settings = _settings(name, field, value)
    if settings is None:
        pytest.skip(f"{field}={value} cannot combine with the other defaults or needs a "
                    "bus feature the sweep's plain bus lacks")
    driver, emulator, clock = _open(name, settings)
    driver.probe()
    driver.configure()
    emulator.set_physics(_physics(driver, DIRECTION[0]))
    got = _run(driver, clock, emulator)
    for ch in driver.channels:
        sample = got[ch]
        assert sample.valid, (ch, sample.flags)
        lsb = expected_lsb(driver, ch)
        if isinstance(sample, VectorSample):
            fs = expected_full_scale(driver, ch)
            want = [d * fs for d in DIRECTION]
            for axis in range(3):
                assert abs(sample.vector[axis] - want[axis]) <= 1.0001 * lsb, (ch, axis)
        elif isinstance(sample, ScalarSample):
            assert abs(sample.scalar - SCALAR_VALUES[ch]) <= 1.0001 * lsb, ch


@pytest.mark.parametrize("name", SWEPT)
def test_beyond_full_scale_is_flagged_never_valid(name: str) -> None:
    driver, emulator, clock = _open(name, {})
    vector_channels = [c for c in driver.channels if c in (Quantity.ACCEL, Quantity.GYRO,
                                                           Quantity.MAG)]
    if not vector_channels:
        pytest.skip("barometers report pressure outside their range as OUT_OF_RANGE, "
                    "tested with their driver")
    driver.probe()
    driver.configure()
    emulator.set_physics(_physics(driver, 1.6))  # x at 1.6 x full scale
    got = _run(driver, clock, emulator)
    for ch in vector_channels:
        flags = got[ch].flags
        assert flags & (SampleFlag.SATURATED | SampleFlag.OVERFLOW), (ch, flags)


def test_every_bundled_emulator_opts_in_and_has_a_datasheet_table() -> None:
    # Register-mapped chips only: a UART byte stream (the GNSS receiver) has no resolution or
    # full scale to sweep; tests/chips/test_gnss_*.py check it against published sentences.
    bundled = [n for n, e in REGISTRY.emulators.entries.items()
               if e.obj.__module__.startswith("imuhal_chips.")
               and REGISTRY.drivers.get(n).bus_kinds != frozenset({BusKind.SERIAL})]
    assert bundled, "the bundled chip plugins are not installed"
    for name in bundled:
        assert name in SWEPT, f"{name} does not opt in to the conformance sweep"
        assert name in TABLE, f"{name} has no entry in conformance_sweep.json"


def test_a_third_party_emulator_that_does_not_opt_in_is_left_out() -> None:
    registry = load_registry()
    registry.drivers(TC3Driver)
    registry.emulators(TC3Emulator)
    assert "tc3" in registry.emulators.names()
    assert "tc3" not in swept(registry)
    assert set(swept(registry)) == set(SWEPT)
