"""Kernel tests skip, one line each, anywhere but inside the guest tests/kernel/run.py boots;
inside it nothing may skip (a missing kernel interface there is a broken guest, not a pass)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from tests.kernel.guest import GUEST_ENV, outside_guest_reason

HERE = Path(__file__).resolve().parent
_skipped_in_guest: list[str] = []


def _ours(path: Path) -> bool:
    return HERE in Path(str(path)).resolve().parents


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    reason = outside_guest_reason()
    if reason is None:
        return
    skip = pytest.mark.skip(reason=reason)
    for item in items:
        if _ours(item.path):
            item.add_marker(skip)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.skipped and os.environ.get(GUEST_ENV) == "1" and \
            _ours(Path(report.location[0]).resolve()):
        _skipped_in_guest.append(report.nodeid)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _skipped_in_guest and session.exitstatus == 0:
        print(f"\nkernel tests skipped inside the guest (a failure there): "
              f"{', '.join(_skipped_in_guest)}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
