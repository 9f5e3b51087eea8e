"""Estimators chained offline (imuhal.offline.chain) repeat what the pipeline made live."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any, ClassVar

from tests.support.chain import offline_estimates

from imuhal.core import samples as smp
from imuhal.core.samples import Frame, GyroSample, Sample
from imuhal.emulation import open_emulated
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import (
    AttitudeEstimate,
    Estimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.offline.chain import EstimatorChain, instants_in_fusion_order
from imuhal.offline.csv_output import write_estimates
from imuhal.offline.runner import feed
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
    samples = [e for e in events if isinstance(e, smp.Sample) and e.valid]
    live = [e for e in events if isinstance(e, Estimate)]
    offline = offline_estimates(registry, profile, pipeline.streams, samples)

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


class _NanAttitude(Estimator):
    """An AHRS gone wrong: every second gyro sample gives a NaN quaternion."""

    name: ClassVar[str] = "nan-attitude"
    Settings: ClassVar[type[EstimatorSettings]] = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample,)

    def reset(self) -> None:
        self.n = 0

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        self.n += 1
        w = math.nan if self.n % 2 == 0 else 1.0
        return [AttitudeEstimate(t_ns=item.t_ns, source=self.instance,
                                 q_body_to_ned=(w, 0.0, 0.0, 0.0))]

    def get_state(self) -> dict[str, Any]:
        return {"n": self.n}

    def set_state(self, state: dict[str, Any]) -> None:
        self.n = state["n"]


class _Listener(Estimator):
    """Records every attitude estimate it is handed."""

    name: ClassVar[str] = "listener"
    Settings: ClassVar[type[EstimatorSettings]] = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (AttitudeEstimate,)

    def reset(self) -> None:
        self.seen: list[AttitudeEstimate] = []

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        assert isinstance(item, AttitudeEstimate)
        self.seen.append(item)
        return []

    def get_state(self) -> dict[str, Any]:
        return {}

    def set_state(self, state: dict[str, Any]) -> None:
        pass


NAN_QUATERNION = EstimateFlag.NOT_FINITE | EstimateFlag.NOT_NORMALISABLE
"""What a NaN quaternion is: NaN compares False with any norm bound."""


def _gyros(n: int) -> list[GyroSample]:
    return [GyroSample(t_ns=i * 1_000_000, device="imu", frame=Frame.BODY_NED,
                       gyro_rad_s=(0.0, 0.0, 0.0)) for i in range(1, n + 1)]


def test_the_chain_refuses_an_estimate_that_is_not_finite_before_anyone_sees_it() -> None:
    """As live (imuhal.pipeline.containment): the refused estimate becomes a
    RejectedEstimate naming its estimator, counted, and the estimator behind gets none."""
    ahrs, listener = _NanAttitude(instance="ahrs"), _Listener(instance="listener")
    chain = EstimatorChain([ahrs, listener])
    out: list[Estimate] = []
    for s in _gyros(4):
        chain.process(s, out)
    refused = [e for e in out if isinstance(e, RejectedEstimate)]
    assert [(e.t_ns, e.kind, e.flags, e.estimator) for e in refused] == [
        (2_000_000, "attitude", NAN_QUATERNION, "nan-attitude"),
        (4_000_000, "attitude", NAN_QUATERNION, "nan-attitude")]
    assert [e.t_ns for e in listener.seen] == [1_000_000, 3_000_000]
    assert chain.rejected == {"ahrs": 2}


def test_an_estimator_run_alone_offline_has_its_refused_estimates_replaced_too() -> None:
    out = feed(_NanAttitude(instance="ahrs"), _gyros(3))
    assert [type(e).__name__ for e in out] == [
        "AttitudeEstimate", "RejectedEstimate", "AttitudeEstimate"]


def test_a_refused_estimate_is_a_row_with_its_flags_and_no_value(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    write_estimates(path, feed(_NanAttitude(instance="ahrs"), _gyros(2)))
    rows = list(csv.DictReader(path.open()))
    assert rows[1]["flags"] == str(int(NAN_QUATERNION))
    assert rows[1]["qw"] == "" and rows[0]["qw"] == "1.0"
