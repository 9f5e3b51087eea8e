"""The generic conformance sweep over every installed driver that has an emulator.

For every enumerable setting value (DriverSettings.choices(), one field varied at a time from
the defaults), the real driver configures its emulator over an emulated bus; a physical value
set on the emulator must come back through the driver within one LSB of the chip's
resolution at that setting, and a value beyond full scale must be flagged, never passed as
valid. Chips behind another chip's master are swept directly on I2C (the path behind a
master has its own tests).
"""

from __future__ import annotations

from typing import Any

import pytest
from tests.support.dither import Dither

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Channel, SampleFlag, ScalarSample, VectorSample
from imuhal.drivers.base import Driver
from imuhal.emulation.base import ChipEmulator, PhysicalInputs
from imuhal.emulation.bus import EmulatedBus
from imuhal.plugins.manager import Registry, load_registry

REGISTRY: Registry = load_registry()
DIRECTION = (0.41037, -0.28963, 0.19021)
"""Fraction of full scale set on each axis: inside the range, all axes different, between
counts (so the dither below moves the raw words), and summing below 1 (the AK8963 overflows
when |x|+|y|+|z| reaches its 4912 uT range)."""
SCALAR_VALUES = {Channel.PRESSURE: 90_123.0, Channel.TEMPERATURE: 23.4}
SETTLE_SAMPLES = 20
"""Samples per channel before comparing: on-chip filters (BMP280 IIR) settle on a constant."""
MAX_SIMULATED_NS = 60_000_000_000


def _variants() -> list[tuple[str, str, Any]]:
    out = []
    for name in REGISTRY.emulators.names():
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


def _physics(emulator: ChipEmulator, channels: tuple[Channel, ...], x_fraction: float
             ) -> PhysicalInputs:
    def vec(ch: Channel) -> tuple[float, float, float] | None:
        if ch not in channels:
            return None
        fs = emulator.full_scale(ch)
        return (x_fraction * fs, DIRECTION[1] * fs, DIRECTION[2] * fs)

    return PhysicalInputs(
        specific_force_m_s2=vec(Channel.ACCEL),
        angular_rate_rad_s=vec(Channel.GYRO),
        magnetic_field_ut=vec(Channel.MAG),
        pressure_pa=SCALAR_VALUES[Channel.PRESSURE],
        temperature_degc=SCALAR_VALUES[Channel.TEMPERATURE],
    )


def _run(driver: Driver, clock: SimulatedClock, emulator: ChipEmulator) -> dict[Channel, Any]:
    """Poll as the pipeline would until every channel gave SETTLE_SAMPLES samples, the
    inputs dithered by under half an LSB as a real chip's noise would (a constant input
    read back unchanged for ever is a frozen chip)."""
    dither = Dither(emulator, seed=20)
    last: dict[Channel, Any] = {}
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
        REGISTRY.drivers.get(name).Settings.model_validate(settings)
    except ValueError:
        return None  # not combinable with the other defaults (e.g. an ODR above a filter)
    return settings


@pytest.mark.parametrize(("name", "field", "value"), _variants())
def test_a_physical_value_reads_back_within_one_lsb(name: str, field: str, value: Any) -> None:
    settings = _settings(name, field, value)
    if settings is None:
        pytest.skip(f"{field}={value} cannot combine with the other defaults")
    driver, emulator, clock = _open(name, settings)
    driver.probe()
    driver.configure()
    emulator.set_physics(_physics(emulator, driver.channels, DIRECTION[0]))
    got = _run(driver, clock, emulator)
    for ch in driver.channels:
        sample = got[ch]
        assert sample.valid, (ch, sample.flags)
        lsb = emulator.resolution(ch)
        if isinstance(sample, VectorSample):
            fs = emulator.full_scale(ch)
            want = [d * fs for d in DIRECTION]
            for axis in range(3):
                assert abs(sample.vector[axis] - want[axis]) <= 1.0001 * lsb, (ch, axis)
        elif isinstance(sample, ScalarSample):
            assert abs(sample.scalar - SCALAR_VALUES[ch]) <= 1.0001 * lsb, ch


@pytest.mark.parametrize("name", REGISTRY.emulators.names())
def test_beyond_full_scale_is_flagged_never_valid(name: str) -> None:
    driver, emulator, clock = _open(name, {})
    vector_channels = [c for c in driver.channels if c in (Channel.ACCEL, Channel.GYRO,
                                                           Channel.MAG)]
    if not vector_channels:
        pytest.skip("barometers report pressure outside their range as OUT_OF_RANGE, "
                    "tested with their driver")
    driver.probe()
    driver.configure()
    emulator.set_physics(_physics(emulator, driver.channels, 1.6))  # x at 1.6 x full scale
    got = _run(driver, clock, emulator)
    for ch in vector_channels:
        flags = got[ch].flags
        assert flags & (SampleFlag.SATURATED | SampleFlag.OVERFLOW), (ch, flags)
