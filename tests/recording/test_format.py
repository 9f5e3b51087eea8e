"""The recording file format (docs/recording.md): what is written reads back, a flushed
record is on disk before the file is closed, and damage ends the readable part cleanly."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from imuhal.bus.recording.format import (
    MAGIC,
    BusInfo,
    ClockReading,
    EndMark,
    RecordedTransfer,
    RecordingWriter,
    open_recording,
)


def _writer(path: Path, interval_s: float = 3600.0) -> RecordingWriter:
    return RecordingWriter(path, {"what": "test"}, flush_interval_s=interval_s)


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
    assert path.read_bytes()[:10] == MAGIC + b"\x01\x00"
