"""Entry point of the vqf plugin: registers "vqf" when the optional ``vqf`` package is
installed (``pip install imuhal[vqf]``); without it the plugin registers nothing."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar


@hookimpl
def imuhal_register_estimators(register: Registrar) -> None:
    try:
        import vqf  # noqa: F401
    except ImportError:
        return
    from imuhal_filters.vqf.estimator import VqfEstimator

    register(VqfEstimator)
