"""Splitting a UART byte stream into NMEA sentences and UBX frames.

A receiver interleaves ASCII NMEA sentences (``$...*CS\\r\\n``) and binary UBX frames
(``B5 62 class id len16 payload ck_a ck_b``). The splitter keeps an incomplete tail for the
next read, and drops bytes that start neither (noise, a baud-rate mismatch) counting them.

A UBX frame's length field says where the next item starts, so a corrupted one must not be
believed: a frame of a class the protocol does not define, or of a message whose length
the protocol fixes (NAV-PVT: 92) announcing another, is dropped at once; a frame whose
checksum fails is handed on (the decoder counts it and the driver flags it ``CRC_ERROR``),
and the stream is searched again from the byte after its sync characters, so the good
frames its wrong length covered are found. Inside the bytes a failed frame claimed, only
items with a good checksum are taken (its payload may hold bytes that look like a start).
NMEA checksums are left to the decoder: a sentence ends at its line feed or at the next
start, so a corrupted one costs only itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

UBX_SYNC = b"\xb5\x62"
MAX_NMEA_LEN = 120
"""Longer than any NMEA 0183 sentence (82 characters) with room for vendor ones."""
MAX_UBX_PAYLOAD = 1024
UBX_CLASSES = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x08, 0x09, 0x0A, 0x0B, 0x0C,
                         0x0D, 0x10, 0x13, 0x21, 0x27, 0x28, 0x29})
"""The UBX message classes u-blox protocol descriptions define (NAV, RXM, TRK, INF, ACK,
CFG, TUN, UPD, MON, AID, DBG, TIM, ESF, MGA, LOG, SEC, HNR, NAV2)."""
UBX_FIXED_PAYLOAD: dict[tuple[int, int], int] = {
    (0x01, 0x07): 92,  # NAV-PVT
    (0x05, 0x00): 2,  # ACK-NAK
    (0x05, 0x01): 2,  # ACK-ACK
}
"""Payload lengths the protocol fixes for the messages this driver reads (u-blox M8
protocol description)."""


@dataclass
class StreamSplitter:
    """Feed bytes, get complete ``("nmea", line)`` / ``("ubx", frame)`` items."""

    buffer: bytearray = field(default_factory=bytearray)
    garbage_bytes: int = 0
    """Bytes that started no sentence or frame (noise, wrong baud rate, a corrupt header)."""
    resyncs: int = 0
    """UBX frames whose header or checksum was wrong: the stream was searched again from the
    byte after their sync characters."""
    _claimed: int = 0
    """Buffer index up to which the bytes were claimed by a frame that failed its checksum."""

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
                        i = self._skip(i, nxt if nxt >= 0 else len(buf))
                        continue
                    break  # wait for the rest
                if 0 <= nxt < end:  # a sentence cut short by the start of the next one
                    i = self._skip(i, nxt)
                    continue
                line = bytes(buf[i:end + 1])
                if i < self._claimed and not _nmea_checksum_ok(line):
                    i = self._skip(i, i + 1)  # payload of a failed frame, not a sentence
                    continue
                out.append(("nmea", line))
                i = end + 1
            elif b == 0xB5 and buf[i + 1:i + 2] in (b"\x62", b""):
                if len(buf) - i < 6:
                    break
                length = buf[i + 4] | buf[i + 5] << 8
                if not _plausible(buf[i + 2], buf[i + 3], length):
                    self.resyncs += 1
                    i = self._skip(i, i + 2)
                    continue
                total = 8 + length
                if len(buf) - i < total:
                    break
                frame = bytes(buf[i:i + total])
                if _ubx_checksum_ok(frame):
                    out.append(("ubx", frame))
                    i += total
                    continue
                self.resyncs += 1
                if i >= self._claimed:  # a frame of its own: the decoder counts it
                    out.append(("ubx", frame))
                    self._claimed = i + total
                i = self._skip(i, i + 2)
            else:
                nxt = _next_start(buf, i)
                i = self._skip(i, nxt if nxt >= 0 else len(buf))
        del buf[:i]
        self._claimed = max(0, self._claimed - i)
        return out

    def _skip(self, i: int, to: int) -> int:
        """Count ``buf[i:to]`` as garbage unless a failed frame already claimed it."""
        self.garbage_bytes += max(0, to - max(i, self._claimed))
        return to


def _plausible(msg_class: int, msg_id: int, length: int) -> bool:
    """Whether a UBX header can be believed before its checksum is in."""
    if msg_class not in UBX_CLASSES or length > MAX_UBX_PAYLOAD:
        return False
    fixed = UBX_FIXED_PAYLOAD.get((msg_class, msg_id))
    return fixed is None or fixed == length


def _ubx_checksum_ok(frame: bytes) -> bool:
    """The 8-bit Fletcher checksum over class, id, length and payload."""
    ck_a = ck_b = 0
    for byte in frame[2:-2]:
        ck_a = (ck_a + byte) & 0xFF
        ck_b = (ck_b + ck_a) & 0xFF
    return frame[-2] == ck_a and frame[-1] == ck_b


def _nmea_checksum_ok(line: bytes) -> bool:
    """``$body*HH``: HH the XOR of the body's bytes, in hexadecimal."""
    star = line.rfind(b"*")
    if star < 0:
        return False
    check = 0
    for byte in line[1:star]:
        check ^= byte
    return line[star + 1:star + 3].upper() == f"{check:02X}".encode()


def _next_start(buf: bytearray, start: int) -> int:
    """Index of the next '$' or UBX sync at or after ``start`` (-1: none)."""
    d = buf.find(b"$", start)
    u = buf.find(UBX_SYNC, start)
    cands = [x for x in (d, u) if x >= 0]
    if not cands and buf[-1:] == b"\xb5":
        return len(buf) - 1  # perhaps the first half of a sync
    return min(cands) if cands else -1
