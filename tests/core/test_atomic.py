"""Safe file writing: links followed, FIFOs written directly, modes from the umask, outputs
never inputs, and a kept partial file only when asked."""

from __future__ import annotations

import os
import stat
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from imuhal.core.atomic import AtomicFile, atomic_write_text, check_outputs
from imuhal.core.errors import OutputError


@pytest.fixture
def umask_027() -> Iterator[None]:
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_a_new_file_follows_the_umask(tmp_path: Path, umask_027: None) -> None:
    """Issue 9 item 14."""
    path = atomic_write_text(tmp_path / "new.csv", "x\n")
    assert _mode(path) == 0o640


def test_a_new_partial_file_follows_the_umask(tmp_path: Path, umask_027: None) -> None:
    f = AtomicFile(tmp_path / "log.csv", partial=True)
    assert _mode(tmp_path / "log.csv.partial") == 0o640
    f.commit()
    assert _mode(tmp_path / "log.csv") == 0o640


def test_a_replaced_file_keeps_its_mode(tmp_path: Path) -> None:
    path = tmp_path / "old.csv"
    path.write_text("old\n")
    path.chmod(0o604)
    atomic_write_text(path, "new\n")
    assert path.read_text() == "new\n" and _mode(path) == 0o604


def test_a_symlink_is_followed_and_kept(tmp_path: Path) -> None:
    real = tmp_path / "data" / "real.csv"
    real.parent.mkdir()
    real.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    written = atomic_write_text(link, "new\n")
    assert written == real.resolve()
    assert link.is_symlink() and real.read_text() == "new\n"


def test_a_dangling_symlink_creates_its_target(tmp_path: Path) -> None:
    link = tmp_path / "link.csv"
    link.symlink_to(tmp_path / "target.csv")
    atomic_write_text(link, "new\n")
    assert link.is_symlink() and (tmp_path / "target.csv").read_text() == "new\n"


def test_a_fifo_is_written_directly(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    f = AtomicFile(fifo)
    f.write("row 1\n")
    f.commit()
    reader.join(timeout=10)
    assert received == [b"row 1\n"]
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


def test_a_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="is a directory"):
        AtomicFile(tmp_path)


def test_a_missing_folder_names_it(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match="does not exist"):
        AtomicFile(tmp_path / "nope" / "x.csv")


def test_abort_keeps_the_partial_file_only_when_asked(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text("good\n")
    f = AtomicFile(path, partial=True)
    f.write("half")
    assert f.abort(keep_partial=True) == tmp_path / "log.csv.partial"
    assert path.read_text() == "good\n"
    assert (tmp_path / "log.csv.partial").read_text() == "half"
    g = AtomicFile(path, partial=True)
    assert g.abort() is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv"]


def test_an_output_that_is_an_input_is_refused(tmp_path: Path) -> None:
    """Issue 9 item 11."""
    src = tmp_path / "in.csv"
    src.write_text("x\n")
    with pytest.raises(OutputError, match=r"same file as INPUT\.csv"):
        check_outputs({"--output": tmp_path / "." / "in.csv"}, {"INPUT.csv": src})


def test_an_output_hard_linked_to_an_input_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "in.csv"
    src.write_text("x\n")
    os.link(src, tmp_path / "alias.csv")
    with pytest.raises(OutputError, match="same file"):
        check_outputs({"--output": tmp_path / "alias.csv"}, {"INPUT.csv": src})


def test_an_output_symlinked_to_an_input_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "in.csv"
    src.write_text("x\n")
    (tmp_path / "link.csv").symlink_to(src)
    with pytest.raises(OutputError, match="same file"):
        check_outputs({"--output": tmp_path / "link.csv"}, {"INPUT.csv": src})


def test_a_second_writer_of_the_same_partial_output_is_refused_and_the_first_kept(
        tmp_path: Path) -> None:
    """Issue 26 item 6: two runs with one --output both wrote (and emptied) TARGET.partial."""
    target = tmp_path / "log.csv"
    first = AtomicFile(target, partial=True)
    first.write("t_s,x\n0,1\n")
    first.sync()
    with pytest.raises(OutputError, match="another run is writing it"):
        AtomicFile(target, partial=True)
    first.write("1,2\n")
    first.commit()
    assert target.read_text() == "t_s,x\n0,1\n1,2\n"
    with AtomicFile(target, partial=True) as again:  # the lock went with the first run
        again.write("t_s,x\n")
    assert target.read_text() == "t_s,x\n"
