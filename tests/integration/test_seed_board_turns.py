"""The bundled seed paragliding board holds the horizon in its first thermal turn.

The profile's AHRS (madgwick) compensates turns with the glider's trim airspeed (10 m/s).
Emulated `thermal`, seed 1, ideal chips (quantisation and range only: an uncalibrated
accelerometer's bias of about 3 deg would hide the filter's own error; docs/estimators.md has
the calibrated board): over 25-33 s, circling at about 18 deg of bank, the tilt error measured
0.15 deg RMS and 0.34 deg at worst, the accelerometer's correction at a mean weight of 0.43.
With the compensation turned off the turn's centripetal acceleration is unmodelled: the soft
gate, which weighs the reading's whole disagreement with the attitude, shuts the
accelerometer out (mean weight 0.022) and the gyro alone carries the attitude (0.70 deg RMS
on these ideal chips; before the gate looked at the whole vector, the filter followed the
centripetal acceleration: 7.8 deg). Bounds: 1 deg at worst with; without, a mean weight under
a quarter of the compensated one and more than 3 times the tilt RMS.
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


def _tilt_errors_deg(profile: BoardProfile) -> tuple[np.ndarray, float]:
    """The AHRS's tilt errors (deg) over WINDOW_S and its mean accelerometer weight."""
    registry = load_registry()
    errors, weights = [], []
    with open_emulated(profile, registry, scenario="thermal", seed=1,
                       sensor_errors=False) as pipeline:
        for event in pipeline.events(WINDOW_S[1]):
            if isinstance(event, AttitudeEstimate) and event.t_ns >= WINDOW_S[0] * 1e9:
                assert pipeline.board is not None
                truth = pipeline.board.truth_at(event.t_ns)
                errors.append(tilt_error_deg(event.q_body_to_ned, tuple(truth.q_body_to_ned)))
                weights.append(event.diagnostics["accel_weight"])
    return np.array(errors), float(np.mean(weights))


def test_the_seed_profile_compensates_the_turn_of_its_own_scenario() -> None:
    profile = load_profile(default_profile_path(), load_registry())
    ahrs = profile.estimators["ahrs"]
    uncompensated = profile.model_copy(update={"estimators": {
        **profile.estimators,
        "ahrs": ahrs.model_copy(update={"settings": {**ahrs.settings,
                                                     "turn_compensation": False}})}})
    with_compensation, weight = _tilt_errors_deg(profile)
    without, weight_without = _tilt_errors_deg(uncompensated)
    assert with_compensation.max() < 1.0
    assert weight_without < 0.25 * weight
    assert np.sqrt(np.mean(without**2)) > 3.0 * np.sqrt(np.mean(with_compensation**2))
