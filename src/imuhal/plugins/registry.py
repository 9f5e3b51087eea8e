"""The Registry: everything the installed plugins registered, one typed registrar per hook;
and :class:`Command`, the base of a plugin's ``imuhal`` subcommand (its ``run`` is handed the
registry).

A registered :class:`Command` becomes ``imuhal NAME``: it adds its own arguments to its
subparser and runs with the parsed arguments and the loaded registry. Its errors follow the
CLI's rule: raise an :class:`~imuhal.core.errors.ImuhalError` naming the input and the fix,
and ``imuhal`` prints it on one line and exits 2.
"""

from __future__ import annotations

import argparse
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Any, ClassVar

from imuhal.bus.factory import BusFactory
from imuhal.calibration.procedure import CalibrationProcedure
from imuhal.core.samples import SAMPLE_TYPES, Sample
from imuhal.drivers.base import Driver
from imuhal.estimation.base import Estimator
from imuhal.plugins.registrars import Registrar
from imuhal.sim.chip import ChipEmulator
from imuhal.sim.scenario import Scenario
from imuhal.sinks.base import SinkPlugin


class Command(ABC):
    """Base of a plugin's ``imuhal`` subcommand."""

    name: ClassVar[str] = ""
    """The subcommand (``imuhal NAME``); must not clash with a built-in one."""
    help: ClassVar[str] = ""
    """One line for ``imuhal --help``."""
    description: ClassVar[str] = ""

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:  # noqa: B027 - optional
        """Add the command's arguments to its subparser (default: none)."""

    @abstractmethod
    def run(self, args: argparse.Namespace, registry: Registry) -> int:
        """Do the work; return the exit status (0: success)."""


@dataclass
class Registry:
    """Everything the installed plugins registered."""

    drivers: Registrar[Driver] = field(default_factory=lambda: Registrar("driver", Driver))
    emulators: Registrar[ChipEmulator] = field(
        default_factory=lambda: Registrar("emulator", ChipEmulator, name_attr="chip")
    )
    estimators: Registrar[Estimator] = field(
        default_factory=lambda: Registrar("estimator", Estimator)
    )
    buses: Registrar[BusFactory] = field(
        default_factory=lambda: Registrar("bus kind", BusFactory, name_attr="scheme")
    )
    scenarios: Registrar[Scenario] = field(
        default_factory=lambda: Registrar("scenario", Scenario)
    )
    quantities: Registrar[Sample] = field(default_factory=lambda: _quantities())
    """Sample classes by the name of the quantity they carry (``channel.name``); imuhal's
    own (accel, gyro, mag, pressure, temperature) are always there."""
    sinks: Registrar[SinkPlugin] = field(default_factory=lambda: Registrar("sink", SinkPlugin))
    commands: Registrar[Command] = field(
        default_factory=lambda: Registrar("command", Command)
    )
    calibrations: Registrar[CalibrationProcedure] = field(
        default_factory=lambda: Registrar("calibration procedure", CalibrationProcedure)
    )
    plugins: dict[str, str] = field(default_factory=dict)
    """Loaded plugin name -> distribution name ('' for a plugin handed over by hand)."""
    versions: dict[str, str] = field(default_factory=dict)
    """Loaded plugin name -> its distribution's version ('' when not known)."""

    def hooks(self) -> dict[str, Registrar[Any]]:
        """Each hook's name and the registrar its implementations are called with, in the
        order the loader calls them."""
        return {
            "imuhal_register_quantities": self.quantities,
            "imuhal_register_buses": self.buses,
            "imuhal_register_drivers": self.drivers,
            "imuhal_register_emulators": self.emulators,
            "imuhal_register_estimators": self.estimators,
            "imuhal_register_scenarios": self.scenarios,
            "imuhal_register_sinks": self.sinks,
            "imuhal_register_commands": self.commands,
            "imuhal_register_calibrations": self.calibrations,
        }

    def registrar_for(self, hook: str) -> Registrar[Any]:
        return self.hooks()[hook]

    @contextmanager
    def attributed(self, plugin_now: Callable[[], str]) -> Iterator[None]:
        """Registrations made inside are recorded as made by the plugin ``plugin_now()``
        names when each is made."""
        def who() -> tuple[str, str]:
            plugin = plugin_now()
            return plugin, self.plugins.get(plugin, "")

        with ExitStack() as stack:
            for registrar in self.hooks().values():
                stack.enter_context(registrar.registering_as(who))
            yield

    @contextmanager
    def registering(self, plugin: str) -> Iterator[None]:
        """Registrations made inside (by any registrar) are recorded as ``plugin``'s."""
        package = self.plugins.get(plugin, "")
        with ExitStack() as stack:
            for registrar in self.hooks().values():
                stack.enter_context(registrar.registering(plugin, package))
            yield


def _quantities() -> Registrar[Sample]:
    registrar: Registrar[Sample] = Registrar(
        "quantity", Sample, name_attr="channel",
        name_of=lambda cls: getattr(getattr(cls, "channel", None), "name", ""))
    with registrar.registering("imuhal", "imuhal"):
        for cls in SAMPLE_TYPES.values():
            registrar(cls)
    return registrar
