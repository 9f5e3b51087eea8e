"""Entry point of the madgwick plugin: registers the "madgwick" attitude estimator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.madgwick.estimator import MadgwickEstimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(MadgwickEstimator)
