"""Entry point of the decoupled plugin: registers the "decoupled" attitude estimator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.decoupled.estimator import DecoupledEstimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(DecoupledEstimator)
