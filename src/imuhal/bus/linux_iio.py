"""Linux Industrial I/O (IIO) as a bus: chips bound to kernel drivers, read through sysfs and
the buffered character device (kernel Documentation/ABI/testing/sysfs-bus-iio).

Many boards' chips already have mainline drivers (bmp280, inv_mpu6050 for the MPU-9250,
hmc5843, ms5611). The kernel then owns the chip; imuhal reads what the driver exports:
``/sys/bus/iio/devices/iio:deviceN/`` (``name``, ``in_accel_x_raw``, ``in_accel_scale``, ...,
``scan_elements/``, ``buffer/``) and ``/dev/iio:deviceN``.

So that tracing, recording and replay work as for any bus, every access is a transaction of
the one bus primitive (``transfer(target, write, read_len)``); the target is N of
``iio:deviceN``. The requests (first byte of ``write``):

* ``r`` + path: read a sysfs attribute (path relative to the device folder). Reply
  (``ATTR_LEN`` bytes): ``+`` and the value (whitespace stripped), or ``-`` when there is no
  such attribute; NUL padded.
* ``l`` + path: list a folder (``LIST_LEN`` bytes): ``+`` and the names, one per line, or
  ``-``; NUL padded.
* ``w`` + path + NUL + value: write an attribute (no reply).
* ``n``: drain the character device into the bus's queue; reply: the queued byte count (u32
  little-endian).
* ``b``: take ``read_len`` queued bytes (whole scans; the driver knows the scan size).
* ``c``: close the character device and drop the queue (after reconfiguring the buffer).

A device folder that is gone answers with NackError, like an absent I2C address.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import ClassVar

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.factory import BusFactory, BusSettings
from imuhal.core.errors import BusError, NackError

ATTR_LEN = 64
"""Reply size of an attribute read: sysfs values are short numbers or words."""
LIST_LEN = 4096
"""Reply size of a folder listing (scan_elements of a 9-axis IMU is about 40 names)."""
FOUND = b"+"
ABSENT = b"-"


class LinuxIIOBus(Bus):
    kind = BusKind.IIO

    def __init__(self, sysfs_root: str | os.PathLike[str] = "/sys/bus/iio/devices",
                 dev_root: str | os.PathLike[str] = "/dev") -> None:
        super().__init__(f"iio://{sysfs_root}")
        self.sysfs_root = Path(sysfs_root)
        self.dev_root = Path(dev_root)
        self._fds: dict[int, int] = {}
        self._queues: dict[int, bytearray] = {}

    def _folder(self, target: int) -> Path:
        folder = self.sysfs_root / f"iio:device{target}"
        if not folder.is_dir():
            self._close(target)
            raise NackError(f"no IIO device iio:device{target} in {self.sysfs_root}",
                            bus=self.name, target=target)
        return folder

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        op, arg = write[:1], write[1:].decode("utf-8", "replace")
        folder = self._folder(target)
        if op == b"r":
            return self._reply(target, self._read_text(folder / arg, target), read_len)
        if op == b"l":
            try:
                names = sorted(p.name for p in (folder / arg).iterdir())
            except FileNotFoundError:
                return self._reply(target, None, read_len)
            except OSError as exc:
                raise BusError(f"cannot list {folder / arg}: {exc}", bus=self.name,
                               target=target) from exc
            return self._reply(target, "\n".join(names), read_len)
        if op == b"w":
            path, _, value = arg.partition("\0")
            try:
                (folder / path).write_text(value)
            except OSError as exc:
                raise BusError(f"cannot write {value!r} to {folder / path}: "
                               f"{exc.strerror or exc}", bus=self.name, target=target) from exc
            return b""
        if op == b"n":
            return len(self._drain(target)).to_bytes(4, "little")
        if op == b"b":
            queue = self._queues.get(target, bytearray())
            if len(queue) < read_len:
                raise BusError(f"buffer holds {len(queue)} bytes, {read_len} asked",
                               bus=self.name, target=target)
            data = bytes(queue[:read_len])
            del queue[:read_len]
            return data
        if op == b"c":
            self._close(target)
            return b""
        raise BusError(f"unknown IIO request {write[:1]!r}", bus=self.name, target=target)

    def _read_text(self, path: Path, target: int) -> str | None:
        try:
            # some attributes end in a NUL after the newline (Linux 6.1's
            # current_timestamp_clock): neither is part of the value
            return path.read_text(encoding="utf-8").replace("\0", "").strip()
        except FileNotFoundError:
            return None
        except OSError as exc:
            if exc.errno == errno.ENODEV:
                raise NackError(f"{path}: device gone", bus=self.name, target=target) from exc
            raise BusError(f"cannot read {path}: {exc.strerror or exc}", bus=self.name,
                           target=target) from exc

    def _reply(self, target: int, text: str | None, read_len: int) -> bytes:
        body = ABSENT if text is None else FOUND + text.encode("utf-8")
        if len(body) > read_len:
            raise BusError(f"attribute value longer than {read_len - 1} bytes", bus=self.name,
                           target=target)
        return body.ljust(read_len, b"\0")

    def _drain(self, target: int) -> bytearray:
        queue = self._queues.setdefault(target, bytearray())
        fd = self._fds.get(target)
        if fd is None:
            path = self.dev_root / f"iio:device{target}"
            try:
                fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
            except OSError as exc:
                raise BusError(f"cannot open {path}: {exc.strerror or exc}. Are you in the "
                               "group that owns it (udev rule)?", bus=self.name,
                               target=target) from exc
            self._fds[target] = fd
        while True:
            try:
                chunk = os.read(fd, 65536)
            except BlockingIOError:
                break
            except OSError as exc:
                self._close(target)
                raise BusError(f"reading /dev/iio:device{target} failed: "
                               f"{exc.strerror or exc}", bus=self.name, target=target) from exc
            if not chunk:
                break
            queue += chunk
        return queue

    def _close(self, target: int) -> None:
        fd = self._fds.pop(target, None)
        self._queues.pop(target, None)
        if fd is not None:
            os.close(fd)

    def close(self) -> None:
        for target in list(self._fds):
            self._close(target)


class IIOSettings(BusSettings):
    sysfs_root: str = "/sys/bus/iio/devices"
    """Where the kernel lists IIO devices."""
    dev_root: str = "/dev"
    """Where the buffered character devices iio:deviceN are."""


class LinuxIIOFactory(BusFactory):
    scheme: ClassVar[str] = "iio"
    kind = BusKind.IIO
    Settings = IIOSettings
    description = "Linux IIO: chips bound to kernel drivers (sysfs and /dev/iio:deviceN)"

    @classmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        assert isinstance(settings, IIOSettings)
        if not Path(settings.sysfs_root).is_dir():
            raise BusError(f"{settings.sysfs_root} does not exist: is the kernel built with "
                           "IIO and a chip driver bound (see dmesg)?", bus=f"iio://{name}")
        return LinuxIIOBus(settings.sysfs_root, settings.dev_root)
