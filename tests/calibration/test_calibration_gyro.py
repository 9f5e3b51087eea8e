"""Gyro offsets at rest: recovered within 0.05 deg/s; a moving board or an axis reading more
than expected is measured again after a wait, and refused with advice when it never settles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.calibration.conftest import DPS, GYRO_BIAS_DPS, make_stream

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.gyro import GyroOffsetProcedure, GyroOffsetSettings
from imuhal.calibration.model import GyroCalibration
from imuhal.calibration.progress import Progress, ProgressKind
from imuhal.core.samples import Frame, GyroSample, Sample
from imuhal.sim.tumble import TumbleScenario


def _shaken_then_still(still_after_s: float) -> list[Sample]:
    """The level hold of the calibration run with a 20 deg/s wobble before ``still_after_s``."""
    from imuhal.sim.calibration import CalibrationScenario

    out = []
    for s in make_stream(CalibrationScenario(seed=3), t1=4.0):
        t = s.t_ns / 1e9
        if isinstance(s, GyroSample) and t < still_after_s:
            w = 20 * DPS * math.sin(2 * math.pi * 3 * t)
            s = s.with_vector((s.gyro_rad_s[0] + w, s.gyro_rad_s[1], s.gyro_rad_s[2]),
                              Frame.SENSOR)
        out.append(s)
    return out


def test_offsets_at_rest_are_recovered_within_0_05_dps(calibration_run: list[Sample]) -> None:
    result = GyroOffsetProcedure().run(calibration_run)
    err_dps = np.abs(result.offset_rad_s / DPS - np.array(GYRO_BIAS_DPS))
    assert err_dps.max() < 0.05
    assert result.samples == 100 and result.attempts == 1


def test_a_board_moving_at_first_is_measured_again_after_waiting() -> None:
    events: list[Progress] = []
    proc = GyroOffsetProcedure(GyroOffsetSettings(retry_wait_s=0.5), progress=events.append)
    result = proc.run(_shaken_then_still(still_after_s=1.0))
    assert result.attempts >= 2
    assert any(e.kind is ProgressKind.RETRY and "moved" in e.message for e in events)
    assert np.abs(result.offset_rad_s / DPS - np.array(GYRO_BIAS_DPS)).max() < 0.05


def test_a_board_that_never_stops_moving_is_refused_with_advice() -> None:
    stream = make_stream(TumbleScenario(seed=2), t0=33.0, t1=44.0)  # the free tumble
    with pytest.raises(CalibrationError, match="moved") as exc:
        GyroOffsetProcedure(GyroOffsetSettings(retry_wait_s=1.0, max_attempts=3)).run(stream)
    assert "steady table" in str(exc.value)


def test_an_axis_reading_more_than_expected_is_refused_naming_the_setting(
        calibration_run: list[Sample]) -> None:
    settings = GyroOffsetSettings(max_offset_dps=1.0, retry_wait_s=0.2, max_attempts=2)
    expected = r"gyro y reads -1\.\d+ deg/s \(more than the expected 1 deg/s\)"
    with pytest.raises(CalibrationError, match=expected) as exc:
        GyroOffsetProcedure(settings).run(calibration_run)
    assert "max_offset_dps" in str(exc.value)


def test_too_few_samples_say_what_is_missing() -> None:
    stream = [GyroSample(t_ns=i * 4_000_000, device="imu", gyro_rad_s=(0.0, 0.0, 0.0))
              for i in range(20)]
    with pytest.raises(CalibrationError, match="only 20 of 100"):
        GyroOffsetProcedure().run(stream)


def test_body_frame_samples_are_refused() -> None:
    sample = GyroSample(t_ns=0, device="imu", frame=Frame.BODY_NED)
    with pytest.raises(ValueError, match="calibrated=False"):
        GyroOffsetProcedure().feed(sample)


def test_the_record_keeps_stored_scale_and_misalignment(calibration_run: list[Sample]) -> None:
    result = GyroOffsetProcedure().run(calibration_run)
    old = GyroCalibration(scale=(1.01, 0.99, 1.0))
    rec = result.record(old)
    assert rec.scale == (1.01, 0.99, 1.0)
    assert rec.offset_rad_s == pytest.approx(tuple(result.offset_rad_s))
    assert rec.procedure == "gyro-at-rest" and rec.quality["samples"] == 100


def test_a_window_with_frozen_samples_says_the_data_may_be_hung_not_only_moved() -> None:
    """A gyro that hangs: its first repeats come in valid (a frozen run is flagged only from
    its Nth repeat), then FROZEN samples, then live ones again. The window's spread looks
    like a board that moved; the verdict says the data were not all measurements."""
    from imuhal.core.samples import SampleFlag

    def gyro(k: int, value: tuple[float, float, float], flags: SampleFlag = SampleFlag.OK
             ) -> GyroSample:
        return GyroSample(t_ns=k * 4_000_000, device="imu", frame=Frame.SENSOR,
                          gyro_rad_s=value, flags=flags)

    frozen, live = (0.0, 0.0, 0.0), (0.05, -0.03, 0.02)  # rad/s: the hung word, the truth
    stream = [gyro(k, frozen) for k in range(49)]
    stream += [gyro(k, (math.nan,) * 3, SampleFlag.FROZEN | SampleFlag.NAN)
               for k in range(49, 60)]
    stream += [gyro(k, live) for k in range(60, 111)]
    messages: list[str] = []
    proc = GyroOffsetProcedure(GyroOffsetSettings(samples=100, max_attempts=3),
                               device="imu", progress=lambda p: messages.append(p.message))
    for sample in stream:
        proc.feed(sample)
    retry = next(m for m in messages if m.startswith("attempt 1"))
    assert "11 FROZEN" in retry and "hung" in retry and "moved" in retry
