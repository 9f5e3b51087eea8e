"""Fusion does not depend on the order drivers emit samples in: the pipeline hands each
instant's samples to the estimators in one documented order, the offline runner uses the
same rule, so an estimator fed the recorded valid samples offline repeats the live run."""

from __future__ import annotations

from imuhal.core.samples import AccelSample, GyroSample, MagSample
from imuhal.emulation import open_emulated
from imuhal.estimation.ordering import fusion_order
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path


def test_the_seed_board_ahrs_repeats_offline_from_the_samples_it_was_fed() -> None:
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, seed=4) as p:
        events = list(p.events(3.0))
    live = [e for e in events if isinstance(e, AttitudeEstimate) and e.source == "ahrs"]
    fed = [e for e in events if isinstance(e, (GyroSample, AccelSample, MagSample))
           and e.valid and e.device in ("imu", "mag")]
    ahrs_cfg = profile.estimators["ahrs"]
    offline = registry.estimators.get(ahrs_cfg.estimator)(ahrs_cfg.settings, instance="ahrs")
    # the MAX21100 driver emits each burst's gyro before its accelerometer: shuffle further
    replayed = [out for s in fusion_order(reversed(fed), {"imu": 0, "mag": 1})
                for out in offline.process(s)]
    assert len(live) > 500
    assert replayed == live

