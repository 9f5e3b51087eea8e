"""The scenarios imuhal ships (registered by :mod:`imuhal.plugins.builtin_scenarios`)."""

from __future__ import annotations

from imuhal.sim.bringup import BringupScenario
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.elevator import ElevatorScenario
from imuhal.sim.magnet import MagnetScenario
from imuhal.sim.rc_flight import RcFlightScenario
from imuhal.sim.recorded import ReplayScenario
from imuhal.sim.static import StaticScenario
from imuhal.sim.thermal import ThermalScenario
from imuhal.sim.tumble import TumbleScenario

BUILTIN_SCENARIOS = (StaticScenario, CalibrationScenario, TumbleScenario, ThermalScenario,
                     RcFlightScenario, MagnetScenario, ElevatorScenario, ReplayScenario,
                     BringupScenario)
