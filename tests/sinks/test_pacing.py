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
    pacing.mark("POV", 1)
    assert not pacing.ready("POV", 2, 5.0)
