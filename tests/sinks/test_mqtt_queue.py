"""The MQTT sink's on-disk queue: order, the count and age limits (oldest first, counted),
and what survives closing the file. Times are given, not read from a clock."""

from __future__ import annotations

from pathlib import Path

import pytest

from imuhal.core.errors import ImuhalError
from imuhal.sinks.mqtt.queue import DiskQueue


def _messages(n: int, *, start: int = 0, at_s: float = 1000.0) -> list[tuple[str, bytes, float]]:
    return [(f"t/{i % 3}", f"m{i}".encode(), at_s) for i in range(start, start + n)]


def _payloads(q: DiskQueue) -> list[bytes]:
    return [p for _, _, p in q.after(0, 10_000)]


def test_messages_come_out_in_the_order_they_went_in(tmp_path: Path) -> None:
    q = DiskQueue(tmp_path / "q.sqlite", max_messages=100, max_age_s=60)
    q.append(_messages(5))
    q.append(_messages(5, start=5))
    assert _payloads(q) == [f"m{i}".encode() for i in range(10)]
    first_ids = [i for i, _, _ in q.after(0, 3)]
    assert [p for _, _, p in q.after(first_ids[-1], 2)] == [b"m3", b"m4"]
    assert len(q) == 10


def test_beyond_the_count_limit_the_oldest_are_dropped_and_counted(tmp_path: Path) -> None:
    q = DiskQueue(tmp_path / "q.sqlite", max_messages=4, max_age_s=60)
    q.append(_messages(10))
    assert q.enforce_limits(1000.0) == 6
    assert _payloads(q) == [b"m6", b"m7", b"m8", b"m9"]
    assert q.dropped == 6 and len(q) == 4


def test_messages_older_than_the_age_limit_are_dropped_and_counted(tmp_path: Path) -> None:
    q = DiskQueue(tmp_path / "q.sqlite", max_messages=100, max_age_s=60)
    q.append(_messages(3, at_s=1000.0))
    q.append(_messages(2, start=3, at_s=1050.0))
    assert q.enforce_limits(1059.0) == 0
    assert q.enforce_limits(1061.0) == 3
    assert _payloads(q) == [b"m3", b"m4"] and q.dropped == 3


def test_messages_handed_to_the_broker_are_never_dropped_by_the_limits(tmp_path: Path) -> None:
    q = DiskQueue(tmp_path / "q.sqlite", max_messages=4, max_age_s=60)
    q.append(_messages(8))
    handed = q.after(0, 2)[-1][0]  # m0 and m1 await their acknowledgement
    assert q.enforce_limits(2000.0, keep_through_id=handed) == 6  # all aged: the rest go
    assert _payloads(q) == [b"m0", b"m1"]
    q.append(_messages(4, start=8, at_s=2000.0))
    assert q.enforce_limits(2000.0, keep_through_id=handed) == 2
    assert _payloads(q) == [b"m0", b"m1", b"m10", b"m11"]


def test_acknowledged_messages_leave_and_the_rest_stay_for_the_next_run(tmp_path: Path) -> None:
    path = tmp_path / "q.sqlite"
    q = DiskQueue(path, max_messages=100, max_age_s=60)
    q.append(_messages(6))
    ids = [i for i, _, _ in q.after(0, 2)]
    assert q.remove(ids) == 2 and q.remove(ids) == 0
    q.close()
    again = DiskQueue(path, max_messages=100, max_age_s=60)
    assert len(again) == 4 and _payloads(again) == [b"m2", b"m3", b"m4", b"m5"]
    again.append(_messages(1, start=6))
    assert _payloads(again)[-1] == b"m6"  # ids keep increasing after reopening


def test_a_queue_path_that_cannot_be_a_file_is_a_one_line_error(tmp_path: Path) -> None:
    (tmp_path / "dir.sqlite").mkdir()
    with pytest.raises(ImuhalError, match=r"dir\.sqlite: cannot open it .* queue_path"):
        DiskQueue(tmp_path / "dir.sqlite", max_messages=10, max_age_s=60)
