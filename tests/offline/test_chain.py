"""Estimators chained offline (imuhal.offline.chain) repeat what the pipeline made live."""

from __future__ import annotations

from imuhal.core import samples as smp
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, Estimate, VerticalEstimate
from imuhal.offline.chain import instants_in_fusion_order, run_chain
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile


def test_the_seed_boards_chain_over_its_recorded_samples_gives_the_live_estimates() -> None:
    """AHRS -> vario and the barometer-only vario, the MAX21100 emitting each burst's gyro
    before its accelerometer, with the datasheet error models: the same estimates, to the
    bit, in the same order."""
    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, seed=3, sensor_errors=True) as pipeline:
        events = list(pipeline.events(6.0))
        streams = pipeline.streams
    samples = [e for e in events if isinstance(e, smp.Sample) and e.valid]
    live = [e for e in events if isinstance(e, Estimate)]
    fresh = [registry.estimators.get(c.estimator)(c.settings, instance=name)
             for name, c in profile.estimators.items()]
    for est, c in zip(fresh, profile.estimators.values(), strict=True):
        # what the pipeline bound into each: its input devices' stream specs
        est.bind([spec for device in (c.inputs or streams) if device in streams
                  for spec in streams[device]])
    inputs = {name: c.inputs for name, c in profile.estimators.items() if c.inputs is not None}

    offline = run_chain(fresh, samples, inputs=inputs)

    assert sum(isinstance(e, AttitudeEstimate) for e in live) > 1000
    assert sum(isinstance(e, VerticalEstimate) and e.source == "vario" for e in live) > 200
    assert offline == live


def test_each_instant_is_put_in_fusion_order_and_instants_keep_their_arrival_order() -> None:
    body = smp.Frame.BODY_NED
    gyro = smp.GyroSample(t_ns=2, device="imu", frame=body, gyro_rad_s=(0.0, 0.0, 0.0))
    accel = smp.AccelSample(t_ns=2, device="imu", frame=body, accel_m_s2=(0.0, 0.0, -9.8))
    mag = smp.MagSample(t_ns=2, device="mag", frame=body, mag_ut=(20.0, 0.0, 40.0))
    late_fix = smp.VelocitySample(t_ns=1, device="gps", velocity_ned_m_s=(1.0, 0.0, 0.0))
    baro = smp.PressureSample(t_ns=3, device="baro", pressure_pa=90000.0)

    ordered = list(instants_in_fusion_order([gyro, accel, mag, late_fix, baro]))

    assert ordered == [accel, mag, gyro, late_fix, baro]
