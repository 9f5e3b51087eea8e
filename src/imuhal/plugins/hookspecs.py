"""Hook specifications. A plugin module implements any of these with ``@hookimpl``.

Each hook receives a registrar: call it with the class to register. Built-in chips and
filters use exactly these hooks, through the same ``imuhal`` entry-point group as anyone's.
The loader calls every hook through pluggy's hook caller (``pm.hook.NAME(register=...)``), so
hook wrappers and tracing work as pluggy documents.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pluggy

PROJECT = "imuhal"
ENTRY_POINT_GROUP = "imuhal"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)

if TYPE_CHECKING:
    from imuhal.plugins.registrars import Registrar


@hookspec
def imuhal_register_drivers(register: Registrar) -> None:
    """Register Driver subclasses: ``register(MyDriver)``."""


@hookspec
def imuhal_register_emulators(register: Registrar) -> None:
    """Register ChipEmulator subclasses; each names the driver it stands in for (``chip``)."""


@hookspec
def imuhal_register_estimators(register: Registrar) -> None:
    """Register Estimator subclasses."""


@hookspec
def imuhal_register_buses(register: Registrar) -> None:
    """Register BusFactory subclasses for new bus kinds (URL schemes)."""


@hookspec
def imuhal_register_scenarios(register: Registrar) -> None:
    """Register Scenario subclasses for the simulator."""


@hookspec
def imuhal_register_quantities(register: Registrar) -> None:
    """Register Sample subclasses for new physical quantities: each names its
    :class:`~imuhal.core.quantities.Quantity` as ``channel`` (``HumiditySample``)."""


@hookspec
def imuhal_register_sinks(register: Registrar) -> None:
    """Register SinkPlugin subclasses (``imuhal run --sink NAME``)."""


@hookspec
def imuhal_register_commands(register: Registrar) -> None:
    """Register Command subclasses: each becomes an ``imuhal`` subcommand."""


@hookspec
def imuhal_register_calibrations(register: Registrar) -> None:
    """Register CalibrationProcedure subclasses (``imuhal calibrate NAME PROFILE``)."""
