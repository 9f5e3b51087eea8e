"""Registers the built-in generic calibration procedures through the same hook any plugin
uses (accel, gyro and mag have their own commands: ``imuhal calibrate gyro|accel|mag``)."""

from __future__ import annotations

from imuhal.calibration.vector_zero import VectorZeroProcedure
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar


@hookimpl
def imuhal_register_calibrations(register: Registrar) -> None:
    register(VectorZeroProcedure)
