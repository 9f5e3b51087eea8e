"""The GNSS epoch checks on their own (imuhal_chips.gnss.integrity): the bounds they apply,
from the receiver's stated accuracies, the time between epochs and the acceleration limit."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from imuhal_chips.gnss.integrity import (
    CONFIRM,
    GATE_SIGMAS,
    HEIGHT_ERROR_TAU_S,
    UNCONFIRMED,
    Epoch,
    EpochWatch,
    height_error_change_m,
    local_offset_m,
    vertical_manoeuvre_m,
)

LAT0, LON0 = 46.6, 8.0
M_PER_DEG_LAT = 111_170.0
"""About, at 46.6 deg: enough to place test epochs (the checks use the ellipsoid's radii)."""


def epoch(t_s: float, north_m: float = 0.0, east_m: float = 0.0, up_m: float = 0.0, *,
          v: tuple[float, float, float] = (10.0, 0.0, 0.0), h_acc: float = 2.5,
          **kwargs: object) -> Epoch:
    """An epoch ``north_m``, ``east_m``, ``up_m`` from a fixed origin at ``t_s`` (placed on
    a sphere: within 0.5 % of the ellipsoid's metres)."""
    kwargs.setdefault("height_ellipsoid_m", 948.0 + up_m)
    return Epoch(t_ns=round(t_s * 1e9), latitude_deg=LAT0 + north_m / M_PER_DEG_LAT,
                 longitude_deg=LON0 + east_m / (M_PER_DEG_LAT * math.cos(math.radians(LAT0))),
                 height_msl_m=900.0 + up_m, velocity_ned_m_s=v, horizontal_accuracy_m=h_acc,
                 vertical_accuracy_m=4.0, speed_accuracy_m_s=0.15,
                 **kwargs)  # type: ignore[arg-type]


def test_local_offsets_are_metres_north_east_down() -> None:
    north, east, down = local_offset_m(epoch(0.0), epoch(0.0, 100.0, -50.0, 20.0))
    assert north == pytest.approx(100.0, rel=5e-3) and east == pytest.approx(-50.0, rel=5e-3)
    assert down == pytest.approx(-20.0)


def started(north_m: float = 0.0) -> EpochWatch:
    """A watch whose reference is ``epoch(0.0, north_m)``: the CONFIRM epochs before it, 10 m/s
    north at 5 Hz, confirmed the first fix (the first CONFIRM - 1 of them refused)."""
    watch = EpochWatch(100.0)
    for k in range(1 - CONFIRM, 1):
        verdict = watch.observe(epoch(0.2 * k, north_m + 2.0 * k))
    assert verdict.ok and watch.refused == {UNCONFIRMED: CONFIRM - 1}
    return watch


def test_the_first_fix_is_valid_only_once_the_next_epochs_follow_it() -> None:
    """Nothing to hold the first fix against: the first CONFIRM - 1 epochs are refused, and
    the CONFIRM-th, following them under every rule, is valid and the first reference."""
    watch = EpochWatch(100.0)
    verdicts = [watch.observe(epoch(0.2 * k, 2.0 * k)) for k in range(CONFIRM + 1)]
    assert [v.ok for v in verdicts] == [False] * (CONFIRM - 1) + [True, True]
    assert {v.reason for v in verdicts[:CONFIRM - 1]} == {UNCONFIRMED}


def test_a_wrong_first_fix_never_becomes_valid_nor_a_reference() -> None:
    """The first fix 300 m north of where the next epochs put the receiver: the epochs after
    it do not follow it, so they start their own run; the wrong one is never valid."""
    watch = EpochWatch(100.0)
    assert not watch.observe(epoch(0.0, 300.0)).ok
    verdicts = [watch.observe(epoch(0.2 * k, 2.0 * k)).ok for k in range(1, CONFIRM + 2)]
    assert verdicts == [False] * (CONFIRM - 1) + [True, True]
    assert watch.refused == {UNCONFIRMED: CONFIRM}


def test_after_a_restart_the_next_epochs_are_held_like_a_first_fix() -> None:
    """Two seconds after the reference the manoeuvre term alone allows 100 m: an epoch
    80 m off would pass. After the receiver's restart it is no reference until the epochs
    after it follow it, and they do not."""
    watch = started()
    assert watch.follows(epoch(0.0), epoch(2.0, 20.0 + 80.0)).ok
    watch.restart()
    assert not watch.observe(epoch(2.0, 20.0 + 80.0)).ok
    verdicts = [watch.observe(epoch(2.0 + 0.2 * k, 20.0 + 2.0 * k)).ok
                for k in range(1, CONFIRM + 1)]
    assert verdicts == [False] * (CONFIRM - 1) + [True]
    assert watch.refused == {UNCONFIRMED: 2 * CONFIRM - 1}


def test_an_epoch_where_the_velocity_put_it_passes_and_one_beyond_the_gate_does_not() -> None:
    """10 m/s north for 0.2 s: 2 m. The horizontal gate of two 2.5 m hAcc is 5 sigma of
    3.5 m, 17.7 m, plus 100 m/s^2 x 0.04 s^2 / 4 (1 m)."""
    watch = started()
    assert watch.observe(epoch(0.2, 2.0 + 18.0)).ok
    verdict = watch.observe(epoch(0.4, 22.0 + 20.0))
    assert not verdict.ok and verdict.reason == "horizontal position"
    assert watch.refused == {UNCONFIRMED: CONFIRM - 1, "horizontal position": 1}


def test_the_gate_is_the_stated_accuracies_and_the_manoeuvre_term() -> None:
    watch = EpochWatch(100.0)
    gate_m = GATE_SIGMAS * math.sqrt(2 * 2.5**2 + 2 * 2 * 0.15**2 * 0.1**2) + 100.0 * 0.04 / 4
    earlier = epoch(0.0)
    assert watch.follows(earlier, epoch(0.2, 2.0 + 0.99 * gate_m)).ok
    assert not watch.follows(earlier, epoch(0.2, 2.0 + 1.01 * gate_m)).ok


def test_a_worse_accuracy_in_the_new_epoch_does_not_widen_its_gate() -> None:
    earlier = epoch(0.0)
    assert not EpochWatch(100.0).follows(earlier, epoch(0.2, 100.0, h_acc=8400.0)).ok
    assert EpochWatch(100.0).follows(epoch(0.0, h_acc=50.0), epoch(0.2, 100.0)).ok


def test_after_a_gap_the_manoeuvre_term_grows_with_the_square_of_the_time() -> None:
    """10 s without a fix: 100 m/s^2 may have moved the vehicle 2.5 km off the path the two
    velocities make."""
    watch = EpochWatch(100.0)
    assert watch.follows(epoch(0.0), epoch(10.0, 100.0 + 2000.0)).ok
    assert not watch.follows(epoch(0.0), epoch(10.0, 100.0 + 2600.0)).ok


def test_heights_made_from_heights_are_not_checked_against_them() -> None:
    """NMEA's vertical velocity is the change of its heights: nothing to hold them to."""
    nmea = {"vertical_velocity_measured": False, "height_ellipsoid_m": None}
    watch = EpochWatch(100.0)
    assert watch.follows(epoch(0.0, **nmea), epoch(0.2, 2.0, up_m=500.0, **nmea)).ok
    assert not watch.follows(epoch(0.0), replace(epoch(0.2, 2.0, up_m=500.0))).ok


def test_a_geoid_separation_that_moved_more_than_the_geoid_can_is_refused() -> None:
    earlier = epoch(0.0)
    hit = replace(epoch(0.2, 2.0), height_ellipsoid_m=948.0 + 0.01)
    verdict = EpochWatch(100.0).follows(earlier, hit)
    assert not verdict.ok and verdict.reason == "geoid separation"


def test_a_geoid_separation_no_place_on_earth_has_is_refused_even_first() -> None:
    watch = EpochWatch(100.0)
    assert not watch.observe(replace(epoch(0.0), height_ellipsoid_m=900.0 + 150.0)).ok
    assert watch.refused == {"geoid separation": 1}


def test_gps_time_less_utc_must_stay_the_leap_seconds() -> None:
    earlier = epoch(0.0, gps_minus_utc_s=18.0)
    assert EpochWatch(100.0).follows(earlier, epoch(0.2, 2.0, gps_minus_utc_s=18.001)).ok
    for flipped_s in (18.0 + 2**23 * 1e-9, 18.0 + 128.0):  # nano's third byte, the second
        assert not EpochWatch(100.0).follows(earlier, epoch(0.2, 2.0,
                                                           gps_minus_utc_s=flipped_s)).ok


def test_the_date_moves_on_by_a_day_at_most() -> None:
    earlier = epoch(0.0, utc_day=739_000)
    assert EpochWatch(100.0).follows(earlier, epoch(0.2, 2.0, utc_day=739_001)).ok
    assert not EpochWatch(100.0).follows(earlier, epoch(0.2, 2.0, utc_day=739_000 - 46_751)).ok


def test_a_wrong_reference_gives_way_to_epochs_that_agree_with_one_another() -> None:
    """The reference is 300 m off (the receiver's solution jumped while epochs were lost):
    the epochs after it are refused until CONFIRM of them agree, and the last of those is
    valid and the new reference."""
    watch = started(300.0)
    verdicts = [watch.observe(epoch(0.2 * k, 2.0 * k)).ok for k in range(1, CONFIRM + 2)]
    assert verdicts == [False] * (CONFIRM - 1) + [True, True]


def test_refused_epochs_that_disagree_with_one_another_never_become_a_reference() -> None:
    watch = started()
    wild = [epoch(0.2 * k, 2.0 * k + (-1) ** k * 400.0) for k in range(1, 6)]
    assert [watch.observe(e).ok for e in wild] == [False] * 5
    assert watch.observe(epoch(1.2, 12.0)).ok


def _vertical(watch: EpochWatch, dt_s: float, up_m: float, *, v_acc: float = 4.0,
              v_down: tuple[float, float] = (0.0, 0.0)) -> bool:
    """Whether an epoch ``up_m`` above where its velD (``v_down``, the earlier's and its
    own) put it after ``dt_s`` follows one at rest, both stating ``v_acc``."""
    earlier = replace(epoch(0.0, v=(0.0, 0.0, v_down[0])), vertical_accuracy_m=v_acc)
    climbed_m = -(v_down[0] + v_down[1]) / 2.0 * dt_s
    later = replace(epoch(dt_s, up_m=climbed_m + up_m, v=(0.0, 0.0, v_down[1])),
                    vertical_accuracy_m=v_acc)
    return watch.follows(earlier, later).ok


def test_the_vertical_gate_is_the_height_errors_change_and_the_manoeuvre_term() -> None:
    """Between epochs 0.2 s apart a height error of 4 m rms wandering over 10 s or more
    (HEIGHT_ERROR_TAU_S) changes by 4 sqrt(2 (1 - exp(-0.02))) = 0.80 m; the gate is 5 of
    those (with two epochs' 0.15 m/s sAcc over the interval) plus 100 m/s^2 x 0.04 s^2 / 4."""
    change_m = 4.0 * math.sqrt(2.0 * (1.0 - math.exp(-0.2 / HEIGHT_ERROR_TAU_S)))
    assert height_error_change_m(4.0, 0.2) == pytest.approx(change_m)
    gate_m = GATE_SIGMAS * math.sqrt(change_m**2 + 2 * 0.15**2 * 0.1**2) + 100.0 * 0.04 / 4
    assert gate_m == pytest.approx(5.0, abs=0.05)
    assert _vertical(EpochWatch(100.0), 0.2, 0.99 * gate_m)
    assert not _vertical(EpochWatch(100.0), 0.2, 1.01 * gate_m)


def test_the_same_32_8_m_flip_of_both_heights_is_refused_whatever_vacc_at_5_hz() -> None:
    """Bit 7 of the second byte of height and of hMSL moves both by 32.768 m and keeps the
    geoid separation. Two epochs' vAcc taken as independent errors let it through from
    vAcc 4.5 m on (5 sqrt(2) vAcc + 1 m); the change of a 30 m vAcc's error over 0.2 s is
    6 m, so 5 of them and the manoeuvre term still stay under 32.8 m."""
    for v_acc in (4.0, 8.0, 30.0):
        assert not _vertical(EpochWatch(100.0), 0.2, 32.768, v_acc=v_acc)
        assert _vertical(EpochWatch(100.0), 0.2, 0.5, v_acc=v_acc)


def test_at_1_hz_the_acceleration_limit_is_the_vertical_gates_larger_part() -> None:
    """At 1 Hz 10 g moves a vehicle 25 m off the trapezoid of two equal velDs, and 5 changes
    of a 4 m vAcc's error over 1 s add 8.7 m: a 32.8 m flip of both heights is within what
    a 10 g vehicle can do between two epochs a second apart (docs/reliability.md). It is
    refused while vAcc stays below 3.5 m, and at any vAcc up to 10 m for a vehicle stating
    4 g (max_acceleration_m_s2, as u-blox's 'airborne < 4 g' platform model does)."""
    assert _vertical(EpochWatch(100.0), 1.0, 32.768, v_acc=4.0)
    assert not _vertical(EpochWatch(100.0), 1.0, 32.768, v_acc=3.4)
    for v_acc in (4.0, 10.0):
        assert not _vertical(EpochWatch(4 * 9.81), 1.0, 32.768, v_acc=v_acc)


def test_a_steep_velocity_change_leaves_the_height_little_room_off_its_ramp() -> None:
    """velD from -5 (a thermal) to +15 m/s (a spiral dive) in 0.2 s is 100 m/s^2, the whole
    acceleration limit: the only path between them is the straight ramp, so no manoeuvre
    term is added (vertical_manoeuvre_m), only the height error's change; with equal velDs
    the vehicle could have left the trapezoid by A dt^2 / 4."""
    assert vertical_manoeuvre_m(100.0, 0.2, 20.0) == 0.0
    assert vertical_manoeuvre_m(100.0, 0.2, 0.0) == pytest.approx(1.0)
    assert vertical_manoeuvre_m(100.0, 0.2, 10.0) == pytest.approx(0.75)
    assert _vertical(EpochWatch(100.0), 0.2, 3.9, v_down=(-5.0, 15.0))
    assert not _vertical(EpochWatch(100.0), 0.2, 4.1, v_down=(-5.0, 15.0))


def test_an_epoch_stamped_like_its_reference_is_judged_not_divided_by_zero() -> None:
    """No time between them and nothing stated of accuracy: no term of either gate is left
    but the fields' resolution. A hit epoch stamped like its reference raised
    ZeroDivisionError in the vertical rule (the driver was then recovered)."""
    still = {"v": (0.0, 0.0, 0.0), "h_acc": 0.0}
    earlier = replace(epoch(0.0, **still), vertical_accuracy_m=0.0, speed_accuracy_m_s=0.0)
    assert EpochWatch(100.0).follows(earlier, earlier).ok
    for moved in (replace(earlier, height_msl_m=earlier.height_msl_m + 1.0,
                          height_ellipsoid_m=earlier.height_ellipsoid_m + 1.0),
                  replace(earlier, latitude_deg=earlier.latitude_deg + 1e-4)):
        assert not EpochWatch(100.0).follows(earlier, moved).ok
