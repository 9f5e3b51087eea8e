"""Entry point of the freescale plugin: the Freescale/NXP 6DOF and 9DOF Kalman estimators."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.freescale.estimator import Freescale6DofEstimator, Freescale9DofEstimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(Freescale9DofEstimator)
    register(Freescale6DofEstimator)
