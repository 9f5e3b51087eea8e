"""Splitting a UART byte stream into NMEA sentences and UBX frames.

A receiver interleaves ASCII NMEA sentences (``$...*CS\\r\\n``) and binary UBX frames
(``B5 62 class id len16 payload ck_a ck_b``). The splitter keeps an incomplete tail for the
next read, and drops bytes that start neither (noise, a baud-rate mismatch) counting them.
It does not check checksums: the decoders do, so that a bad one is counted as such.
"""

from __future__ import annotations

from dataclasses import dataclass, field

UBX_SYNC = b"\xb5\x62"
MAX_NMEA_LEN = 120
"""Longer than any NMEA 0183 sentence (82 characters) with room for vendor ones."""
MAX_UBX_PAYLOAD = 1024


@dataclass
class StreamSplitter:
    """Feed bytes, get complete ``("nmea", line)`` / ``("ubx", frame)`` items."""

    buffer: bytearray = field(default_factory=bytearray)
    garbage_bytes: int = 0
    """Bytes that started no sentence or frame (noise, wrong baud rate)."""

    def feed(self, data: bytes) -> list[tuple[str, bytes]]:
        self.buffer += data
        out: list[tuple[str, bytes]] = []
        buf = self.buffer
        i = 0
        while i < len(buf):
            b = buf[i]
            if b == 0x24:  # '$'
                end = buf.find(b"\n", i)
                nxt = _next_start(buf, i + 1)
                if end < 0:
                    if nxt >= 0 or len(buf) - i > MAX_NMEA_LEN:
                        self.garbage_bytes += (nxt if nxt >= 0 else len(buf)) - i
                        i = nxt if nxt >= 0 else len(buf)
                        continue
                    break  # wait for the rest
                if 0 <= nxt < end:  # a sentence cut short by the start of the next one
                    self.garbage_bytes += nxt - i
                    i = nxt
                    continue
                out.append(("nmea", bytes(buf[i:end + 1])))
                i = end + 1
            elif b == 0xB5 and buf[i + 1:i + 2] in (b"\x62", b""):
                if len(buf) - i < 6:
                    break
                length = buf[i + 4] | buf[i + 5] << 8
                if length > MAX_UBX_PAYLOAD:
                    self.garbage_bytes += 2
                    i += 2
                    continue
                total = 8 + length
                if len(buf) - i < total:
                    break
                out.append(("ubx", bytes(buf[i:i + total])))
                i += total
            else:
                nxt = _next_start(buf, i)
                stop = nxt if nxt >= 0 else len(buf)
                self.garbage_bytes += stop - i
                i = stop
        del buf[:i]
        return out


def _next_start(buf: bytearray, start: int) -> int:
    """Index of the next '$' or UBX sync at or after ``start`` (-1: none)."""
    d = buf.find(b"$", start)
    u = buf.find(UBX_SYNC, start)
    cands = [x for x in (d, u) if x >= 0]
    if not cands and buf[-1:] == b"\xb5":
        return len(buf) - 1  # perhaps the first half of a sync
    return min(cands) if cands else -1
