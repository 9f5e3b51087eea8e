"""An emulated board: the profile's buses and chips as register-level emulators, driven by a
simulated scenario on the pipeline's simulated clock.

The simulation knows the truth in the body frame; each chip sees it in its own sensor frame
(the inverse of its chip -> body rotation), optionally through that chip's error model.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import PluginError
from imuhal.core.frames import FloatArray
from imuhal.emulation.base import ChipEmulator, PhysicalInputs
from imuhal.emulation.bus import EmulatedBus
from imuhal.pipeline.topology import device_order, split_bus_ref
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.sim.scenario import Scenario, TruthState

ErrorModel = Callable[[float, PhysicalInputs], PhysicalInputs]


class EmulatedBoard:
    def __init__(
        self,
        profile: BoardProfile,
        registry: Registry,
        clock: SimulatedClock,
        scenario: Scenario,
        chip_to_body: dict[str, FloatArray],
        error_models: dict[str, ErrorModel] | None = None,
    ) -> None:
        self.clock = clock
        self.scenario = scenario
        self.buses: dict[str, EmulatedBus] = {}
        for name, cfg in profile.buses.items():
            factory = registry.buses.get(cfg.kind)
            self.buses[name] = EmulatedBus(f"emul://{name}", factory.kind)
        self.emulators: dict[str, ChipEmulator] = {}
        hosts: dict[str, EmulatedBus] = {}
        for name in device_order(profile):
            dev = profile.devices[name]
            reg = registry.emulators.entries.get(dev.driver)
            if reg is None:
                raise PluginError(
                    f"device {name!r}: no emulator is installed for driver {dev.driver!r}, so "
                    f"this profile cannot run emulated; emulators exist for: "
                    f"{', '.join(registry.emulators.names()) or 'none'}"
                )
            emulator = reg.obj(clock=clock)
            host = self._bus_for(dev.bus)
            host.attach(dev.address, emulator)
            self.emulators[name] = emulator
            hosts[name] = host
        for name, emulator in self.emulators.items():
            emulator.connect_host(hosts[name])
        self._sensor_from_body = {n: np.asarray(r).T for n, r in chip_to_body.items()}
        self._errors = error_models or {}
        self._last_t_ns: int | None = None
        self.truth: TruthState | None = None

    def _bus_for(self, ref: str) -> EmulatedBus:
        parent, child = split_bus_ref(ref)
        if child is None:
            return self.buses[parent]
        provided = self.emulators[parent].child_buses()
        if child not in provided:
            raise PluginError(
                f"the emulator of device {parent!r} provides no bus {child!r} "
                f"(it provides: {', '.join(provided) or 'none'})"
            )
        return provided[child]

    def update(self, t_ns: int) -> TruthState:
        """Set every chip's physical inputs to the truth at ``t_ns``."""
        if t_ns == self._last_t_ns and self.truth is not None:
            return self.truth
        t_s = t_ns / 1e9
        truth = self.scenario.truth(t_s)
        for name, emulator in self.emulators.items():
            r = self._sensor_from_body[name]
            inputs = PhysicalInputs(
                specific_force_m_s2=_t3(r @ truth.specific_force_body_m_s2),
                angular_rate_rad_s=_t3(r @ truth.angular_rate_body_rad_s),
                magnetic_field_ut=_t3(r @ truth.magnetic_field_body_ut),
                pressure_pa=truth.pressure_pa,
                temperature_degc=truth.temperature_degc,
            )
            model = self._errors.get(name)
            emulator.set_physics(model(t_s, inputs) if model else inputs)
        self._last_t_ns = t_ns
        self.truth = truth
        return truth


def _t3(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))
