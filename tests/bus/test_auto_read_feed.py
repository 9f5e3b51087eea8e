"""The slave auto-read feed (imuhal.bus.auto_read): what a master's driver delivers and what
a slave's driver takes, with the failed reads a master reports (issue 25)."""

from __future__ import annotations

from imuhal.bus.auto_read import AutoReadFeed, Copy

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
    assert f.take() == [Copy(10, b"\x01\x10\x20"), Copy(40, b"\x01\x11\x21", (20, 30))]
    assert f.failures == 2


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
    assert f.take()[-1] == Copy(40, b"\x01\x12\x22")
