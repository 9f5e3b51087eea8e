"""Entry point of the vario plugin: registers the variometer estimators."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_filters.vario.baro_estimator import BaroVarioEstimator
from imuhal_filters.vario.kf3_estimator import VarioKf3Estimator


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    register(BaroVarioEstimator)
    register(VarioKf3Estimator)
