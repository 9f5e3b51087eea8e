"""Saturation is recovered, not a gap: a rotation faster than the gyro's configured range
(the ``tumble`` scenario, one quick roll, on the seed board with its gyro set to +-250 deg/s)
is integrated clipped at the stream's full scale and the tilt is pulled back with Fusion's
angular-rate recovery; dropping the clipped samples leaves a tilt error for many seconds.
A clip the rate did not ramp into (out of a rate well inside the range: a corrupt word or a
shock, no rotation) is dropped."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.quantities import Quantity
from imuhal.core.samples import AccelSample, Frame, GyroSample, SampleFlag
from imuhal.core.streams import StreamSpec
from imuhal.emulation.open import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, EstimateFlag, RejectedEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile
from imuhal_filters.common.ahrs import _tilt_pulled
from imuhal_filters.common.quat import tilt_error_deg

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
QUICK_ROLL = {"axes": [[1.0, 0.0, 0.0]], "rotation_s": 0.8, "ramp_s": 0.2, "hold_s": 2.0,
              "free_tumble_s": 0.0}
"""One full roll in 0.8 s after 2 s still: up to about 10 rad/s, beyond +-250 deg/s
(4.4 rad/s) for about 0.6 s."""
ROLL_ENDS_S = 2.8
AFTER_S = (0.5, 2.0)
"""The window after the roll where the attitude error is judged (s after it ends)."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _fly(registry: Registry, estimator: str, saturation: str, after_s: float = AFTER_S[1]
         ) -> tuple[np.ndarray, dict[str, object]]:
    """(t_s, tilt error deg) of the AHRS's estimates handed out until ``after_s`` after the
    roll, and its diagnostics at the end."""
    text = PROFILE.read_text().replace("gyro_range_dps: 500", "gyro_range_dps: 250")
    text = text.replace("estimator: madgwick ", f"estimator: {estimator} ")
    text = text.replace("nominal_airspeed_m_s: 10\n",
                        f"nominal_airspeed_m_s: 10\n      gyro_saturation: {saturation}\n")
    profile = parse_profile(text, "quick-roll", registry)
    truth = registry.scenarios.get("tumble")(QUICK_ROLL, seed=3)
    errors = []
    with open_emulated(profile, registry, scenario="tumble", scenario_params=QUICK_ROLL,
                       seed=3) as pipeline:
        for event in pipeline.events(ROLL_ENDS_S + after_s):
            if isinstance(event, AttitudeEstimate) and event.source == "ahrs":
                t = event.t_ns / 1e9
                errors.append((t, tilt_error_deg(event.q_body_to_ned,
                                                 tuple(truth.truth(t).q_body_to_ned))))
        ahrs = next(r.estimator for r in pipeline.estimators if r.name == "ahrs")
        return np.array(errors), ahrs.diagnostics()


def _after_the_roll(errors: np.ndarray) -> np.ndarray:
    """The tilt errors (deg) of the estimates in the window after the roll."""
    t = errors[:, 0]
    window = (t >= ROLL_ENDS_S + AFTER_S[0]) & (t <= ROLL_ENDS_S + AFTER_S[1])
    return errors[window, 1]  # type: ignore[no-any-return]


def _worst_after_the_roll(errors: np.ndarray) -> float:
    return float(_after_the_roll(errors).max())


@pytest.mark.parametrize("estimator", ["madgwick", "mahony"])
def test_a_rotation_beyond_the_range_is_recovered_within_a_degree(
        registry: Registry, estimator: str) -> None:
    recovered, diag = _fly(registry, estimator, "recover")
    dropped, _ = _fly(registry, estimator, "drop")
    assert _worst_after_the_roll(recovered) < 1.0
    # what dropping the clipped samples leaves: the roll unmeasured, so the attitude is
    # withheld until the accelerometer checks it, or many degrees off
    after = _after_the_roll(dropped)
    assert after.size == 0 or after.max() > 5.0
    recovery = diag["angular_rate_recovery"]
    assert recovery["recoveries"] == 1 and recovery["clipped_samples"] > 50  # type: ignore[index]
    # the roll ramped into the rail: no clip of it is taken for a corrupt word
    assert "unramped_clips" not in recovery  # type: ignore[operator]
    assert diag["invalid"]["gyro"] == 0  # type: ignore[index]


GYRO_HZ = 250
"""The seed board's gyro rate (its profile's ``gyro_odr_hz``): one estimate per sample."""


@pytest.mark.parametrize("estimator", ["decoupled", "vqf"])
def test_a_filter_whose_kernel_keeps_the_attitude_is_reseated_and_recovers_within_a_degree(
        registry: Registry, estimator: str) -> None:
    # decoupled's and VQF's kernels keep their attitude, so the recovery cannot pull their
    # tilt: they integrated the clipped roll and were 168 (decoupled) and 118 deg (VQF) off
    # when the recovery ran out; then withheld until the accelerometer agreed, a gap of
    # seconds. The recovery re-seats their inclination from the accelerometer (reading
    # 1 g) instead, and they are handed out, within a degree, as Madgwick is.
    if estimator == "vqf":
        pytest.importorskip("vqf", reason="the vqf estimator needs the vqf package")
    errors, diag = _fly(registry, estimator, "recover")
    after = _after_the_roll(errors)
    window = round((AFTER_S[1] - AFTER_S[0]) * GYRO_HZ)
    assert after.size >= 0.9 * window  # handed out, not withheld (measured: all of them)
    assert after.max() < 1.0  # measured 0.39 (decoupled), 0.58 deg (VQF)
    recovery = diag["angular_rate_recovery"]
    assert recovery["recoveries"] == 1 and recovery["reseats"] > 0  # type: ignore[index]


def test_without_a_gyro_stream_a_clipped_sample_is_dropped_and_counted(
        registry: Registry) -> None:
    ahrs = registry.estimators.get("madgwick")({"initial_attitude": "identity"})
    clipped = GyroSample(t_ns=1, device="imu", flags=SampleFlag.SATURATED,
                         frame=Frame.BODY_NED, gyro_rad_s=(9.0, 0.0, 0.0))
    assert ahrs.process(clipped) == []
    assert ahrs.diagnostics()["invalid"]["gyro"] == 1


def test_the_tilt_pull_turns_the_predicted_gravity_towards_the_measured() -> None:
    rolled = (np.cos(np.radians(10)), np.sin(np.radians(10)), 0.0, 0.0)  # 20 deg of roll
    level = (1.0, 0.0, 0.0, 0.0)
    pulled, _ = _tilt_pulled(tuple(rolled), (0.0, 0.0, 1.0), 0.1)  # type: ignore[arg-type]
    before, after = tilt_error_deg(rolled, level), tilt_error_deg(pulled, level)
    assert after < before
    # a small pull turns by the gain times the sine of the error
    assert before - after == pytest.approx(np.degrees(0.1 * np.sin(np.radians(20))), rel=0.05)


def test_a_reading_only_out_of_range_is_no_clip_and_is_dropped(registry: Registry) -> None:
    ahrs = registry.estimators.get("madgwick")({"initial_attitude": "identity"})
    ahrs.bind(_gyro_stream())
    corrupt = GyroSample(t_ns=1, device="imu", flags=SampleFlag.OUT_OF_RANGE,
                         frame=Frame.BODY_NED, gyro_rad_s=(9.0, 0.0, 0.0))
    assert ahrs.process(corrupt) == []
    diag = ahrs.diagnostics()
    assert diag["invalid"]["gyro"] == 1
    assert diag["angular_rate_recovery"]["clipped_samples"] == 0


def _identity_madgwick(registry: Registry, rate_hz: float = 250.0) -> Any:
    """A Madgwick AHRS that only integrates (beta 0, identity start, nominal steps), bound
    to a +-250 deg/s (4.363 rad/s) gyro stream at ``rate_hz``."""
    ahrs = registry.estimators.get("madgwick")({"initial_attitude": "identity", "beta": 0.0,
                                                "dt_from_timestamps": False})
    ahrs.bind(_gyro_stream(rate_hz))
    return ahrs


def _gyro(t_ns: int, rate_rad_s: tuple[float, float, float],
          flags: SampleFlag = SampleFlag.OK) -> GyroSample:
    return GyroSample(t_ns=t_ns, device="imu", flags=flags, frame=Frame.BODY_NED,
                      gyro_rad_s=rate_rad_s)


CLIP = SampleFlag.SATURATED | SampleFlag.OUT_OF_RANGE


def _roll_deg(ahrs: Any) -> float:
    """The roll (deg) of an attitude that has only rolled."""
    w, x, _, _ = ahrs.quaternion
    return float(np.degrees(2.0 * np.arctan2(x, w)))


def test_a_saturated_reading_the_rate_ramped_into_is_integrated_at_the_full_scale(
        registry: Registry) -> None:
    """A fast roll at 3 rad/s (over half the +-4.363 rad/s range) that goes on beyond the
    range: its clipped reading is a rotation, integrated at the full scale."""
    ahrs = _identity_madgwick(registry)
    ahrs.process(_gyro(4_000_000, (3.0, 0.0, 0.0)))
    # no accelerometer checks the attitude: the estimate is withheld, the rotation kept
    (estimate,) = ahrs.process(_gyro(8_000_000, (4.5, 0.0, 0.0), CLIP))
    assert isinstance(estimate, RejectedEstimate)
    # measured, then clipped: one 4 ms step each
    assert _roll_deg(ahrs) == pytest.approx(np.degrees(3.0 * 0.004) + 250.0 * 0.004,
                                            rel=1e-4)
    diag = ahrs.diagnostics()
    assert diag["angular_rate_recovery"]["active"] is True
    assert diag["angular_rate_recovery"]["clipped_samples"] == 1
    assert diag["invalid"]["gyro"] == 0


def test_a_saturated_reading_out_of_rest_is_dropped_not_integrated(
        registry: Registry) -> None:
    """Issue 26 (the fault matrix at 10 % ``wild_value``: gy91 handed out 220 of 923
    attitudes more than 10 deg off in the ``thermal`` launch run): a word at the rail
    straight after a still gyro would be a rate grown by the whole range in 4 ms
    (62,500 deg/s^2), no rotation. It is dropped and counted, no recovery starts, and the
    attitude does not move."""
    ahrs = _identity_madgwick(registry)
    ahrs.process(_gyro(4_000_000, (0.0, 0.0, 0.0)))
    assert ahrs.process(_gyro(8_000_000, (4.5, 0.0, 0.0), CLIP)) == []
    diag = ahrs.diagnostics()
    assert diag["angular_rate_recovery"]["unramped_clips"] == 1
    assert diag["angular_rate_recovery"]["clipped_samples"] == 0
    assert diag["angular_rate_recovery"]["active"] is False
    assert diag["invalid"]["gyro"] == 1
    (estimate,) = ahrs.process(_gyro(12_000_000, (0.0, 0.0, 0.0)))
    assert isinstance(estimate, AttitudeEstimate)
    assert estimate.q_body_to_ned == pytest.approx((1.0, 0.0, 0.0, 0.0), abs=1e-12)


def test_a_clip_against_the_direction_of_the_last_rate_is_dropped(
        registry: Registry) -> None:
    """A fast roll at +3 rad/s, then a word at the negative rail: the rate would have
    swung by 1.7 times the range in one sample, so it ramped into nothing."""
    ahrs = _identity_madgwick(registry)
    ahrs.process(_gyro(4_000_000, (3.0, 0.0, 0.0)))
    assert ahrs.process(_gyro(8_000_000, (-4.5, 0.0, 0.0), CLIP)) == []
    assert ahrs.diagnostics()["angular_rate_recovery"]["unramped_clips"] == 1


def test_a_slow_gyro_integrates_a_clip_out_of_rest(registry: Registry) -> None:
    """At 25 Hz one sample period at MAX_ANGULAR_ACCEL_RAD_S2 spans more than the whole
    +-250 deg/s range: a vehicle can reach the rail from rest between two samples, so the
    clip is a rotation and is integrated."""
    ahrs = _identity_madgwick(registry, rate_hz=25.0)
    ahrs.process(_gyro(40_000_000, (0.0, 0.0, 0.0)))
    ahrs.process(_gyro(80_000_000, (4.5, 0.0, 0.0), CLIP))
    # 10 deg in one step, integrated to first order (the quaternion's tangent step)
    assert _roll_deg(ahrs) == pytest.approx(np.degrees(2 * np.arctan(np.radians(250.0) * 0.02)),
                                            rel=1e-6)
    assert ahrs.diagnostics()["angular_rate_recovery"]["clipped_samples"] == 1


def _gyro_stream(rate_hz: float = 250.0) -> list[StreamSpec]:
    return [StreamSpec("imu", Quantity.GYRO, Frame.SENSOR, rate_hz,
                       full_scale=float(np.radians(250.0)))]


def _feed(ahrs: Any, t0_s: float, t1_s: float, *, accel_m_s2: tuple[float, float, float],
          gyro_flags: SampleFlag = SampleFlag.OK,
          gyro_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> list[Any]:
    """Gyro samples reading ``gyro_rad_s`` (still by default) at 100 Hz from t0_s to t1_s
    (flagged as given), each after an accelerometer sample reading ``accel_m_s2`` (body
    NED); the estimates they give."""
    out: list[Any] = []
    for k in range(round((t1_s - t0_s) * 100)):
        t_ns = round((t0_s + k / 100) * 1e9)
        ahrs.process(AccelSample(t_ns=t_ns, device="imu", flags=SampleFlag.OK,
                                 frame=Frame.BODY_NED, accel_m_s2=accel_m_s2))
        out += ahrs.process(GyroSample(t_ns=t_ns + 1, device="imu", flags=gyro_flags,
                                       frame=Frame.BODY_NED, gyro_rad_s=gyro_rad_s))
    return out


LEVEL = (0.0, 0.0, -STANDARD_GRAVITY_M_S2)
ROLLED_20 = (0.0, -STANDARD_GRAVITY_M_S2 * np.sin(np.radians(20)),
             -STANDARD_GRAVITY_M_S2 * np.cos(np.radians(20)))
"""What a still accelerometer reads level, and rolled 20 deg right (body NED)."""


def _madgwick(registry: Registry) -> Any:
    return registry.estimators.get("madgwick")({"use_mag": False, "beta": 0.5,
                                                "accel_soft_gate_g": None,
                                                "sample_period_s": 0.01})


def _withheld(estimates: list[Any]) -> int:
    return sum(isinstance(e, RejectedEstimate) and bool(e.flags & EstimateFlag.UNSETTLED)
               for e in estimates)


def test_an_attitude_that_missed_a_rotation_is_withheld_until_the_accelerometer_agrees(
        registry: Registry) -> None:
    """Issue 26 (the soak, seed-rc-vario): 0.5 s of invalid gyro samples hid a 20 deg
    roll; the filter's first estimates after them would be 20 deg off, so they are
    withheld (UNSETTLED) until the accelerometer, reading 1 g, agrees within 5 deg."""
    ahrs = _madgwick(registry)
    assert _withheld(_feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)) == 0
    _feed(ahrs, 1.0, 1.5, accel_m_s2=ROLLED_20, gyro_flags=SampleFlag.BLANK)
    after = _feed(ahrs, 1.5, 6.0, accel_m_s2=ROLLED_20)
    first_out = next(i for i, e in enumerate(after) if isinstance(e, AttitudeEstimate))
    assert first_out > 0 and _withheld(after[:first_out]) == first_out
    released = after[first_out]
    assert abs(tilt_error_deg(released.q_body_to_ned,
                              (np.cos(np.radians(10)), np.sin(np.radians(10)), 0.0, 0.0))) \
        <= 5.01
    assert all(isinstance(e, AttitudeEstimate) for e in after[first_out:])


def test_a_short_gap_or_an_unchanged_attitude_is_not_withheld(registry: Registry) -> None:
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    # under max_dt_s (0.1 s) of dropped samples: the filter steps on as usual
    _feed(ahrs, 1.0, 1.05, accel_m_s2=ROLLED_20, gyro_flags=SampleFlag.BLANK)
    assert _withheld(_feed(ahrs, 1.05, 1.5, accel_m_s2=ROLLED_20)) == 0
    # a long gap in which nothing turned: the accelerometer confirms the attitude at once
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    _feed(ahrs, 1.0, 1.5, accel_m_s2=LEVEL, gyro_flags=SampleFlag.BLANK)
    assert _withheld(_feed(ahrs, 1.5, 2.0, accel_m_s2=LEVEL)) == 0


G = STANDARD_GRAVITY_M_S2
PUSH = (0.5 * G, 0.0, -G)
"""A level take-off run's accelerometer: half a g of push forward (1.12 g in all, so no
reading is gravity alone)."""


def test_a_span_across_which_the_push_and_the_rate_went_on_is_handed_out_at_once(
        registry: Registry) -> None:
    """Issue 26 (seed-rc-vario's fault matrix): an IMU outage in the take-off run left the
    attitude withheld for the rest of the flight, as the accelerometer never read 1 g. The
    push and the rate before the span and after it are the same, through an attitude
    that missed nothing: handed out at once."""
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=PUSH)
    _feed(ahrs, 1.0, 1.3, accel_m_s2=PUSH, gyro_flags=SampleFlag.BLANK)
    after = _feed(ahrs, 1.3, 2.0, accel_m_s2=PUSH)
    assert after and _withheld(after) == 0
    counts = ahrs.diagnostics()["angular_rate_recovery"]
    assert counts["unmeasured_spans"] == counts["unmeasured_continued"] == 1


def test_a_span_that_hid_a_roll_in_a_steady_push_is_withheld(registry: Registry) -> None:
    """The same push, but the aircraft rolled 20 deg while the gyro was out, and the rate
    is 0 again after it: the push comes out of the attitude turned, so the attitude is
    not handed out (and the accelerometer, reading 1.12 g, never confirms it)."""
    rolled = (0.5 * G, -G * float(np.sin(np.radians(20))), -G * float(np.cos(np.radians(20))))
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=PUSH)
    _feed(ahrs, 1.0, 1.3, accel_m_s2=rolled, gyro_flags=SampleFlag.BLANK)
    after = _feed(ahrs, 1.3, 2.0, accel_m_s2=rolled)
    assert after and _withheld(after) == len(after)
    assert "unmeasured_continued" not in ahrs.diagnostics()["angular_rate_recovery"]


def test_a_roll_into_a_coordinated_turn_inside_a_span_is_withheld(registry: Registry) -> None:
    """A roll into a coordinated 22 deg turn at 15 m/s while the gyro was out: the force
    stays along the body's z axis, so through the unrolled attitude it points where it
    did (1.08 g: within the magnitude the span check allows); the turn rate it leaves
    (g tan(bank) / speed, 8.3 deg/s) gives it away."""
    bank = np.radians(22.0)
    turn_rad_s = G * float(np.tan(bank)) / 15.0
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    turning = {"accel_m_s2": (0.0, 0.0, -G / float(np.cos(bank))),
               "gyro_rad_s": (0.0, turn_rad_s * float(np.sin(bank)),
                              turn_rad_s * float(np.cos(bank)))}
    _feed(ahrs, 1.0, 1.3, gyro_flags=SampleFlag.BLANK, **turning)  # type: ignore[arg-type]
    after = _feed(ahrs, 1.3, 1.8, **turning)  # type: ignore[arg-type]
    assert after and _withheld(after) == len(after)


def test_a_span_longer_than_max_gap_s_is_not_checked_by_the_push(registry: Registry) -> None:
    """Beyond ``max_gap_s`` (1 s) the step after the span does not integrate it, so the
    push going on says nothing of the attitude: withheld, as the accelerometer never reads
    1 g."""
    ahrs = _madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=PUSH)
    _feed(ahrs, 1.0, 2.5, accel_m_s2=PUSH, gyro_flags=SampleFlag.BLANK)
    after = _feed(ahrs, 2.5, 3.0, accel_m_s2=PUSH)
    assert after and _withheld(after) == len(after)


def test_a_recovery_whose_accelerometer_went_quiet_withholds(registry: Registry) -> None:
    """Issue 26 (seed-rc-vario's fault matrix, wild values on the IMU at 10 %): clipped
    gyro readings kept coming, each integrated at the full scale, while every
    accelerometer reading was flagged (the chip's filter settling after the wild ones).
    The recovery's last agreement with the accelerometer, from before its readings
    stopped, kept the estimates handed out: 177 deg off. An agreement holds only while
    the reading is fresh (``max_aux_age_s``, 0.1 s). Here a fast roll ramps into the rail
    (3 rad/s of +-4.363) each time, so its clips are integrated."""
    ahrs = registry.estimators.get("madgwick")({"use_mag": False})
    ahrs.bind(_gyro_stream())  # +-250 deg/s

    def rolled_into_the_rail(t_s: float, clips: int) -> list[Any]:
        """One measured sample at 3 rad/s, then ``clips`` clipped ones, 10 ms apart."""
        out = ahrs.process(_gyro(round(t_s * 1e9) + 1, (3.0, 0.0, 0.0)))
        for k in range(1, clips + 1):
            out += ahrs.process(_gyro(round((t_s + k / 100) * 1e9) + 1, (4.5, 0.0, 0.0),
                                      SampleFlag.SATURATED))
        return out

    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    rolled_into_the_rail(1.0, 1)
    assert ahrs.diagnostics()["angular_rate_recovery"]["recoveries"] == 1
    # the recovery pulls the roll's 4 deg back while the accelerometer reads level
    assert _withheld(_feed(ahrs, 1.02, 1.5, accel_m_s2=LEVEL)[-10:]) == 0
    # then the accelerometer falls silent (its last reading at 1.49 s) and, from 0.11 s
    # after that reading, the roll comes back into the rail: nothing checks the attitude
    quiet = rolled_into_the_rail(1.6, 49)
    assert len(quiet) == 50 and _withheld(quiet) == 50
    assert ahrs.diagnostics()["angular_rate_recovery"]["clipped_samples"] == 50


BANK_RAD = float(np.radians(22.0))
TURN_SPEED_M_S = 15.0


def _turning(bank_rad: float = BANK_RAD) -> dict[str, Any]:
    """A coordinated turn at ``bank_rad`` and TURN_SPEED_M_S: the accelerometer reads the
    load factor along the body's z axis (1/cos(bank) g), the gyro the turn rate
    g tan(bank) / speed about the vertical, seen in the banked body."""
    turn_rad_s = G * float(np.tan(bank_rad)) / TURN_SPEED_M_S
    return {"accel_m_s2": (0.0, 0.0, -G / float(np.cos(bank_rad))),
            "gyro_rad_s": (0.0, turn_rad_s * float(np.sin(bank_rad)),
                           turn_rad_s * float(np.cos(bank_rad)))}


def _compensating_madgwick(registry: Registry) -> Any:
    """``_madgwick`` compensating turns by the nominal airspeed TURN_SPEED_M_S."""
    return registry.estimators.get("madgwick")({"use_mag": False, "beta": 0.5,
                                                "accel_soft_gate_g": None,
                                                "sample_period_s": 0.01,
                                                "nominal_airspeed_m_s": TURN_SPEED_M_S})


def test_an_attitude_that_kept_its_bank_through_a_long_span_is_handed_out_in_the_turn(
        registry: Registry) -> None:
    """Issue 26 (gy91's soak: an attitude withheld for 33 s of thermal circling after a
    2 s IMU outage): the accelerometer of a turning glider reads 1.08 g at 22 deg of bank,
    never within 0.05 g of 1 g, so the check of the raw reading never passed. Less the
    turn's kinematic acceleration (what the filter fuses) it reads gravity, which confirms
    an attitude whose bank the span did not change at its first step."""
    ahrs = _compensating_madgwick(registry)
    _feed(ahrs, 0.0, 1.0, **_turning())
    # longer than max_gap_s (1 s): the span is stepped over, only the accelerometer checks
    _feed(ahrs, 1.0, 2.5, gyro_flags=SampleFlag.BLANK, **_turning())
    after = _feed(ahrs, 2.5, 3.0, **_turning())
    assert after and _withheld(after) == 0
    banked = (float(np.cos(BANK_RAD / 2)), float(np.sin(BANK_RAD / 2)), 0.0, 0.0)
    assert max(tilt_error_deg(e.q_body_to_ned, banked) for e in after) < 1.0
    assert ahrs.diagnostics()["angular_rate_recovery"]["unmeasured_spans"] == 1


def test_a_roll_into_a_compensated_turn_inside_a_span_is_withheld_until_it_agrees(
        registry: Registry) -> None:
    """The same turn entered while the gyro was out: less its kinematic acceleration the
    reading is gravity in the banked body, 22 deg from the level attitude's, so it does
    not confirm the attitude (and the turn rate it leaves stops the span check) until the
    filter's own correction has brought the bank within 5 deg."""
    ahrs = _compensating_madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    _feed(ahrs, 1.0, 1.3, gyro_flags=SampleFlag.BLANK, **_turning())
    after = _feed(ahrs, 1.3, 2.5, **_turning())
    first_out = next(i for i, e in enumerate(after) if isinstance(e, AttitudeEstimate))
    assert first_out > 10 and _withheld(after[:first_out]) == first_out
    banked = (float(np.cos(BANK_RAD / 2)), float(np.sin(BANK_RAD / 2)), 0.0, 0.0)
    assert tilt_error_deg(after[first_out].q_body_to_ned, banked) <= 5.01
    assert all(isinstance(e, AttitudeEstimate) for e in after[first_out:])


ROLLED_9 = (0.0, -STANDARD_GRAVITY_M_S2 * np.sin(np.radians(9)),
            -STANDARD_GRAVITY_M_S2 * np.cos(np.radians(9)))


def _slow_madgwick(registry: Registry) -> Any:
    """A filter that starts level and corrects its tilt at about half a degree a second:
    held against an accelerometer reading rolled 9 deg, it disagrees with it by 7-9 deg for
    many seconds (in the soak: an accelerometer offset and the turn compensation's error
    at the nominal airspeed that the filter never took up)."""
    return registry.estimators.get("madgwick")({"use_mag": False, "beta": 0.005,
                                                "accel_soft_gate_g": None,
                                                "sample_period_s": 0.01,
                                                "initial_attitude": "identity",
                                                "rest_detection": False})


def _roll_apart_deg(ahrs: Any, accel_m_s2: tuple[float, float, float]) -> float:
    g = tuple(-a / STANDARD_GRAVITY_M_S2 for a in accel_m_s2)
    return float(np.degrees(_tilt_pulled(tuple(ahrs.quaternion), g, 0.0)[1]))


def test_an_attitude_that_disagreed_as_steadily_before_a_long_span_is_handed_out_at_once(
        registry: Registry) -> None:
    """Issue 26 (the paraglider's 5 s `frozen` IMU window, 27 s withheld): a filter that
    disagreed with the accelerometer by a steady 8-9 deg before the span never came within
    the 5 deg the check after a span asks, and withheld until the flight changed. Its
    disagreement after the span is the one it had before, the filter's own, handed out
    before the span: it is handed out at once."""
    ahrs = _slow_madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=ROLLED_9)
    assert 7.0 < _roll_apart_deg(ahrs, ROLLED_9) < 9.0  # beyond the 5 deg check
    _feed(ahrs, 1.0, 3.0, accel_m_s2=ROLLED_9, gyro_flags=SampleFlag.FROZEN)
    after = _feed(ahrs, 3.0, 3.5, accel_m_s2=ROLLED_9)
    assert ahrs.diagnostics()["angular_rate_recovery"]["unmeasured_spans"] == 1
    assert _withheld(after) == 0


def test_an_attitude_whose_disagreement_the_span_changed_is_still_withheld(
        registry: Registry) -> None:
    """The same filter, and the vehicle rolled on from 9 to 20 deg inside the span: the
    disagreement after it (19 deg) is not the one before (8 deg), and the attitude stays
    withheld."""
    ahrs = _slow_madgwick(registry)
    _feed(ahrs, 0.0, 1.0, accel_m_s2=ROLLED_9)
    _feed(ahrs, 1.0, 3.0, accel_m_s2=ROLLED_20, gyro_flags=SampleFlag.FROZEN)
    after = _feed(ahrs, 3.0, 4.0, accel_m_s2=ROLLED_20)
    assert _withheld(after) == len(after) == 100


def test_a_recovery_is_not_confirmed_by_a_reading_far_from_1_g(registry: Registry) -> None:
    """The seed board's 8 s tumble beyond +-250 deg/s: Madgwick handed out attitudes up to
    14.3 deg off during a recovery, confirmed by a reading (compensated for the nominal
    airspeed's turn) of 4.2 g that pointed along the gravity they predicted. A load's
    direction is not gravity's: a reading far from 1 g neither pulls nor confirms, and the
    attitude is withheld until one near 1 g agrees."""
    ahrs = _madgwick(registry)
    ahrs.bind(_gyro_stream(100.0))  # +-250 deg/s, at _feed's rate
    _feed(ahrs, 0.0, 1.0, accel_m_s2=LEVEL)
    # a fast roll ramps into the rail: integrated clipped, the recovery starts
    ahrs.process(_gyro(1_000_000_001, (3.0, 0.0, 0.0)))
    ahrs.process(_gyro(1_010_000_001, (4.5, 0.0, 0.0), SampleFlag.SATURATED))
    assert ahrs.diagnostics()["angular_rate_recovery"]["recoveries"] == 1
    # 3 g along the gravity the attitude predicts: its direction agrees, its size says load
    w, x, y, z = ahrs.quaternion
    down = (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)
    loaded = tuple(-3.0 * G * d for d in down)
    after = _feed(ahrs, 1.02, 1.2, accel_m_s2=loaded)
    assert after and _withheld(after) == len(after)
    # back at 1 g (level): the recovery pulls the roll out and hands the attitude out again
    assert _withheld(_feed(ahrs, 1.2, 2.0, accel_m_s2=LEVEL)[-10:]) == 0
