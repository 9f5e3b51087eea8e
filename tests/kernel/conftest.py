"""Kernel tests skip, one line each, anywhere but inside the guest tests/kernel/run.py boots."""

from __future__ import annotations

from pathlib import Path

import pytest
from tests.kernel.guest import outside_guest_reason

HERE = Path(__file__).resolve().parent


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    reason = outside_guest_reason()
    if reason is None:
        return
    skip = pytest.mark.skip(reason=reason)
    for item in items:
        if HERE in Path(str(item.path)).resolve().parents:
            item.add_marker(skip)
