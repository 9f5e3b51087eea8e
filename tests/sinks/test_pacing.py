"""The sinks' shared per-message rate limit (imuhal.sinks.pacing)."""

from imuhal.sinks.pacing import RateLimiter


def test_a_10_hz_limit_passes_events_100_ms_apart_even_rounded_down_a_nanosecond() -> None:
    pacing = RateLimiter()
    assert pacing.due("LK8EX1", 0, 10.0)
    assert pacing.due("LK8EX1", 99_999_999, 10.0)


def test_a_10_hz_limit_refuses_an_event_a_microsecond_early() -> None:
    pacing = RateLimiter()
    assert pacing.due("LK8EX1", 0, 10.0)
    assert not pacing.due("LK8EX1", 99_999_000, 10.0)


def test_each_name_is_limited_on_its_own() -> None:
    pacing = RateLimiter()
    assert pacing.due("GGA", 0, 1.0)
    assert pacing.due("RMC", 1_000, 1.0)
    assert not pacing.due("GGA", 2_000, 1.0)


def test_a_rate_of_zero_means_no_limit() -> None:
    pacing = RateLimiter()
    assert all(pacing.due("PRS", t, 0.0) for t in range(0, 10, 1))


def test_ready_does_not_use_up_the_slot_until_marked() -> None:
    pacing = RateLimiter()
    assert pacing.ready("POV", 0, 5.0)
    assert pacing.ready("POV", 1, 5.0)  # nothing was marked: still free
    pacing.mark("POV", 1, 5.0)
    assert not pacing.ready("POV", 2, 5.0)


def test_events_a_hair_under_their_period_apart_keep_the_rate_asked_for() -> None:
    # a 200 Hz IMU on a chip 0.02 % fast: 4.999 ms apart; 50 Hz must stay 50 Hz, not 40
    pacing = RateLimiter()
    sent = sum(pacing.due("HIGHRES_IMU", i * 4_999_000, 50.0) for i in range(2000))
    assert sent == 500  # 2000 events over 9.998 s: one at or after each 20 ms point (40 Hz: 400)


def test_a_gap_in_the_events_restarts_the_grid_instead_of_sending_a_burst() -> None:
    pacing = RateLimiter()
    assert pacing.due("ATT", 0, 50.0)
    assert pacing.due("ATT", 1_000_000_000, 50.0)  # 1 s later: a gap
    assert not pacing.due("ATT", 1_005_000_000, 50.0)  # not one per missed point
    assert pacing.due("ATT", 1_020_000_000, 50.0)
