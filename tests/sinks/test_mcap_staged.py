"""The MCAP sink's output stream lands a chunk and its footer in one write: between landings
the file on disk does not change, so a kill at any point leaves it readable."""

from __future__ import annotations

from pathlib import Path

from imuhal.sinks.ros.mcap_sink import StagedFile


def _staged(tmp_path: Path, head: bytes) -> tuple[Path, StagedFile]:
    path = tmp_path / "out.bin"
    f = path.open("wb")
    f.write(head)
    return path, StagedFile(f)


def test_writes_stay_in_memory_until_landed(tmp_path: Path) -> None:
    path, staged = _staged(tmp_path, b"HEAD")
    staged.write(b"chunk-1")
    staged.flush()  # the writer's own flushes must not reach the file
    assert path.read_bytes() == b"HEAD"
    assert staged.tell() == len(b"HEADchunk-1")


def test_a_landing_writes_the_held_bytes_and_the_trailer_at_the_end(tmp_path: Path) -> None:
    path, staged = _staged(tmp_path, b"HEAD")
    staged.write(b"chunk-1")
    staged.land(b"<footer>")
    assert path.read_bytes() == b"HEADchunk-1<footer>"
    assert staged.tell() == len(b"HEADchunk-1")  # the next chunk goes over the footer


def test_the_next_landing_overwrites_the_previous_trailer(tmp_path: Path) -> None:
    path, staged = _staged(tmp_path, b"HEAD")
    staged.write(b"chunk-1")
    staged.land(b"<footer>")
    staged.write(b"chunk-2")
    assert path.read_bytes() == b"HEADchunk-1<footer>"  # untouched until landed
    staged.land(b"<footer>")
    assert path.read_bytes() == b"HEADchunk-1chunk-2<footer>"


def test_the_end_cuts_off_a_longer_earlier_trailer(tmp_path: Path) -> None:
    path, staged = _staged(tmp_path, b"HEAD")
    staged.land(b"<a long footer>")
    staged.write(b"summary")
    staged.end()
    assert path.read_bytes() == b"HEADsummary"
