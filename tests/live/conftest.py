"""Fixtures of the live view's tests: the installed plugins and the bundled seed board."""

from __future__ import annotations

import pytest

from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile


@pytest.fixture(scope="session")
def plugins() -> Registry:
    return load_registry()


@pytest.fixture(scope="session")
def seed_board(plugins: Registry) -> BoardProfile:
    return load_profile(default_profile_path(), plugins)
