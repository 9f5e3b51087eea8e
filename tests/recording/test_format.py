"""The recording file format (docs/recording.md): what is written reads back, a flushed
record is on disk before the file is closed, and damage ends the readable part cleanly."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imuhal.bus.recording.format import (
    MAGIC,
    BusInfo,
    ClockReading,
    EndMark,
    LatePoll,
    RecordedEdge,
    RecordedTransfer,
    RecordingError,
    RecordingWriter,
    open_recording,
)


def _writer(path: Path, interval_s: float = 3600.0) -> RecordingWriter:
    return RecordingWriter(path, {"what": "test"}, flush_interval_s=interval_s)


# Each example writes and fsyncs a file: a loaded disk must not fail it on hypothesis' deadline.
@settings(deadline=None)
@given(st.lists(st.tuples(st.integers(-(2**62), 2**62), st.integers(0, 0x3FF),
                          st.binary(max_size=40), st.binary(max_size=300)), max_size=30))
def test_transfers_and_clock_readings_read_back_exactly(
        tmp_path_factory: object, items: list[tuple[int, int, bytes, bytes]]) -> None:
    path = tmp_path_factory.mktemp("rec") / "r.imurec"  # type: ignore[attr-defined]
    w = _writer(path)
    w.bus(BusInfo(0, "spi0", "spi:///dev/spidev0", "spi"))
    for t, target, written, read in items:
        w.transfer(t, 0, target, written, read)
        w.clock(t + 7)
    w.failed(5, 0, 0x68, b"\x75", 1, "NackError", "no ACK")
    w.end("complete")
    w.close()
    rec = open_recording(path)
    assert rec.header == {"what": "test"}
    got = list(rec.records())
    assert got[0] == BusInfo(0, "spi0", "spi:///dev/spidev0", "spi")
    want: list[object] = []
    for i, (t, target, written, read) in enumerate(items):
        want += [RecordedTransfer(i, t, 0, target, written, read, len(read)), ClockReading(t + 7)]
    want += [RecordedTransfer(len(items), 5, 0, 0x68, b"\x75", b"", 1, "NackError", "no ACK"),
             EndMark(5, "complete")]
    assert got[1:] == want
    assert rec.damage == ""


def test_a_flushed_record_is_on_disk_before_the_file_is_closed(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    w = _writer(path, interval_s=0.0)  # flush at every record
    w.transfer(1_000, 0, 0x76, b"\xd0", b"\x58")
    readable = list(open_recording(path).records())  # the writer is still open
    assert readable == [RecordedTransfer(0, 1_000, 0, 0x76, b"\xd0", b"\x58", 1)]
    w.close()


def test_unflushed_records_are_not_on_disk_yet(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    w = _writer(path)
    w.transfer(1_000, 0, 0x76, b"\xd0", b"\x58")
    assert list(open_recording(path).records()) == []
    w.close()
    assert len(list(open_recording(path).records())) == 1


def test_a_damaged_chunk_ends_the_readable_part_and_says_where(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    w = _writer(path)
    w.transfer(1, 0, 1, b"\x01", b"\x02")
    w.flush()
    good_size = path.stat().st_size
    w.transfer(2, 0, 1, b"\x03", b"\x04")
    w.close()
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF  # one flipped bit in the last chunk
    path.write_bytes(bytes(data))
    rec = open_recording(path)
    assert [r.written for r in rec.records()] == [b"\x01"]  # type: ignore[union-attr]
    assert "CRC" in rec.damage and f"at byte {good_size}" in rec.damage


def test_the_file_starts_with_the_magic_and_the_version(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    _writer(path).close()
    assert path.read_bytes()[:10] == MAGIC + b"\x03\x00"


@settings(deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2**40), st.integers(1, 4096), st.binary(max_size=300),
                          st.sampled_from([4800, 9600, 115200, 921600])), max_size=20))
def test_byte_stream_receives_and_baud_changes_read_back_exactly(
        tmp_path_factory: object, items: list[tuple[int, int, bytes, int]]) -> None:
    path = tmp_path_factory.mktemp("rec") / "r.imurec"  # type: ignore[attr-defined]
    w = _writer(path)
    w.bus(BusInfo(0, "uart", "serial:///dev/ttyS0", "serial"))
    for t, max_len, data, baud in items:
        w.baudrate(t, 0, baud)
        w.received(t + 1, 0, 0, max_len, data)
        w.late_poll(t + 2, "gps")
    w.stream_failed(3, 0, "receive", 0, 64, "BusError", "serial read failed: EIO")
    w.stream_failed(4, 0, "baud", 0, 57600, "BusError", "cannot set 57600 baud")
    w.close()
    got = list(open_recording(path).records())[1:]
    want: list[object] = []
    for i, (t, max_len, data, baud) in enumerate(items):
        want += [RecordedTransfer(2 * i, t, 0, 0, b"", b"", 0, op="baud", baudrate=baud),
                 RecordedTransfer(2 * i + 1, t + 1, 0, 0, b"", data, max_len, op="receive"),
                 LatePoll(t + 2, "gps")]
    n = 2 * len(items)
    want += [RecordedTransfer(n, 3, 0, 0, b"", b"", 64, "BusError", "serial read failed: EIO",
                              op="receive"),
             RecordedTransfer(n + 1, 4, 0, 0, b"", b"", 0, "BusError", "cannot set 57600 baud",
                              op="baud", baudrate=57600)]
    assert got == want


def test_data_ready_edges_read_back_exactly(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    w = _writer(path)
    w.clock(5_000_000)
    w.edge(4_990_000, "imu", 1)  # an edge stamped before the previous record's time
    w.edge(9_990_000, "imu", 3)
    w.close()
    got = list(open_recording(path).records())
    assert got[1:] == [RecordedEdge(4_990_000, "imu", 1), RecordedEdge(9_990_000, "imu", 3)]


def test_an_edge_record_in_a_version_2_file_is_damage(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    w = _writer(path)
    w.edge(1, "imu", 1)
    w.close()
    data = bytearray(path.read_bytes())
    data[len(MAGIC)] = 2
    path.write_bytes(bytes(data))
    rec = open_recording(path)
    assert list(rec.records()) == []
    assert rec.damage.endswith("record type 10 in a version-2 recording: damaged")


def test_a_version_1_recording_still_reads(tmp_path: Path) -> None:
    # Written by imuhal before byte streams were recorded (gy91, static, 1.5 s).
    rec = open_recording(Path("tests/data/recording/gy91-static-1.5s-v1.imurec"))
    records = list(rec.records())
    assert rec.version == 1 and rec.damage == ""
    assert sum(isinstance(r, RecordedTransfer) for r in records) == 564
    assert rec.end is not None and rec.end.how == "complete"


def test_a_recording_of_a_newer_format_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "r.imurec"
    _writer(path).close()
    data = bytearray(path.read_bytes())
    data[len(MAGIC)] = 4
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"format version 4; this imuhal reads versions "
                                             r"1-3 \(upgrade imuhal to replay it\)$"):
        open_recording(path)


def test_the_loss_bound_holds_in_data_time_when_wall_time_does_not_pass(
        tmp_path: Path) -> None:
    """Issue 26 item 7: 3 s of records written within a moment of wall time (a loaded
    machine, a fast emulation) are on disk, bar the last second, before the file closes."""
    path = tmp_path / "r.imurec"
    w = _writer(path, interval_s=1.0)
    for i in range(301):
        w.transfer(i * 10_000_000, 0, 0x76, b"\xf3", b"\x00" * 10)
    on_disk = [r.t_ns for r in open_recording(path).records()
               if isinstance(r, RecordedTransfer)]
    assert on_disk and on_disk[-1] >= 2_000_000_000
    w.close()


def test_the_end_record_says_when_the_run_ended_and_an_older_one_reads_without_it(
        tmp_path: Path) -> None:
    writer = _writer(tmp_path / "run.imurec")
    writer.clock(1_000)
    writer.end("complete", 5_000)
    writer.close()
    assert list(open_recording(tmp_path / "run.imurec").records())[-1] == \
        EndMark(1_000, "complete", 5_000)
    old = list(open_recording(Path("tests/data/recording/seed-thermal-1.5s-plan1.imurec"))
               .records())[-1]
    assert isinstance(old, EndMark) and old.how == "complete" and old.end_ns is None
