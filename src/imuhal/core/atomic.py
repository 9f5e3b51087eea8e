"""Safe file writing: a crash or a failed run never destroys a good file, and never leaves
half of one under the final name.

Everything imuhal writes for a user (CSV logs, truth files, traces, profiles with calibration)
goes through here. The rules:

* **Atomic replace.** Data go to a temporary file in the target's folder (so the final rename
  never crosses file systems), are flushed and fsync'ed, and only then replace the target.
  With ``partial=True`` the temporary file has a visible, documented name, ``TARGET.partial``,
  so a long log survives a power cut there up to its last ``sync()``; otherwise a hidden
  ``.TARGET.*.tmp``.
* **Symlinks are followed**: the file a link points to is replaced and the link is kept.
* **FIFOs and character devices** (``/dev/stdout``, a named pipe) are written directly: they
  cannot be replaced, and nothing could be lost there. Other special files (block devices,
  sockets, directories) are refused with an :class:`OutputError`.
* **Modes**: a replaced file keeps its permission bits; a new file gets ``0666`` minus the
  umask, like any file a shell redirection creates.
* **One writer**: a ``partial=True`` file is locked (``fcntl.flock``) from its creation to
  its rename, so a second run given the same output is refused with one line instead of
  both writing (and emptying) the same ``TARGET.partial``.
* **Inputs are never outputs**: :func:`check_outputs` refuses a command whose output is one of
  its inputs (same path after resolving links, or the same file through a hard link), and an
  output folder that is missing or not writable, before any work starts.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import signal
import stat
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any

from imuhal.core.errors import ImuhalError, OutputError

PARTIAL_SUFFIX = ".partial"
"""Suffix of the visible temporary file of a ``partial=True`` write (``log.csv.partial``)."""

PathLike = str | os.PathLike[str]


def resolve_target(path: PathLike) -> Path:
    """The file a write to ``path`` must change: ``path`` with every symlink followed (a
    dangling link yields the path it points to, which will be created). A special file
    reached through links (``/dev/stdout`` -> ``/proc/self/fd/1`` -> a pipe) is opened by
    the path given, since its resolved name may not be openable."""
    try:
        special = not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        special = False
    return Path(path) if special else Path(os.path.realpath(os.fspath(path)))


def _special_kind(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISFIFO(mode) or stat.S_ISCHR(mode):
        return "direct"
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a special file"


def current_umask() -> int:
    """The process umask, read without changing it where Linux allows."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no way to read it without setting it: put it straight back
    os.umask(mask)
    return mask


def check_writable(path: PathLike, what: str = "output") -> Path:
    """Fail early, before a board is opened or a long computation runs, when ``path`` cannot
    be written: its folder is missing or not writable, or it is a directory or a block
    device. Returns the resolved target."""
    given = Path(path)
    target = resolve_target(given)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{what} {given}: cannot be used: {exc.strerror or exc}") from None
    if st is not None:
        kind = _special_kind(st.st_mode)
        if kind == "direct":
            return target
        if kind is not None:
            raise OutputError(f"{what} {given}: is {kind}; give the path of a file to write")
    folder = target.parent
    if not folder.is_dir():
        raise OutputError(f"{what} {given}: folder {folder} does not exist; create it first "
                          f"(mkdir -p {folder}) or choose another path")
    try:  # really create a file there: permissions, ACLs and read-only mounts all show
        fd, probe = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".probe", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{what} {given}: folder {folder} is not writable "
                          f"({exc.strerror or exc}); choose a folder you can write to") from None
    if st is not None and not os.access(target, os.W_OK) and os.geteuid() != 0:
        # Replacing it by rename would succeed, but the user marked it read-only on purpose.
        raise OutputError(f"{what} {given}: the file is read-only; make it writable or "
                          "choose another path")
    return target


def _same_file(a: Path, b: Path) -> bool:
    if resolve_target(a) == resolve_target(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _partial_of(path: Path) -> Path:
    """The visible scratch file a ``partial=True`` write of ``path`` uses."""
    target = resolve_target(path)
    return target.with_name(target.name + PARTIAL_SUFFIX)


def check_outputs(outputs: Mapping[str, PathLike | None],
                  inputs: Mapping[str, PathLike | None] | None = None) -> None:
    """Refuse before any work when an output is also an input of the same command, when two
    outputs are the same file, or when an output cannot be written (:func:`check_writable`).

    Keys are how the user gave each path (``"--output"``, ``"INPUT.csv"``): every message
    names the two options and the file.
    """
    for label, p in (*outputs.items(), *(inputs or {}).items()):
        if p is not None and not os.fspath(p):  # `--output "$LOG"` with LOG unset
            raise OutputError(f"{label}: an empty path was given (an unset shell variable?); "
                              "give a file name")
    outs = [(label, Path(p)) for label, p in outputs.items() if p is not None]
    ins = [(label, Path(p)) for label, p in (inputs or {}).items() if p is not None]
    for label, out in outs:
        for in_label, inp in ins:
            if _same_file(out, inp):
                raise OutputError(
                    f"{label} {out}: is the same file as {in_label} {inp}; writing it would "
                    "destroy the input - choose another output path")
            if _same_file(_partial_of(out), inp):
                raise OutputError(
                    f"{label} {out}: its rows go to {_partial_of(out).name} while it is "
                    f"written, which is {in_label} {inp}; rename the input or choose another "
                    "output path")
    for i, (label, out) in enumerate(outs):
        for other_label, other in outs[i + 1:]:
            if (_same_file(out, other) or _same_file(_partial_of(out), other)
                    or _same_file(out, _partial_of(other))):
                raise OutputError(f"{label} {out} and {other_label} {other}: are the same file "
                                  "(or one is the other's .partial); give each output its own "
                                  "path")
    for label, out in outs:
        check_writable(out, label)


def open_seekable_partial(path: PathLike, option: str, why: str) -> AtomicFile:
    """A binary ``partial`` :class:`AtomicFile` for an output written in place (seeks back,
    rewrites a trailer): a pipe or device cannot be, so it is refused in one line naming
    ``option`` (the command-line option) and ``why``."""
    try:
        out = AtomicFile(path, binary=True, partial=True)
    except OutputError as exc:
        raise ImuhalError(f"{option} {exc}") from None
    if out.direct:
        out.abort()
        raise ImuhalError(f"{option} {path}: is a pipe or device; {why} - give a file path")
    return out


class AtomicFile:
    """A file that appears under ``path`` only on ``commit()`` (or a clean ``with``).

    Text (UTF-8) by default, bytes with ``binary=True``. ``mode_from`` copies the permission
    bits of an existing file; otherwise a replaced target keeps its own mode and a new one
    follows the umask. ``partial=True`` writes to the visible ``TARGET.partial`` (replaced if
    left over from an earlier run), which :meth:`sync` makes durable and :meth:`abort` can
    keep. When ``path`` is a FIFO or character device, data are written to it directly and
    commit only flushes (``direct`` is then True).
    """

    def __init__(self, path: PathLike, *, newline: str | None = None,
                 binary: bool = False, mode_from: PathLike | None = None,
                 partial: bool = False) -> None:
        self.path = Path(path)
        self.target = resolve_target(self.path)
        self.mode_from = Path(mode_from) if mode_from is not None else None
        self.partial = partial
        self.direct = False
        st: os.stat_result | None
        try:
            st = os.stat(self.target)
        except FileNotFoundError:
            st = None
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot be written: {exc.strerror or exc}") from None
        kind = _special_kind(st.st_mode) if st is not None else None
        if kind not in (None, "direct"):
            raise OutputError(f"{self.path}: is {kind}; give the path of a file to write")
        try:
            if kind == "direct":
                self.direct = True
                self.tmp_path = self.target
                fd = os.open(self.target, os.O_WRONLY | os.O_APPEND)
            elif partial:
                self.tmp_path = self.target.with_name(self.target.name + PARTIAL_SUFFIX)
                if self.tmp_path.is_symlink():
                    self.tmp_path.unlink()  # never write through a link at our scratch name
                # Not O_TRUNC: the file may be another run's, still writing; it is emptied
                # only once this run holds its lock.
                fd = os.open(self.tmp_path, os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW,
                             0o666)  # the kernel applies the umask
                _lock_or_refuse(fd, self.path, self.tmp_path)
                os.ftruncate(fd, 0)
            else:
                fd, tmp = tempfile.mkstemp(prefix=f".{self.target.name}.", suffix=".tmp",
                                           dir=self.target.parent)
                self.tmp_path = Path(tmp)
                os.chmod(fd, 0o666 & ~current_umask())  # mkstemp makes 0600
        except FileNotFoundError:
            raise OutputError(f"{self.path}: folder {self.target.parent} does not exist; create "
                              "it first or choose another path") from None
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot be written: {exc.strerror or exc}") from None
        self._keep_mode_of = self.mode_from if self.mode_from is not None else (
            self.target if st is not None else None)
        self.file: IO[Any] | None = (os.fdopen(fd, "wb") if binary else
                                     os.fdopen(fd, "w", newline=newline, encoding="utf-8"))
        if partial and not self.direct:
            _fsync_dir(self.tmp_path.parent)  # the visible name itself survives a power cut

    def write(self, data: str | bytes) -> int:
        assert self.file is not None, "file already committed or aborted"
        with self._write_errors():
            return self.file.write(data)

    @contextlib.contextmanager
    def _write_errors(self) -> Iterator[None]:
        """A full disk, a quota or an I/O error is the user's to fix, not a bug: one line
        naming the file (the target itself is untouched until commit)."""
        try:
            yield
        except BrokenPipeError:
            raise  # a reader that went away (`| head`): the CLI ends quietly, as before
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot be written: {exc.strerror or exc}; free "
                              "some space or choose another path") from None

    def sync(self) -> None:
        """Make everything written so far durable (flush and fsync), without committing: after
        a power cut it is in the temporary file (``TARGET.partial`` with ``partial=True``)."""
        if self.file is None:
            return
        with self._write_errors():
            self.file.flush()
            if not self.direct:
                os.fsync(self.file.fileno())

    def commit(self) -> Path:
        """Flush, fsync and rename over the target; returns the path written. Stop signals
        arriving meanwhile are held until it is done (a stop must not cut the commit)."""
        if self.file is None:
            raise ValueError(f"{self.path}: already committed or aborted")
        with _stop_signals_held():
            try:
                self.sync()
            except OutputError:
                self.abort(keep_partial=self.partial)  # the target stays as it was
                raise
            if self.direct:
                self.file.close()
                self.file = None
                return self.target
            try:
                keep = self._keep_mode_of
                if keep is not None and keep.exists():
                    os.chmod(self.tmp_path, stat.S_IMODE(os.stat(keep).st_mode))
                # Renamed while still open: a partial file's lock is held until it has its
                # final name, so no second run can take the scratch name and empty it first.
                os.replace(self.tmp_path, self.target)
            except BaseException:
                # The rename did not happen: the target is untouched. A visible partial file
                # is the only copy of the data, so it stays; a hidden temporary one goes.
                self.file.close()
                self.file = None
                if not self.partial:
                    self.tmp_path.unlink(missing_ok=True)
                raise
            self.file.close()
            self.file = None
            _fsync_dir(self.target.parent)
        return self.target

    def abort(self, *, keep_partial: bool = False) -> Path | None:
        """Leave the target as it was. The data written so far are dropped, or with
        ``keep_partial`` kept (synced) in the temporary file, whose path is returned."""
        if self.file is not None:
            # Best effort: abort runs after a failure, often the very write error (a full
            # disk) that would fail again here; what reached the file stays.
            with contextlib.suppress(OSError, OutputError):
                if keep_partial:
                    self.sync()
            with contextlib.suppress(OSError):
                self.file.close()
            self.file = None
        if self.direct:
            return None
        if keep_partial and self.tmp_path.exists():
            return self.tmp_path
        self.tmp_path.unlink(missing_ok=True)
        return None

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()


def _lock_or_refuse(fd: int, path: Path, scratch: Path) -> None:
    """Take the exclusive lock (``fcntl.flock``) of a partial file, or close it and refuse:
    another process writes the same output. Released when the file is closed, which
    happens after its commit renamed it (or on abort, or when the process dies)."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise OutputError(f"{path}: another run is writing it ({scratch.name} is locked); "
                              "wait for it to end or choose another output") from None
        raise OutputError(f"{path}: cannot lock {scratch.name}: "
                          f"{exc.strerror or exc}") from None


def atomic_write_text(path: PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically; returns the path written (links followed)."""
    with AtomicFile(path) as f:
        f.write(text)
    return f.target


def keep_backup(path: PathLike) -> Path | None:
    """Copy the file ``path`` is (links followed) to ``NAME.bak`` beside it, atomically and
    with its permissions, before it is replaced; None when there is no such file."""
    target = resolve_target(path)
    if not target.is_file():
        return None
    return atomic_write_bytes(target.with_name(target.name + ".bak"), target.read_bytes(),
                              mode_from=target)


def atomic_write_bytes(path: PathLike, data: bytes, *,
                       mode_from: PathLike | None = None) -> Path:
    """Write ``data`` to ``path`` atomically (keeping ``mode_from``'s permissions)."""
    with AtomicFile(path, binary=True, mode_from=mode_from) as f:
        f.write(data)
    return f.target


_HELD_SIGNALS = {getattr(signal, n) for n in ("SIGTERM", "SIGHUP", "SIGINT")
                 if hasattr(signal, n)}


@contextlib.contextmanager
def _stop_signals_held() -> Iterator[None]:
    """Hold SIGTERM, SIGHUP and SIGINT (delivered when the block ends) where the platform can."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


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
