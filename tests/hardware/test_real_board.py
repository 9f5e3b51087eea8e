"""The same checks on real hardware, when a board is attached.

Set IMUHAL_HARDWARE_PROFILE to a profile whose buses exist on this machine (e.g. on a
Raspberry Pi with the seed board on SPI: profiles/seed-paraglider-vario.yaml) and keep the
board still; otherwise these tests are skipped.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from imuhal.core.samples import AccelSample, PressureSample, Sample
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

PROFILE = os.environ.get("IMUHAL_HARDWARE_PROFILE")
pytestmark = pytest.mark.skipif(not PROFILE, reason="set IMUHAL_HARDWARE_PROFILE to run on a "
                                "real board")


@pytest.fixture(scope="module")
def events() -> list[object]:
    registry = load_registry()
    profile = load_profile(PROFILE or "", registry)
    with Pipeline.open(profile, registry) as p:
        return list(p.events(2.0))


def test_every_device_produces_valid_samples(events: list[object]) -> None:
    registry = load_registry()
    profile = load_profile(PROFILE or "", registry)
    for device in profile.devices:
        valid = [e for e in events if isinstance(e, Sample) and e.device == device and e.valid]
        assert valid, f"{device}: no valid samples in 2 s"


def test_a_still_board_measures_one_g(events: list[object]) -> None:
    accel = [e.accel_m_s2 for e in events if isinstance(e, AccelSample) and e.valid]
    if not accel:
        pytest.skip("no accelerometer on this board")
    norm = float(np.mean([math.dist(a, (0, 0, 0)) for a in accel]))
    assert 9.0 < norm < 10.6  # uncalibrated chips: +-8 %


def test_pressure_is_atmospheric(events: list[object]) -> None:
    pressure = [e.pressure_pa for e in events if isinstance(e, PressureSample) and e.valid]
    if not pressure:
        pytest.skip("no barometer on this board")
    assert 30_000 < float(np.median(pressure)) < 110_000
