"""The "decoupled" estimator on the bundled seed paragliding board, against the emulator's truth.

The profile's AHRS is swapped for decoupled with the same settings (250 Hz, nominal airspeed
10 m/s, the chips' full scales). Emulated `thermal`, seed 1, ideal chips (as in
test_seed_board_turns.py), over 25-33 s while circling at about 18 deg of bank.
"""

from __future__ import annotations

import numpy as np
from tests.integration.test_seed_board_turns import WINDOW_S, _tilt_deg

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path


def test_decoupled_holds_the_horizon_in_the_thermal_turn() -> None:
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    ahrs = profile.estimators["ahrs"]
    profile = profile.model_copy(update={"estimators": {
        **profile.estimators,
        "ahrs": ahrs.model_copy(update={"estimator": "decoupled"})}})
    errors = []
    with open_emulated(profile, registry, scenario="thermal", seed=1,
                       sensor_errors=False) as pipeline:
        for event in pipeline.events(WINDOW_S[1]):
            if (isinstance(event, AttitudeEstimate) and event.source == "ahrs"
                    and event.t_ns >= WINDOW_S[0] * 1e9):
                assert pipeline.board is not None
                truth = pipeline.board.truth_at(event.t_ns)
                errors.append(_tilt_deg(event.q_body_to_ned, truth.q_body_to_ned))
    errors_deg = np.array(errors)
    assert errors_deg.size > 1000
    assert errors_deg.max() < 1.0
