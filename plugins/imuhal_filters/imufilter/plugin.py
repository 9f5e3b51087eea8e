"""Entry point of the imufilter plugin: registers the "imufilter" attitude estimator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.imufilter.estimator import ImuFilterEstimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(ImuFilterEstimator)
