"""The shared validity checks: blank frames, frozen frames, range limits, chip filters."""

from __future__ import annotations

import copy
import math

import pytest

from imuhal.core.samples import SampleFlag
from imuhal.drivers.validity import (
    FilterMemory,
    FrozenWatch,
    LearnedFrozenWatch,
    LowPassWatch,
    NewLevel,
    StepWatch,
    blank_flag,
    lowpass_coefficient,
    lowpass_settling_outputs,
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


@pytest.mark.parametrize(("bandwidth_hz", "rate_hz", "settled_share", "outputs"), [
    (10, 200, 3 / 1000, 16),         # seed RC vario gyro: 3 deg/s of 1000 deg/s
    (200 / 48, 200, 0.06 / 8, 26),   # its accelerometer: 60 mg of 8 g
    (14, 250, 3 / 500, 13),          # seed paraglider gyro: 3 deg/s of 500 deg/s
    (41, 200, 5 / 500, 3)])          # GY-91 gyro: 5 deg/s of 500 deg/s
def test_a_low_pass_settles_when_one_rail_input_can_add_under_the_chips_offset(
        bandwidth_hz: float, rate_hz: float, settled_share: float, outputs: int) -> None:
    a = lowpass_coefficient(bandwidth_hz, 1.0 / rate_hz)
    n = lowpass_settling_outputs(bandwidth_hz, rate_hz, settled_share)
    assert n == outputs
    assert 2 * (1 - a) * a ** (n + 1) < settled_share <= 2 * (1 - a) * a ** n


def _filtered(inputs: list[float], a: float) -> list[int]:
    """A first-order low-pass's outputs (counts) of ``inputs``, settled on the first."""
    y, out = inputs[0], []
    for x in inputs:
        y = a * y + (1 - a) * x
        out.append(round(y))
    return out


RAIL = 30000
PERIOD_NS = 5_000_000
SETTLED = 90.0
"""3 deg/s on a 1000 deg/s gyro (30000 counts): the MAX2110x's specified offset."""


def _watch(a: float) -> LowPassWatch:
    return LowPassWatch({"gyro": a}, {"gyro": PERIOD_NS}, RAIL, {"gyro": SETTLED})


def test_a_rail_input_the_low_pass_hides_in_range_is_seen_and_its_trace_settles() -> None:
    a = lowpass_coefficient(10, 1 / 200)
    inputs = [100.0] * 10 + [RAIL] + [100.0] * 20
    outputs = _filtered(inputs, a)
    assert abs(outputs[10]) < RAIL / 2  # in range: no SATURATED to see
    watch = _watch(a)
    flags = [watch.observe("gyro", k * PERIOD_NS, (y, 0, -y), SampleFlag.OK)
             for k, y in enumerate(outputs)]
    n = lowpass_settling_outputs(10, 200, SETTLED / RAIL)
    assert flags == [SampleFlag.OK] * 10 + [SampleFlag.FILTER_SETTLING] * (1 + n) \
        + [SampleFlag.OK] * (20 - n)


def test_motion_through_the_low_pass_is_no_rail_input() -> None:
    a = lowpass_coefficient(10, 1 / 200)
    inputs = [20000 * math.sin(k / 10) for k in range(200)]  # up to 2/3 of the range
    watch = _watch(a)
    assert all(watch.observe("gyro", k * PERIOD_NS, (y, y, y), SampleFlag.OK)
               is SampleFlag.OK for k, y in enumerate(_filtered(inputs, a)))


def test_outputs_lost_between_count_as_periods_the_chip_filtered() -> None:
    a = lowpass_coefficient(10, 1 / 200)
    outputs = _filtered([0.0] * 5 + [RAIL] + [0.0] * 30, a)
    watch = _watch(a)
    flags = {k: watch.observe("gyro", k * PERIOD_NS, (y, 0, 0), SampleFlag.OK)
             for k, y in enumerate(outputs) if k not in (7, 8, 9)}
    n = lowpass_settling_outputs(10, 200, SETTLED / RAIL)
    assert [k for k, f in flags.items() if f] == [k for k in range(5, 6 + n)
                                                  if k not in (7, 8, 9)]


def test_an_input_held_at_the_rail_is_flagged_while_it_lasts_and_two_full_scales_fade() -> None:
    """A rotation beyond the range for 30 outputs: each output is flagged (its input at the
    rail), and after it the filter may carry up to two full scales, which fade below the
    settled 0.3 % after floor(ln(2 / 0.003) / ln(1 / a)) = 20 outputs at 10 Hz and 200 Hz."""
    a = lowpass_coefficient(10, 1 / 200)
    outputs = _filtered([0.0] * 5 + [RAIL] * 30 + [0.0] * 30, a)
    watch = _watch(a)
    flags = [watch.observe("gyro", k * PERIOD_NS, (y, 0, 0),
                           SampleFlag.SATURATED if abs(y) >= RAIL else SampleFlag.OK)
             for k, y in enumerate(outputs)]
    flagged = [k for k, f in enumerate(flags) if f]
    assert flagged == list(range(5, 35 + 20))


def test_a_quiet_block_is_observed_as_row_by_row_would() -> None:
    np = pytest.importorskip("numpy")
    a = lowpass_coefficient(10, 1 / 200)
    outputs = _filtered([100.0] * 8 + [RAIL] + [100.0] * 8, a)
    rows = np.array([(y, 0, 0) for y in outputs], dtype=np.int16)
    stamps = [k * PERIOD_NS for k in range(len(outputs))]
    block = _watch(a)
    assert block.quiet_block("gyro", rows[:8], stamps[:8])
    assert not block.quiet_block("gyro", rows[8:], stamps[8:])  # the rail input
    single = _watch(a)
    for k in range(8):
        single.observe("gyro", stamps[k], tuple(rows[k]), SampleFlag.OK)
    assert [block.observe("gyro", stamps[k], tuple(rows[k]), SampleFlag.OK)
            for k in range(8, 17)] == [single.observe("gyro", stamps[k], tuple(rows[k]),
                                                      SampleFlag.OK) for k in range(8, 17)]
