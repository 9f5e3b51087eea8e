"""Fixtures shared by the core test areas."""

from __future__ import annotations

import pytest

from imuhal.plugins.manager import Registry, load_registry
from tests.support import testchip


@pytest.fixture(scope="session")
def registry() -> Registry:
    """The installed plugins (built-ins via entry points) plus the fictional test chip."""
    return load_registry(extra=[("testchip", testchip)])
