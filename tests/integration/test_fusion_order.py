"""Fusion does not depend on the order drivers emit samples in: the pipeline hands each
instant's samples to the estimators in one documented order, the offline runner uses the
same rule, so an estimator fed the recorded valid samples offline repeats the live run."""

from __future__ import annotations

from pathlib import Path

from imuhal.core.samples import AccelSample, GyroSample, MagSample
from imuhal.emulation import open_emulated
from imuhal.estimation.ordering import fusion_order
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.offline.csv_input import read_sample_csv
from imuhal.offline.runner import imu_events
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile


def test_the_seed_board_ahrs_repeats_offline_from_the_samples_it_was_fed() -> None:
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, seed=4) as p:
        events = list(p.events(3.0))
        streams = [spec for device in ("imu", "mag") for spec in p.streams[device]]
    live = [e for e in events if isinstance(e, AttitudeEstimate) and e.source == "ahrs"]
    fed = [e for e in events if isinstance(e, (GyroSample, AccelSample, MagSample))
           and e.valid and e.device in ("imu", "mag")]
    ahrs_cfg = profile.estimators["ahrs"]
    offline = registry.estimators.get(ahrs_cfg.estimator)(ahrs_cfg.settings, instance="ahrs")
    offline.bind(streams)  # the period and limits the live one took from its inputs' streams
    # the MAX21100 driver emits each burst's gyro before its accelerometer: shuffle further
    replayed = [out for s in fusion_order(reversed(fed), {"imu": 0, "mag": 1})
                for out in offline.process(s)]
    assert len(live) > 500
    assert replayed == live



def test_the_offline_runner_feeds_each_row_in_fusion_order(tmp_path: Path) -> None:
    path = tmp_path / "imu.csv"
    path.write_text("t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2,mx_ut,my_ut,mz_ut,"
                    "pressure_pa\n"
                    "0.0,0.1,0,0,0,0,-9.8,20,0,40,90000\n0.004,0.1,0,0,0,0,-9.8,,,,\n")
    fed = list(imu_events(read_sample_csv(path)))
    assert [type(s).__name__ for s in fed] == ["AccelSample", "MagSample", "PressureSample",
                                               "GyroSample", "AccelSample", "GyroSample"]
    assert fed == fusion_order(reversed(fed))
