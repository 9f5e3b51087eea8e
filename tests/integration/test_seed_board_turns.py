"""The bundled seed paragliding board holds the horizon in its first thermal turn.

The profile's AHRS (madgwick) compensates turns with the glider's trim airspeed (10 m/s).
Emulated `thermal`, seed 1, ideal chips (quantisation and range only: an uncalibrated
accelerometer's bias of about 3 deg would hide the filter's own error; docs/estimators.md has
the calibrated board): over 25-33 s, circling at about 18 deg of bank, the tilt error measured
0.14 deg RMS and 0.31 deg at worst; with the compensation turned off, 7.8 deg RMS and 9.1 deg
at worst. Bounds: 1 deg at worst with, more than 5 times the RMS without.
"""

from __future__ import annotations

import numpy as np

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

WINDOW_S = (25.0, 33.0)


def _tilt_errors_deg(profile: BoardProfile) -> np.ndarray:
    registry = load_registry()
    errors = []
    with open_emulated(profile, registry, scenario="thermal", seed=1,
                       sensor_errors=False) as pipeline:
        for event in pipeline.events(WINDOW_S[1]):
            if isinstance(event, AttitudeEstimate) and event.t_ns >= WINDOW_S[0] * 1e9:
                assert pipeline.board is not None
                truth = pipeline.board.truth_at(event.t_ns)
                errors.append(tilt_error_deg(event.q_body_to_ned, tuple(truth.q_body_to_ned)))
    return np.array(errors)


def test_the_seed_profile_compensates_the_turn_of_its_own_scenario() -> None:
    profile = load_profile(default_profile_path(), load_registry())
    ahrs = profile.estimators["ahrs"]
    uncompensated = profile.model_copy(update={"estimators": {
        **profile.estimators,
        "ahrs": ahrs.model_copy(update={"settings": {**ahrs.settings,
                                                     "turn_compensation": False}})}})
    with_compensation = _tilt_errors_deg(profile)
    without = _tilt_errors_deg(uncompensated)
    assert with_compensation.max() < 1.0
    assert np.sqrt(np.mean(without**2)) > 5.0 * np.sqrt(np.mean(with_compensation**2))
