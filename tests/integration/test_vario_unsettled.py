"""A variometer that has lost its barometer withholds its estimate (issue 26, the fault
matrix's unflagged wrong climb rates).

vario-kf3 (and baro-vario) return a RejectedEstimate flagged UNSETTLED instead of a value
while their innovation gate refused most altitudes of the last second, and vario-kf3 after
a restart after a gap until its own climb-rate uncertainty is small; a restart after a gap
keeps the accelerometer bias. Faults come through imuhal.emulation.faults on bundled boards.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import ChipAbsent, ChipReset, FaultSpec, WildValue, WrongPressure
from imuhal.estimation.outputs import (
    AttitudeEstimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal_filters.common.quat import tilt_error_deg

CLIMB_MARGIN_M_S = 3.0
SETTLE_S = 3.0
"""As the fault matrix (tests/benchmarks/fault_matrix.py): the filters start from zero climb."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _vario(registry: Registry, board: str, faults: list[FaultSpec], seconds: float
           ) -> tuple[list[tuple[VerticalEstimate, float]], list[RejectedEstimate], Any]:
    profile = load_profile(bundled_profiles()[board], registry)
    estimates, withheld = [], []
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        for event in pipeline.events(seconds):
            if getattr(event, "source", None) != "vario":
                continue
            if isinstance(event, VerticalEstimate):
                estimates.append((event, truth(event.t_ns / 1e9).climb_m_s))
            elif isinstance(event, RejectedEstimate):
                withheld.append(event)
        summary = pipeline.summary()
    return estimates, withheld, summary


def _wrong(estimates: list[tuple[VerticalEstimate, float]]) -> list[tuple[float, float, float]]:
    return [(e.t_ns / 1e9, e.climb_m_s, truth) for e, truth in estimates
            if e.t_ns / 1e9 > SETTLE_S and abs(e.climb_m_s - truth) > CLIMB_MARGIN_M_S]


def test_a_vario_whose_gate_refuses_most_altitudes_withholds_its_climb_rate(
        registry: Registry) -> None:
    """GY-91, a +300 Pa pressure in one measurement out of ten: the BMP280's IIR smears each
    over the next outputs, the gate refuses most altitudes and the filter coasted to a climb
    rate 6 m/s off, unflagged (355 such estimates in the matrix)."""
    # from 2 s: the start-up's own withholding (until about 1.4 s) is over
    faults: list[FaultSpec] = [WrongPressure(device="baro", start_s=2.0 + 0.2 * i,
                                             offset_pa=300.0) for i in range(40)]
    estimates, withheld, summary = _vario(registry, "gy91.yaml", faults, 10.0)
    assert _wrong(estimates) == []
    assert withheld and {w.flags for w in withheld} == {EstimateFlag.UNSETTLED}
    assert {w.estimator for w in withheld} == {"vario-kf3"}
    # withheld by the estimator itself: no failure of it, never disabled
    assert not [label for label in summary.contained if "vario" in label]
    spoke = min(e.t_ns for e, _ in estimates)
    assert spoke < 2e9  # between its start-up and the faults it speaks
    assert not [w for w in withheld if spoke < w.t_ns < 2e9]


def test_a_vario_restarted_after_a_gap_keeps_its_bias_and_withholds_until_it_knows_the_climb(
        registry: Registry) -> None:
    """seed-gps-vario, chip resets on every device: the barometer's outage restarted the
    filter in a 1 m/s sink from climb 0, and the bias ran to 13 m/s^2 and the climb rate 4 m/s
    off (the matrix's seed-gps-vario reset finding). The outage then came from the GNSS
    receiver's reconfiguration holding the thread 1.2 s; it no longer does (issue 26), so
    the barometer is unplugged as long."""
    faults: list[FaultSpec] = [ChipReset(device=d, start_s=t) for d, t in (
        ("imu", 3.25), ("imu", 7.75), ("mag", 5.5), ("baro", 5.5), ("gps", 5.5))]
    faults.append(ChipAbsent(device="baro", start_s=5.6, end_s=6.8))
    estimates, withheld, _ = _vario(registry, "seed-gps-vario.yaml", faults, 10.0)
    restarted = [e for e, _ in estimates if e.diagnostics["restarts_after_gap"]]
    assert restarted, "the barometer's outage restarts the filter"
    assert _wrong(estimates) == []
    assert withheld and all(w.flags == EstimateFlag.UNSETTLED for w in withheld)
    assert all(abs(e.accel_bias_m_s2 or 0.0) < 1.0 for e in restarted)


def test_one_wrong_pressure_is_gated_and_the_estimate_still_speaks(registry: Registry) -> None:
    """The case the gate is for: one wrong altitude among fifty is refused and the estimate
    at it carries its value and ``altitude_gated`` (the soak's check)."""
    faults: list[FaultSpec] = [WrongPressure(device="baro", start_s=5.0, offset_pa=300.0)]
    estimates, withheld, summary = _vario(registry, "seed-paraglider-vario.yaml", faults, 7.0)
    spoke = min(e.t_ns for e, _ in estimates)
    assert [w for w in withheld if w.t_ns > spoke] == []  # only the start-up's
    assert any(e.diagnostics["altitude_gated"] for e, _ in estimates)
    assert not [label for label in summary.contained if "vario" in label]


RC_GYRO_FULL_SCALE_RAD_S = 17.453292519943297
"""seed-rc-vario's MAX21100 at +-1000 deg/s."""


def _ahrs_tilt_and_vario(registry: Registry, faults: list[FaultSpec], seconds: float
                         ) -> tuple[float, list[tuple[VerticalEstimate, float]], int]:
    """seed-rc-vario in its ``rc-flight``: the worst tilt error of the AHRS estimates after
    3 s (deg), the vario's estimates with the true climb rate, and how many estimates the
    vario withheld."""
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], registry)
    worst, estimates, withheld = 0.0, [], 0
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        for event in pipeline.events(seconds):
            t_s = getattr(event, "t_ns", 0) / 1e9
            if isinstance(event, AttitudeEstimate) and event.source == "ahrs" and t_s > 3.0:
                worst = max(worst, tilt_error_deg(event.q_body_to_ned,
                                                  tuple(truth(t_s).q_body_to_ned)))
            elif isinstance(event, RejectedEstimate) and event.source == "vario":
                withheld += 1
            elif isinstance(event, VerticalEstimate) and event.source == "vario":
                estimates.append((event, truth(t_s).climb_m_s))
    return worst, estimates, withheld


def test_a_clipped_gyro_word_on_the_take_off_run_does_not_pull_the_tilt_to_the_run_up(
        registry: Registry) -> None:
    """One wild pitch rate (1000 times the full scale, clipped by the chip, flagged
    SATURATED) as the take-off run starts: the angular-rate recovery used to pull the tilt
    towards an accelerometer reading the run-up's 1 g push, 46 deg off, and the vario
    integrated the wrong vertical acceleration (climb 4.5 m/s off, unflagged). A clip out of
    a rate well inside the range is no rotation: the recovery finds no more than it put in."""
    clip = [WildValue(device="imu", start_s=3.25, channel="gyro", axis=1,
                      value=1000.0 * RC_GYRO_FULL_SCALE_RAD_S)]
    worst, estimates, _ = _ahrs_tilt_and_vario(registry, clip, 8.0)
    clean, _, _ = _ahrs_tilt_and_vario(registry, [], 8.0)
    assert _wrong(estimates) == []
    # the clip's 5 deg at most, on the uncalibrated board's own error through the run-up
    assert worst < clean + 6.0


def test_an_ahrs_and_a_vario_without_a_usable_imu_withhold_rather_than_guess(
        registry: Registry) -> None:
    """Wild values on the MAX21100 every 0.15 s (gyro, accelerometer and temperature in
    turn): the chip's filters keep nearly every IMU sample flagged settling, so the vario
    predicts through the take-off's climb-out almost without acceleration. It lagged the
    truth by more than 3 m/s, unflagged; now its climb rate's uncertainty grows by a g of
    unmeasured acceleration and it withholds until the altitudes have pinned it down."""
    channels = ("gyro", "accel", "temperature")
    scale = {"gyro": RC_GYRO_FULL_SCALE_RAD_S, "accel": 8 * 9.80665, "temperature": 1e5}
    faults: list[FaultSpec] = [
        WildValue(device="imu", start_s=0.75 + 0.05 * i, channel=channels[i % 3],
                  axis=(i // 3) % 3, value=1000.0 * scale[channels[i % 3]])
        for i in range(180)]
    _, estimates, withheld = _ahrs_tilt_and_vario(registry, faults, 10.0)
    assert _wrong(estimates) == []
    assert withheld > 0


def test_a_clipped_gyro_word_never_turns_the_in_flight_accelerometer_learner(
        registry: Registry) -> None:
    """seed-gps-vario learns its accelerometer in flight by default (it has a GNSS velocity).
    The fault matrix's 10 % `wild_value` on its IMU (every 0.05 s an accelerometer, gyro or
    temperature measurement 1000 times the full scale) gave 46 climb rates up to 3.1 m/s off
    the truth, unflagged, since learning became the default: the learner's own attitude
    integrated the gyro words clipped at the rail that reach the AHRS flagged SATURATED (its
    angular-rate recovery), each a turn of the full scale for a sample, and fitted an
    accelerometer offset to the tilt that left."""
    wild = [("accel", 0, 1000 * 4 * 9.80665), ("gyro", 1, 1000 * math.radians(1000)),
            ("temperature", 2, 1e8)]
    faults: list[FaultSpec] = [
        WildValue(device="imu", channel=wild[i % 3][0], axis=wild[i % 3][1],
                  value=wild[i % 3][2], start_s=round(1.025 + 0.05 * i, 4))
        for i in range(180)]
    estimates, _, _ = _vario(registry, "seed-gps-vario.yaml", faults, 10.0)
    assert estimates and _wrong(estimates) == []
