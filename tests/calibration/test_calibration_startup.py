"""Gyro offsets re-measured at start-up (``gyro_at_startup``): the measured offsets replace
the stored ones in memory only, events then flow calibrated in the body frame; a board that
never stays still keeps the stored offsets with a warning."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imuhal.core.samples import Frame, GyroSample
from imuhal.emulation import open_emulated
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile
from imuhal.sim.errors import SensorErrorSpec

DATA = Path(__file__).resolve().parent.parent / "data" / "calibration"
DPS = math.pi / 180.0
BIAS_DPS = (1.5, -0.7, 0.9)
SPEC = SensorErrorSpec.model_validate(
    {"gyro": {"noise_density": 0.005 * DPS, "bias": tuple(b * DPS for b in BIAS_DPS)}})
STARTUP = """    calibration:
      gyro: {offset_rad_s: [0.1, 0.1, 0.1]}
      gyro_at_startup: {samples: 100, retry_wait_s: 0.5, max_attempts: 2}
"""


@pytest.fixture(scope="module")
def chips() -> Registry:
    return load_registry()


def _profile(chips: Registry):  # type: ignore[no-untyped-def]
    text = (DATA / "seed-board.yaml").read_text()
    text = text.replace('    address: 0          # chip select 0\n    mount: "-Y-X-Z"\n',
                        '    address: 0          # chip select 0\n    mount: "-Y-X-Z"\n' + STARTUP)
    return parse_profile(text, "startup.yaml", chips)


def test_offsets_measured_at_start_up_replace_the_stored_ones(chips: Registry) -> None:
    with open_emulated(_profile(chips), chips, scenario="static",
                       error_specs={"imu": SPEC}) as p:
        events = list(p.events(3.0))
        stored = p.devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert stored is not None and stored.procedure == "gyro-at-startup"
    assert np.abs(np.array(stored.offset_rad_s) / DPS - BIAS_DPS).max() < 0.05
    gyros = [e for e in events if isinstance(e, GyroSample)]
    assert gyros and all(g.frame is Frame.BODY_NED for g in gyros)
    assert gyros[0].t_ns >= 0.39e9  # the first 100 samples at 250 Hz went to the measurement
    mean = np.mean([g.gyro_rad_s for g in gyros], axis=0) / DPS
    assert np.abs(mean).max() < 0.05  # at rest, calibrated: no rate left


def test_a_board_that_never_stays_still_keeps_the_stored_offsets(chips: Registry) -> None:
    with open_emulated(_profile(chips), chips, scenario="tumble",
                       scenario_params={"hold_s": 0.0}, error_specs={"imu": SPEC}) as p:
        list(p.events(3.0))
        stored = p.devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert stored is not None and stored.offset_rad_s == (0.1, 0.1, 0.1)
    assert any("start-up gyro offsets not measured" in w for w in p.warnings)


def test_a_gyro_frozen_for_a_moment_at_start_up_is_measured_from_live_data(
        chips: Registry) -> None:
    from imuhal.emulation.faults import FrozenData

    with open_emulated(_profile(chips), chips, scenario="static", error_specs={"imu": SPEC},
                       faults=[FrozenData(device="imu", start_s=0.0, end_s=0.3)]) as p:
        list(p.events(3.0))
        stored = p.devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert stored is not None and stored.procedure == "gyro-at-startup"
    assert np.abs(np.array(stored.offset_rad_s) / DPS - BIAS_DPS).max() < 0.05


def test_a_gyro_frozen_for_good_ends_the_start_up_phase_and_the_run_goes_on(
        chips: Registry) -> None:
    """A chip hung from power-up sends only FROZEN samples after its first repeats: the
    start-up phase waited for still samples for ever and the run yielded nothing. After 30 s
    of nothing but flagged samples it gives up, says why, and the run goes on."""
    from imuhal.core.samples import Sample
    from imuhal.emulation.faults import FrozenData

    with open_emulated(_profile(chips), chips, scenario="static", error_specs={"imu": SPEC},
                       faults=[FrozenData(device="imu", start_s=0.0)]) as p:
        events = [e for e in p.events(32.0) if isinstance(e, Sample) and e.device != "imu"]
        stored = p.devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert stored is not None and stored.offset_rad_s == (0.1, 0.1, 0.1)
    warning = next(w for w in p.warnings if "start-up gyro offsets not measured" in w)
    assert "FROZEN" in warning and "hung" in warning and "no measurements" in warning
    assert events and events[0].t_ns < 31.0e9  # the rest of the board's output flows
