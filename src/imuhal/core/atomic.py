"""Atomic file writing: a crash leaves either the old file or the new one, never half of one.

Everything imuhal writes for a user (CSV logs, truth files, profiles with calibration) goes
through here: the data go to a temporary file in the same folder (so the final rename never
crosses file systems), are flushed and fsync'ed, and only then replace the target.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import IO, Any


class AtomicFile:
    """A file that appears under ``path`` only on ``commit()`` (or a clean ``with``).

    Text (UTF-8) by default, bytes with ``binary=True``. ``mode_from`` copies the permission
    bits of an existing file (a profile rewritten in place keeps its mode).
    """

    def __init__(self, path: str | os.PathLike[str], *, newline: str | None = None,
                 binary: bool = False, mode_from: str | os.PathLike[str] | None = None) -> None:
        self.path = Path(path)
        self.mode_from = Path(mode_from) if mode_from is not None else None
        folder = self.path.parent if str(self.path.parent) else Path(".")
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=folder)
        self.tmp_path = Path(tmp)
        self.file: IO[Any] | None = (os.fdopen(fd, "wb") if binary else
                                     os.fdopen(fd, "w", newline=newline, encoding="utf-8"))

    def write(self, data: str | bytes) -> int:
        assert self.file is not None, "file already committed or aborted"
        return self.file.write(data)

    def commit(self) -> Path:
        """Flush, fsync and rename over the target; returns the target path."""
        if self.file is None:
            raise ValueError(f"{self.path}: already committed or aborted")
        self.file.flush()
        os.fsync(self.file.fileno())
        self.file.close()
        self.file = None
        try:
            if self.mode_from is not None and self.mode_from.exists():
                shutil.copymode(self.mode_from, self.tmp_path)
            os.replace(self.tmp_path, self.path)
        except BaseException:
            # Interrupted before the rename took effect: the target is untouched; leave no
            # temporary file behind either.
            self.tmp_path.unlink(missing_ok=True)
            raise
        _fsync_dir(self.path.parent)
        return self.path

    def abort(self) -> None:
        """Drop the temporary file; the target keeps whatever it had."""
        if self.file is not None:
            self.file.close()
            self.file = None
        self.tmp_path.unlink(missing_ok=True)

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with AtomicFile(path) as f:
        f.write(text)
    return Path(path)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *,
                       mode_from: str | os.PathLike[str] | None = None) -> Path:
    """Write ``data`` to ``path`` atomically (keeping ``mode_from``'s permissions)."""
    with AtomicFile(path, binary=True, mode_from=mode_from) as f:
        f.write(data)
    return Path(path)


def _fsync_dir(folder: Path) -> None:
    # The rename itself is durable only once the directory entry is on disk.
    try:
        fd = os.open(folder if str(folder) else ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
