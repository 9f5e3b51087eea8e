"""Entry point of the mahony plugin: registers the "mahony" attitude estimator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.mahony.estimator import MahonyEstimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(MahonyEstimator)
