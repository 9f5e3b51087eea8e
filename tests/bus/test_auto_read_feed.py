"""The slave auto-read feed (imuhal.bus.auto_read): what a master's driver delivers and what
a slave's driver takes, with the failed reads a master reports (issue 25)."""

from __future__ import annotations

from imuhal.bus.auto_read import AutoReadFeed, Copy, stamp_on_cadence

DRDY = 0x01


def feed() -> AutoReadFeed:
    f = AutoReadFeed(0x0C, 0x02, 3, latency_ns=5_000)
    f.keep_ready_only(0, DRDY)
    return f


def test_a_change_after_failed_reads_names_them_oldest_first() -> None:
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x01\x10\x20", failed=True)
    f.deliver(30, b"\x01\x10\x20", failed=True)
    f.deliver(40, b"\x01\x11\x21")
    assert f.take() == [Copy(10, b"\x01\x10\x20"), Copy(40, b"\x01\x11\x21", (20, 30), 30)]
    assert f.failures == 2


def test_a_delivery_whose_master_copied_nothing_keeps_the_copy_time() -> None:
    """``master_fresh=False``: the master's own chip did not measure since its previous
    read, so it made no copy of the slave: ``copied_ns`` stays at the latest delivery that
    may hold one (a master that says nothing, None, may)."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20", master_fresh=True)
    f.deliver(20, b"\x00\x10\x20", master_fresh=False)
    f.deliver(30, b"\x00\x10\x20", master_fresh=False)
    assert (f.t_ns, f.copied_ns) == (30, 10)
    f.deliver(40, b"\x00\x10\x20")
    assert f.copied_ns == 40


def test_a_repeated_copy_among_reads_with_a_nack_is_a_failed_read() -> None:
    """A FIFO read whose SLV0_NACK says one of its frames' slave reads failed, not which:
    a frame that repeats the copy before may be it; one that differs is not."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20", nack_seen=True)
    f.deliver(20, b"\x01\x10\x20", nack_seen=True)
    f.deliver(30, b"\x01\x11\x21", nack_seen=True)
    f.deliver(40, b"\x00\x11\x21", nack_seen=True)
    f.deliver(50, b"\x00\x11\x21")
    assert f.take() == [Copy(10, b"\x01\x10\x20"), Copy(30, b"\x01\x11\x21", (20,), 20)]
    assert f.failures == 1


def test_a_failed_read_is_no_change_even_with_other_bytes() -> None:
    """The master's registers after a failed read are not the slave's new data (the
    MPU-9250's register map leaves EXT_SENS_DATA's content then unsaid)."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x01\x99\x99", failed=True)
    assert f.take() == [Copy(10, b"\x01\x10\x20")]
    assert f.data == b"\x01\x10\x20" and f.t_ns == 20


def test_a_good_read_without_new_data_ends_the_run_of_failures() -> None:
    """A good read that finds no new measurement (no data-ready) says the failed read
    before it missed none: the measurement after it owes nothing to that read."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x01\x10\x20", failed=True)
    f.deliver(30, b"\x00\x10\x20")
    f.deliver(40, b"\x01\x12\x22")
    assert f.take()[-1] == Copy(40, b"\x01\x12\x22", after_ns=30)


def test_a_copy_names_the_last_of_the_good_reads_since_the_one_before_that_found_nothing(
) -> None:
    """Every master read between two measurements found the slave's data-ready bit clear:
    the slave made nothing new up to the last of them (a hung chip's proof, issue 25)."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x00\x10\x20")
    f.deliver(30, b"\x00\x10\x20")
    f.deliver(40, b"\x03\x11\x21")
    assert [c.quiet_ns for c in f.take()] == [None, 30]


def test_a_failed_read_breaks_the_run_of_reads_that_found_nothing() -> None:
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x00\x10\x20")
    f.deliver(30, b"\x00\x10\x20", failed=True)
    f.deliver(40, b"\x00\x10\x20")
    f.deliver(50, b"\x01\x11\x21")
    assert f.take()[-1].quiet_ns is None


def test_a_repeated_copy_with_data_ready_breaks_the_run() -> None:
    """A copy with data-ready equal to the one before is no read of the slave's state now
    (a master read that failed unreported leaves the copy as it was)."""
    f = feed()
    f.deliver(10, b"\x01\x10\x20")
    f.deliver(20, b"\x01\x10\x20")
    f.deliver(30, b"\x00\x10\x20")
    f.deliver(40, b"\x01\x11\x21")
    assert f.take()[-1].quiet_ns is None


def test_a_pause_in_the_deliveries_breaks_the_run_of_reads_that_found_nothing() -> None:
    """Deliveries further apart than the feed's latency (a host stall): the master read
    the slave between them unseen, and one of those reads may have found new data (a read
    clears the slave's data-ready bit, so the copy after shows it clear)."""
    f = feed()
    f.deliver(10_000, b"\x01\x10\x20")
    f.deliver(15_000, b"\x00\x10\x20")
    f.deliver(26_000, b"\x00\x10\x20")
    f.deliver(31_000, b"\x00\x10\x20")
    f.deliver(36_000, b"\x01\x11\x21")
    assert f.take()[-1].quiet_ns is None


def test_a_feed_without_a_data_ready_bit_proves_no_quiet_reads() -> None:
    """The MAX21100's copies hold the slave's data bytes only: equal bytes may be a read
    that found nothing or a read that failed."""
    f = AutoReadFeed(0x1E, 0x03, 2, latency_ns=5_000)
    for t in (10, 20, 30):
        f.deliver(t, b"\x10\x20")
    f.deliver(40, b"\x11\x21")
    assert [c.quiet_ns for c in f.take()] == [None, None]


P = 10_000


def test_a_copy_after_failed_reads_is_stamped_at_the_one_on_the_slaves_cadence() -> None:
    copy = Copy(35_000, b"\x01", failed_ns=(30_000,), after_ns=30_000)
    assert stamp_on_cadence(copy, 20_000, P, pause_ns=7_500) == 30_000


def test_a_copy_after_a_paused_master_is_stamped_at_the_latest_cadence_point() -> None:
    """The master delivered nothing for 90 us (its chip recovering): the copy may have
    waited in the slave, so it goes on the slave's cadence, not after its delivery."""
    copy = Copy(128_000, b"\x01", after_ns=38_000)
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500) == 120_000


def test_a_copy_delivered_on_time_keeps_its_delivery() -> None:
    assert stamp_on_cadence(Copy(15_500, b"\x01", after_ns=10_500), 5_000, P,
                            pause_ns=7_500) == 15_500
    assert stamp_on_cadence(Copy(15_500, b"\x01", after_ns=0), None, P,
                            pause_ns=7_500) == 15_500


def test_a_cadence_stamp_never_goes_back_before_the_delivery_before_it() -> None:
    copy = Copy(31_000, b"\x01", after_ns=20_500)
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500) == 30_000
    copy = Copy(28_000, b"\x01", after_ns=20_200)  # 2.8 periods: the cadence point 20_000
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500) == 20_201


def test_a_copy_after_a_pause_within_a_period_of_a_late_stamp_keeps_its_delivery() -> None:
    """The field before was stamped by a poll 10.7 ms after its measurement (of 13.3): the
    next field's copy came 8.1 ms later, after a pause of the master's. No cadence point
    lies between, and the copy is no repeat: stamped 1 ns after the field before, 2.7 ms
    before its own measurement, the frame ledger counted a field too many after it (the
    seed paraglider's HMC5883L under 10 % jitter: 750 for the chip's 748)."""
    copy = Copy(8_053, b"\x01", after_ns=-500)
    assert stamp_on_cadence(copy, 0, 13_333, pause_ns=6_000) == 8_053


def test_a_copy_after_failed_reads_and_a_pause_is_stamped_at_the_latest_cadence_point() -> None:
    """A failed read, then no delivery for 1.06 master periods of pause (the master's poll
    put off): the copy may have waited in the slave since its cadence point, which is
    nearer its measurement than the failed read or the delivery (seed-gps-vario, 10 % bus
    errors, I/O errors and 0xFF reads: stamped at the delivery, 1.5 periods after the field
    before, the gap counted a field the chip never skipped)."""
    copy = Copy(15_016, b"\x01", failed_ns=(4_391,), after_ns=4_391)
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500) == 10_000


def test_a_copy_whose_slave_says_it_measured_twice_is_never_stamped_one_period_on() -> None:
    """The AK8963's ST1.DOR in a copy after three failed slave reads: it measured twice
    since the master's last good read, so the failed read one period on (nearest the
    cadence) cannot be where its copy was due; the delivery two periods on is (seed-gps-
    vario, I/O errors on the magnetometer's wire: stamped one period on, 9.6 ms before its
    measurement, the ledger counted a field more than the chip made)."""
    copy = Copy(20_000, b"\x03", failed_ns=(5_000, 10_000, 15_000), after_ns=15_000)
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500) == 10_000
    assert stamp_on_cadence(copy, 0, P, pause_ns=7_500, at_least=2) == 20_000
