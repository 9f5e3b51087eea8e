"""The shared validity checks: blank frames, frozen frames, range limits."""

from __future__ import annotations

import copy
import math

import pytest

from imuhal.core.samples import SampleFlag
from imuhal.drivers.validity import (
    FilterMemory,
    FrozenWatch,
    LearnedFrozenWatch,
    NewLevel,
    StepWatch,
    blank_flag,
    range_flag,
    wilson_upper,
)


@pytest.mark.parametrize("frame", [b"\xff" * 15, b"\x00" * 6, b"\xff"])
def test_a_frame_of_all_ones_or_all_zeros_is_blank(frame: bytes) -> None:
    assert blank_flag(frame) is SampleFlag.BLANK


@pytest.mark.parametrize("frame", [b"\xff\xfe", b"\x00\x01\x00", b"\x12" * 6, b""])
def test_any_other_frame_is_not_blank(frame: bytes) -> None:
    assert blank_flag(frame) is SampleFlag.OK


def test_a_frame_is_frozen_from_its_nth_repeat_until_it_changes() -> None:
    watch = FrozenWatch(3)
    flags = [watch.observe("gyro", b"\x01\x02") for _ in range(4)]
    assert flags == [SampleFlag.OK, SampleFlag.OK, SampleFlag.FROZEN, SampleFlag.FROZEN]
    assert watch.observe("gyro", b"\x01\x03") is SampleFlag.OK
    assert watch.observe("gyro", b"\x01\x03") is SampleFlag.OK


def test_channels_are_watched_apart() -> None:
    watch = FrozenWatch(2)
    watch.observe("accel", b"\x05")
    assert watch.observe("gyro", b"\x05") is SampleFlag.OK
    assert watch.observe("accel", b"\x05") is SampleFlag.FROZEN


@pytest.mark.parametrize("watch", [FrozenWatch(3), LearnedFrozenWatch(3, learn_pairs=2,
                                                                  false_alarm=0.5)])
def test_a_burst_observed_at_once_leaves_the_watch_as_frame_by_frame(
        watch: FrozenWatch) -> None:
    twin = copy.deepcopy(watch)
    bursts = [[b"a", b"b", b"b"], [b"b", b"c"], [b"c", b"c", b"d"], [b"d", b"d"], [b"e"]]
    for burst in bursts:
        frozen = twin.would_flag("k", burst)
        assert watch.observe_all("k", burst) is not frozen
        if not frozen:  # taken: the same state as observing each frame
            for frame in burst:
                twin.observe("k", frame)
        assert vars(watch) == vars(twin)


def test_a_frozen_window_needs_at_least_two_frames() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        FrozenWatch(1)


def test_values_outside_the_limits_are_out_of_range_and_nan_is_left_to_the_nan_check() -> None:
    assert range_flag([25.0], -40.0, 85.0) is SampleFlag.OK
    assert range_flag([-40.0, 85.0], -40.0, 85.0) is SampleFlag.OK
    assert range_flag([85.1], -40.0, 85.0) is SampleFlag.OUT_OF_RANGE
    assert range_flag([math.nan], -40.0, 85.0) is SampleFlag.OK


def test_a_wrong_measurement_inside_an_open_window_is_settling_and_never_shortens_it() -> None:
    """Found by the fault matrix (gy91, wild values and wrong pressures at 10 %): the BMP280's
    temperature, filtered with the pressure, came out valid 1.4 degC off when the pressure
    of that output carried a wrong measurement of its own; and a later wrong measurement
    must not end the window an earlier one opened."""
    memory = FilterMemory({"adc": 10}, {"adc": 20})
    assert memory.flag("adc", 0, SampleFlag.SATURATED) == SampleFlag.OK
    assert memory.flag("adc", 20, SampleFlag.OUT_OF_RANGE) == SampleFlag.FILTER_SETTLING
    assert memory.flag("adc", 200, SampleFlag.OK) == SampleFlag.FILTER_SETTLING
    assert memory.flag("adc", 230, SampleFlag.OK) == SampleFlag.FILTER_SETTLING  # 20's window
    assert memory.flag("adc", 240, SampleFlag.OK) == SampleFlag.OK


def test_a_step_beyond_the_rate_and_noise_is_implausible_and_moves_no_reference() -> None:
    """One disturbed reading is refused and the honest ones after it are judged against the
    last valid reading, not against it."""
    watch = StepWatch(max_rate_per_s=100.0, noise=5.0)
    assert watch.observe(0, 1000.0) is SampleFlag.OK
    assert watch.observe(100_000_000, 1014.0) is SampleFlag.OK  # 10 + 5 allowed in 0.1 s
    assert watch.observe(200_000_000, 1500.0) is SampleFlag.IMPLAUSIBLE
    assert watch.observe(300_000_000, 1030.0) is SampleFlag.OK  # 20 + 5 from 1014
    assert watch.refused == 1


def test_the_bound_grows_with_the_time_since_the_last_valid_reading() -> None:
    watch = StepWatch(max_rate_per_s=100.0, noise=5.0)
    watch.observe(0, 1000.0)
    assert watch.observe(10_000_000, 1010.0) is SampleFlag.IMPLAUSIBLE  # 1 + 5 allowed
    assert watch.observe(2_000_000_000, 1190.0) is SampleFlag.OK        # 200 + 5 allowed


def test_a_new_level_confirmed_by_readings_that_agree_is_taken_after_confirm_readings() -> None:
    """A wrong reference (the first reading was the disturbed one) costs ``confirm - 1``
    honest readings, flagged, never passed wrong."""
    watch = StepWatch(max_rate_per_s=100.0, noise=5.0, confirm=3)
    watch.observe(0, 60_000.0)
    flags = [watch.observe(t * 20_000_000, 90_000.0 + t) for t in (1, 2, 3, 4)]
    assert flags == [SampleFlag.IMPLAUSIBLE, SampleFlag.IMPLAUSIBLE, SampleFlag.OK,
                     SampleFlag.OK]


def test_refused_readings_that_disagree_with_one_another_confirm_nothing() -> None:
    watch = StepWatch(max_rate_per_s=100.0, noise=5.0, confirm=2)
    watch.observe(0, 1000.0)
    assert watch.observe(20_000_000, 5000.0) is SampleFlag.IMPLAUSIBLE
    assert watch.observe(40_000_000, 9000.0) is SampleFlag.IMPLAUSIBLE
    assert watch.observe(60_000_000, 9001.0) is SampleFlag.OK


def test_a_step_watch_refuses_bounds_that_check_nothing_or_everything() -> None:
    with pytest.raises(ValueError, match="confirm >= 2"):
        StepWatch(max_rate_per_s=0.0, noise=1.0)
    with pytest.raises(ValueError, match="confirm >= 2"):
        StepWatch(max_rate_per_s=1.0, noise=1.0, confirm=1)


def test_a_new_level_is_confirm_refused_readings_in_a_row_each_agreeing_with_the_last() -> None:
    """The agreement test is the caller's: here, within 1 of the reading before."""
    level = NewLevel(3, lambda earlier, later: abs(later - earlier) <= 1)
    assert [level.refused(v) for v in (10, 11, 12)] == [False, False, True]
    assert [level.refused(v) for v in (10, 11, 50, 51, 52)] == [False, False, False, False,
                                                                True]


def test_an_accepted_reading_breaks_the_run_of_refused_ones() -> None:
    level = NewLevel(2, lambda earlier, later: earlier == later)
    assert not level.refused("b")
    level.clear()
    assert not level.refused("b")
    assert level.refused("b")


def test_a_new_level_needs_two_readings_at_least() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        NewLevel(1, lambda earlier, later: True)


def test_a_learned_frozen_window_holds_the_ceiling_until_enough_pairs_were_seen() -> None:
    watch = LearnedFrozenWatch(30, learn_pairs=20, false_alarm=1e-6)
    for i in range(20):  # 20 frames, 19 pairs, none repeated
        assert watch.observe("adc", bytes([i])) is SampleFlag.OK
    assert watch.window("adc") == 30
    watch.observe("adc", b"\x40")  # the 20th pair
    assert watch.window("adc") < 30


def test_a_chip_that_never_repeats_is_flagged_at_its_learned_window() -> None:
    watch = LearnedFrozenWatch(41, learn_pairs=100, false_alarm=0.3 ** 24)
    for i in range(101):
        watch.observe("adc", i.to_bytes(2, "big"))
    n = watch.window("adc")
    flags = [watch.observe("adc", b"\xff\xff") for _ in range(n)]
    assert flags == [SampleFlag.OK] * (n - 1) + [SampleFlag.FROZEN]


def test_a_chip_that_repeats_often_keeps_a_longer_window_never_beyond_the_ceiling() -> None:
    often = LearnedFrozenWatch(41, learn_pairs=100, false_alarm=0.3 ** 24)
    seldom = LearnedFrozenWatch(41, learn_pairs=100, false_alarm=0.3 ** 24)
    for i in range(101):
        often.observe("adc", bytes([i // 2]))  # every other pair repeats
        seldom.observe("adc", bytes([i]))
    assert seldom.window("adc") < often.window("adc") <= 41
    assert often.window_for(100, 100) == 41  # a chip frozen while learning


def test_learned_windows_are_kept_per_channel() -> None:
    watch = LearnedFrozenWatch(20, learn_pairs=5, false_alarm=1e-3)
    for i in range(6):
        watch.observe("fast", bytes([i]))
        watch.observe("slow", b"\x01")
    assert watch.window("fast") < 20
    assert watch.window("slow") == 20


def test_the_wilson_bound_is_above_the_observed_rate_and_below_one() -> None:
    assert 0.0 < wilson_upper(0, 100, 2.0) < 0.05
    assert 0.3 < wilson_upper(30, 100, 2.0) < 0.4
    assert wilson_upper(100, 100, 2.0) == 1.0
