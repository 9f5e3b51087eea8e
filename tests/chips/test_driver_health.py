"""Every built-in driver records its health the same way: each sample it returns is counted,
flagged ones by flag name."""

from __future__ import annotations

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation.base import PhysicalInputs
from imuhal.emulation.bus import EmulatedBus
from imuhal.plugins.manager import load_registry

REGISTRY = load_registry()
BUILT_IN = ("ms5611", "bmp280", "max21100", "max21105", "hmc5883l", "mpu9250", "ak8963")
INPUTS = PhysicalInputs(specific_force_m_s2=(0.3, -0.2, 9.7), angular_rate_rad_s=(0.1, 0.0, -0.1),
                        magnetic_field_ut=(20.0, -3.0, 43.0), pressure_pa=95_000.0,
                        temperature_degc=21.0)


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_sample_a_driver_returns_is_counted_in_its_health(name: str) -> None:
    driver_cls = REGISTRY.drivers.get(name)
    clock = SimulatedClock()
    emulator = REGISTRY.emulators.get(name)(clock=clock)
    emulator.set_physics(INPUTS)
    kind = BusKind.I2C if BusKind.I2C in driver_cls.bus_kinds else BusKind.SPI
    bus = EmulatedBus("emul://health", kind)
    bus.attach(0x42, emulator)
    driver = driver_cls(bus.link(0x42), {}, device="dut", clock=clock)
    driver.probe()
    driver.configure()
    t = driver.start(clock.now_ns())
    returned = []
    while len(returned) < 12:
        clock.sleep_until(t)
        result = driver.poll(clock.now_ns())
        returned += result.samples
        t = result.next_poll_ns
    assert driver.health.samples == len(returned)
    assert driver.health.flagged == sum(1 for s in returned if not s.valid)
