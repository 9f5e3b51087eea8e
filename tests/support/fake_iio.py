"""A fake Linux IIO device: the sysfs folder and buffer character device a kernel driver
exports, written from the ABI (Documentation/ABI/testing/sysfs-bus-iio), in a temp folder."""

from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Element:
    """A scan element: name (``in_accel_x``), index, ``_type`` text and struct format."""

    name: str
    index: int
    type: str
    fmt: str
    """struct format of one stored value, e.g. ``<h`` for ``le:s16/16>>0``."""


@dataclass
class FakeIIODevice:
    sysfs: Path
    dev: Path
    number: int
    name: str
    attributes: dict[str, str]
    elements: list[Element] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.create()

    @property
    def folder(self) -> Path:
        return self.sysfs / f"iio:device{self.number}"

    @property
    def chardev(self) -> Path:
        return self.dev / f"iio:device{self.number}"

    def create(self) -> None:
        self.folder.mkdir(parents=True)
        (self.folder / "name").write_text(self.name + "\n")
        for attribute, value in self.attributes.items():
            (self.folder / attribute).parent.mkdir(parents=True, exist_ok=True)
            (self.folder / attribute).write_text(value + "\n")
        if self.elements:
            scan = self.folder / "scan_elements"
            scan.mkdir()
            for e in self.elements:
                (scan / f"{e.name}_en").write_text("0\n")
                (scan / f"{e.name}_index").write_text(f"{e.index}\n")
                (scan / f"{e.name}_type").write_text(e.type + "\n")
            (self.folder / "buffer").mkdir(exist_ok=True)
            (self.folder / "buffer" / "enable").write_text("0\n")
            (self.folder / "buffer" / "length").write_text("128\n")
            self.dev.mkdir(parents=True, exist_ok=True)
            self.chardev.write_bytes(b"")

    def remove(self) -> None:
        """The device is unbound (a loose wire, the module unloaded): its folder goes."""
        shutil.rmtree(self.folder)

    def read(self, attribute: str) -> str:
        return (self.folder / attribute).read_text().strip()

    def enabled(self) -> list[Element]:
        return [e for e in self.elements
                if self.read(f"scan_elements/{e.name}_en") == "1"]

    def push(self, *scans: dict[str, float]) -> None:
        """Append scans of the enabled elements to the character device, laid out as the ABI
        says: index order, each value aligned to its storage size, the scan padded to the
        largest one."""
        enabled = sorted(self.enabled(), key=lambda e: e.index)
        with self.chardev.open("ab") as f:
            for values in scans:
                data = bytearray()
                largest = 1
                for e in enabled:
                    size = struct.calcsize(e.fmt)
                    largest = max(largest, size)
                    data += bytes(-len(data) % size)
                    data += struct.pack(e.fmt, values[e.name])
                data += bytes(-len(data) % largest)
                f.write(bytes(data))
