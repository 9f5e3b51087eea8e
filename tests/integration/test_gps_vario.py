"""The seed GPS vario emulated end to end: its GNSS samples reach the estimators that
consume them (a third-party estimator registered here, as a plugin would), with timestamps
at the measurement epoch, and a GNSS fault leaves the rest of the board running."""

from __future__ import annotations

import types
from typing import Any, ClassVar

import numpy as np
import pytest

pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from tests.support.noise import noise_only_specs

from imuhal.core.samples import PositionSample, Sample, VelocitySample
from imuhal.emulation import open_emulated
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import Estimate, VerticalEstimate
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile


class GpsClimb(Estimator):
    """Climb rate from GNSS velocity alone (what a GPS-only vario shows)."""

    name: ClassVar[str] = "test-gps-climb"
    Settings = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (PositionSample, VelocitySample)

    def reset(self) -> None:
        self.positions = 0
        self.height_m = 0.0

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        if isinstance(item, PositionSample):
            self.positions += 1
            self.height_m = item.height_m
            return []
        assert isinstance(item, VelocitySample) and item.valid
        # the GNSS height as altitude: an estimate must be finite to reach the sinks
        return [VerticalEstimate(t_ns=item.t_ns, source=self.instance, altitude_m=self.height_m,
                                 climb_m_s=-item.velocity_ned_m_s[2])]

    def get_state(self) -> dict[str, Any]:
        return {"positions": self.positions}

    def set_state(self, state: dict[str, Any]) -> None:
        self.positions = state["positions"]


@hookimpl
def imuhal_register_estimators(register: Any) -> None:
    register(GpsClimb)


def _profile(registry: Any) -> Any:
    text = bundled_profiles()["seed-gps-vario.yaml"].read_text()
    text = text.replace("\nemulation:", "\n  gps-climb:\n    estimator: test-gps-climb\n"
                        "    inputs: [gps]\n\nemulation:")
    return parse_profile(text, "seed-gps-vario+gps-climb", registry)


@pytest.mark.slow
def test_gnss_samples_reach_an_estimator_and_its_climb_follows_the_truth() -> None:
    plugin = types.ModuleType("gps_climb_plugin")
    plugin.imuhal_register_estimators = imuhal_register_estimators  # type: ignore[attr-defined]
    registry = load_registry(extra=[("gps-climb", plugin)])
    profile = _profile(registry)
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        scenario = pipeline.board.scenario
        events = list(pipeline.events(40.0))
        summary = pipeline.summary()
    climbs = [e for e in events if isinstance(e, VerticalEstimate) and e.source == "gps-climb"]
    assert summary.estimates["gps-climb"] == len(climbs) > 150  # 5 Hz after the first fix
    err = [c.climb_m_s - scenario.truth(c.t_ns / 1e9).climb_m_s for c in climbs]
    # 3 x the receiver's 0.15 m/s speed accuracy, plus the epoch time known to one poll
    assert float(np.sqrt(np.mean(np.square(err)))) < 0.45 + 0.1
    assert summary.bus_errors["gps"] == 0 and summary.warnings == []


@pytest.mark.slow
def test_a_lost_fix_flags_gnss_samples_while_the_vario_runs_on() -> None:
    registry = load_registry()
    profile = parse_profile(bundled_profiles()["seed-gps-vario.yaml"].read_text(),
                            "seed-gps-vario", registry)
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        pipeline.board.emulators["gps"].lose_fix(10.0, 20.0)
        events = list(pipeline.events(30.0))
    gps = [e for e in events if isinstance(e, PositionSample)]
    during = [e for e in gps if 10.3e9 < e.t_ns < 19.8e9]
    after = [e for e in gps if e.t_ns > 20.3e9]
    assert during and not any(e.valid for e in during)
    assert after and all(e.valid for e in after)
    vario = [e for e in events if isinstance(e, VerticalEstimate) and 10e9 < e.t_ns < 20e9]
    assert len(vario) > 400  # the barometric vario never noticed


@pytest.mark.slow
def test_the_gps_varios_ahrs_compensates_turns_with_the_gnss_velocity() -> None:
    """The bundled profile feeds the receiver's velocity to the AHRS (flight's turn
    compensation: wind fitted while circling). Emulated `thermal`, seed 1, chips with their
    datasheet white noise only (ideal chips repeat one raw frame at rest, which the driver
    flags FROZEN, so the start-up gyro measurement never succeeded and its 15 s phase ate
    the first 70 GNSS epochs), over 25-40 s: measured 0.43 deg tilt RMS with the GNSS
    velocity, the accelerometer's correction at a mean weight of 0.38. With the compensation
    off the turns' centripetal acceleration is unmodelled and the soft gate (on the reading's
    whole disagreement with the attitude) shuts the accelerometer out of them (mean weight
    0.16); on these noise-only chips the gyro alone then holds the tilt (0.46 deg; 6.1 deg
    before the gate looked at the whole vector). Bounds: 1 deg RMS with; without, less than
    half the compensated weight."""
    from imuhal.estimation.outputs import AttitudeEstimate
    from imuhal.profile.loader import load_profile
    from imuhal_filters.common.quat import tilt_error_deg

    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)

    def fly(p: Any) -> tuple[float, float, dict[str, Any]]:
        errors, weights = [], []
        with open_emulated(p, registry, scenario="thermal", seed=1,
                           error_specs=noise_only_specs(p, registry)) as pipeline:
            for event in pipeline.events(40.0):
                if isinstance(event, AttitudeEstimate) and event.t_ns >= 25e9:
                    truth = pipeline.board.truth_at(event.t_ns)
                    errors.append(tilt_error_deg(event.q_body_to_ned,
                                                 tuple(truth.q_body_to_ned)))
                    weights.append(event.diagnostics["accel_weight"])
            ahrs = next(e for e in pipeline.estimators if e.name == "ahrs").estimator
            return (float(np.sqrt(np.mean(np.square(errors)))), float(np.mean(weights)),
                    ahrs.diagnostics())

    rms, weight, diag = fly(profile)
    turn = diag["turn_compensation"]
    assert turn["source"] == "velocity" and turn["velocity_samples"] > 150
    assert turn["wind_fits"] > 0
    ahrs = profile.estimators["ahrs"]
    off = profile.model_copy(update={"estimators": {**profile.estimators, "ahrs": ahrs.model_copy(
        update={"settings": {**ahrs.settings, "turn_compensation": False}})}})
    _, weight_off, _ = fly(off)
    assert rms < 1.0 and weight_off < 0.5 * weight
