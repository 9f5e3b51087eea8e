"""The bundled GY-91's own AHRS (``decoupled`` with its defaults since issue 27 item 3),
flown as ``imuhal run --emulate`` flies it: the calibrations its file lacks measured first
on the emulated board (seed 1), then its profile's scenario, ``thermal``, through the launch.

Bound: issue 27's ``thermal`` tilt maximum, 3 deg including the launch (a target, not a fit).
Over these 12 s, which hold the launch's run-up (5 to 8 s, up to 5 m/s^2 of forward push the
profile does not model: it has no airspeed), `decoupled` stays within 1.1 deg (measured: 1.09
at 10.2 s); the Madgwick at beta 0.1 the profile ran before reached 4.17 deg at 7.75 s and
fails it (docs/estimators.md, "The GY-91's AHRS", over 300 s: 1.90 against 4.17).
"""

from __future__ import annotations

import pytest

from imuhal.calibrate.as_user import calibrate_emulated
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

FLIGHT_S = 12.0
TILT_MAX_DEG = 3.0


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def as_run(registry: Registry) -> BoardProfile:
    path = bundled_profiles()["gy91.yaml"]
    profile = load_profile(path, registry)
    return calibrate_emulated(profile, path.read_text(encoding="utf-8"), str(path), registry,
                              seed=1).profile


def test_the_gy91s_ahrs_holds_the_tilt_through_the_launch(registry: Registry) -> None:
    tilts = []
    with open_emulated(as_run(registry), registry, scenario="thermal", seed=1) as pipeline:
        world = pipeline.board.scenario  # type: ignore[union-attr]
        for e in pipeline.events(FLIGHT_S):
            if isinstance(e, AttitudeEstimate) and e.source == "ahrs":
                truth = world.truth(e.t_ns / 1e9).q_body_to_ned
                tilts.append(tilt_error_deg(e.q_body_to_ned, tuple(float(v) for v in truth)))
    assert len(tilts) > 0.9 * FLIGHT_S * 200  # the MPU-9250's 200 Hz, every one handed out
    assert max(tilts) <= TILT_MAX_DEG
