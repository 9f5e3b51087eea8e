"""The buffered scan layout of an IIO device (kernel ABI, scan_elements/*_type and *_index).

``_type`` reads ``[be|le]:[f|s|u]bits/storagebits[Xrepeat][>>shift]``: byte order, float,
signed or unsigned, the valid bits, the bits the value occupies in the buffer, how often it
repeats, and the right shift to apply before masking the valid bits. In a scan the enabled
elements follow in ``_index`` order, each aligned to its own storage size, and the scan is
padded to a multiple of the largest storage size.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

_TYPE = re.compile(r"^(be|le):([fsu])(\d+)/(\d+)(?:X(\d+))?(?:>>(\d+))?$")


@dataclass(frozen=True)
class ScanType:
    big_endian: bool
    kind: str
    """``s`` signed, ``u`` unsigned, ``f`` IEEE 754 float."""
    bits: int
    storage_bits: int
    repeat: int = 1
    shift: int = 0

    @property
    def storage_bytes(self) -> int:
        return self.storage_bits // 8

    def decode(self, data: bytes) -> float:
        """The first value of ``data`` (``storage_bytes`` long) as a number."""
        if self.kind == "f":
            fmt = {2: "e", 4: "f", 8: "d"}[self.storage_bytes]
            return float(struct.unpack((">" if self.big_endian else "<") + fmt, data)[0])
        raw = int.from_bytes(data, "big" if self.big_endian else "little") >> self.shift
        raw &= (1 << self.bits) - 1
        if self.kind == "s" and raw & (1 << (self.bits - 1)):
            raw -= 1 << self.bits
        return float(raw)


def parse_scan_type(text: str) -> ScanType:
    """Parse a ``_type`` attribute; ValueError naming it when it is not one."""
    m = _TYPE.match(text.strip())
    if m is None:
        raise ValueError(f"{text!r} is not an IIO scan type ([be|le]:[f|s|u]bits/storage"
                         "bits[Xrepeat][>>shift])")
    order, kind, bits, storage, repeat, shift = m.groups()
    scan = ScanType(order == "be", kind, int(bits), int(storage), int(repeat or 1),
                    int(shift or 0))
    if scan.storage_bits % 8 or scan.storage_bits not in (8, 16, 32, 64) or \
            not 0 < scan.bits <= scan.storage_bits or (kind == "f" and scan.storage_bits == 8):
        raise ValueError(f"{text!r}: unsupported storage ({scan.bits}/{scan.storage_bits})")
    return scan


@dataclass(frozen=True)
class ScanElement:
    name: str
    """The element's name without ``_en``: ``in_accel_x``, ``in_timestamp``."""
    index: int
    type: ScanType
    offset: int = 0
    """Byte offset in the scan."""


def layout(elements: list[tuple[str, int, ScanType]]) -> tuple[list[ScanElement], int]:
    """The enabled elements placed in a scan, and the scan size in bytes."""
    placed = []
    position = 0
    largest = 1
    for name, index, scan in sorted(elements, key=lambda e: e[1]):
        size = scan.storage_bytes
        position = -(-position // size) * size
        placed.append(ScanElement(name, index, scan, position))
        position += size * scan.repeat
        largest = max(largest, size)
    return placed, -(-position // largest) * largest
