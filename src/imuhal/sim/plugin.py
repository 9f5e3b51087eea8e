"""Registers the built-in scenarios through the same hook any plugin uses."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.elevator import ElevatorScenario
from imuhal.sim.magnet import MagnetScenario
from imuhal.sim.rc_flight import RcFlightScenario
from imuhal.sim.recorded import ReplayScenario
from imuhal.sim.static import StaticScenario
from imuhal.sim.thermal import ThermalScenario
from imuhal.sim.tumble import TumbleScenario

BUILTIN_SCENARIOS = (StaticScenario, CalibrationScenario, TumbleScenario, ThermalScenario,
                     RcFlightScenario, MagnetScenario, ElevatorScenario, ReplayScenario)


@hookimpl
def imuhal_register_scenarios(register: Registrar) -> None:
    for cls in BUILTIN_SCENARIOS:
        register(cls)
