"""A driver that builds its own blocks (overrides ``Driver.poll_blocks``, as a FIFO reader
that decodes into arrays does) gets the same pipeline as one that returns samples: the
blocks go through the array steps and come out as the same events."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from tests.support import testchip
from tests.support.testchip import TC3Driver, TC3Emulator

from imuhal.bus.base import Bus, BusKind
from imuhal.core.blocks import Block
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Sample, VectorSample
from imuhal.drivers.base import BlockPoll
from imuhal.pipeline import Pipeline
from imuhal.plugins import builtin_buses, builtin_scenarios
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile
from imuhal.sim.emulated_bus import EmulatedBus
from imuhal.sim.inputs import PhysicalInputs

PROFILE = """\
schema_version: 1
name: blocks-test
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc: {driver: DRIVER, bus: i2c1, address: 0x19, mount: "+Y-X+Z", settings: {odr_hz: 100}}
"""


class TC3ArrayDriver(TC3Driver):
    """The TC3, its readings handed over as blocks built from arrays."""

    name = "tc3-arrays"

    def poll_blocks(self, now_ns: int) -> BlockPoll:
        result = self.poll(now_ns)
        blocks = []
        for s in result.samples:
            values = s.vector if isinstance(s, VectorSample) else (s.scalar,)  # type: ignore[attr-defined]
            blocks.append(Block.from_arrays(
                type(s), s.device, s.t_ns, np.zeros(1, np.int64), np.array([values]),
                np.array([int(s.flags)]), frame=getattr(s, "frame", None)))
        return BlockPoll(blocks, result.next_poll_ns)


@hookimpl
def _register(register) -> None:  # type: ignore[no-untyped-def]
    register(TC3ArrayDriver)


def _registry() -> Registry:
    return load_registry(entry_point_plugins=False, extra=[
        ("buses", builtin_buses), ("scenarios", builtin_scenarios), ("testchip", testchip),
        ("arrays", SimpleNamespace(imuhal_register_drivers=_register))])


class _Bench:
    """One I2C bus with a TC3 feeling a fixed specific force and pressure."""

    def __init__(self) -> None:
        self.clock = SimulatedClock()
        chip = TC3Emulator(clock=self.clock)
        chip.set_physics(PhysicalInputs(specific_force_m_s2=(1.25, -2.5, -9.75),
                                        pressure_pa=90_123.5))
        bus = EmulatedBus("bench", BusKind.I2C)
        bus.attach(0x19, chip)
        self.buses: dict[str, Bus] = {"i2c1": bus}

    def before_poll(self, t_ns: int, device: str) -> int:
        return t_ns


def _events(registry: Registry, driver: str) -> list[Sample]:
    profile = parse_profile(PROFILE.replace("DRIVER", driver), "blocks.yaml", registry)
    pipeline = Pipeline(profile, registry, _Bench())  # type: ignore[arg-type]
    return [e for e in pipeline.events(0.2) if isinstance(e, Sample)]


def test_a_driver_that_builds_array_blocks_gives_the_events_of_one_that_returns_samples(
) -> None:
    registry = _registry()
    from_samples = _events(registry, "tc3")
    from_arrays = _events(registry, "tc3-arrays")
    assert len(from_samples) == 40  # 20 polls, accelerometer and pressure
    assert from_arrays == from_samples
    # the mount (+Y-X+Z) rotated the chip's axes into the body frame
    assert from_samples[0].vector != (1.25, -2.5, -9.75)  # type: ignore[attr-defined]
