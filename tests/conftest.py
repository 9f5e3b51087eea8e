"""Fixtures shared by the core test areas."""

from __future__ import annotations

import pytest
from tests.support import testchip
from tests.support.kernels import aot_kernel_dir, compiled_backend  # noqa: F401 - fixtures

from imuhal.plugins import builtin_buses as bus_plugin
from imuhal.plugins import builtin_scenarios as sim_plugin
from imuhal.plugins.manager import Registry, load_registry


@pytest.fixture(scope="session")
def registry() -> Registry:
    """Core's own plugins (bus kinds, scenarios) plus the fictional test chip: core tests do
    not depend on any real chip or filter plugin."""
    return load_registry(
        entry_point_plugins=False,
        extra=[("buses", bus_plugin), ("scenarios", sim_plugin), ("testchip", testchip)],
    )
