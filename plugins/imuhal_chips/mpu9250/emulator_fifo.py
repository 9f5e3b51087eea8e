"""The MPU-9250's 512-byte FIFO, from the register-map side (rev 1.4; imuhal shared chip
facts, section 4 "FIFO"), for the emulator.

At every sample, while USER_CTRL.FIFO_EN is set, the bytes FIFO_EN selects are appended in
register order: ACCEL_XOUT_H..ACCEL_ZOUT_L (FIFO_EN[3]), TEMP_OUT (FIFO_EN[7]), GYRO X, Y, Z
(FIFO_EN[6:4], each its two bytes), then slave 0's EXT_SENS_DATA bytes (FIFO_EN[0], LENG of
I2C_SLV0_CTRL, as slave 0 copied them this sample). Slaves 1 to 3 are not modelled.

When a sample does not fit: CONFIG.FIFO_MODE = 1 drops the whole sample's bytes; 0 drops
the oldest bytes to make room, so the first frame left in the FIFO may start mid-frame.
Either sets INT_STATUS.FIFO_OFLOW_INT when INT_ENABLE.FIFO_OFLOW_EN is set. [UNVERIFIED
details: whether the chip drops whole samples or single bytes in FIFO_MODE 1, and whether
the status bit is set with the interrupt disabled; the register map says only "additional
writes will not be written" and "the oldest data ... dropped".]

FIFO_COUNTH/L give the byte count; each byte read from FIFO_R_W pops one (a burst read of N
pops N: the register pointer stays on FIFO_R_W); reading an empty FIFO returns 0xFF
[UNVERIFIED]. USER_CTRL.FIFO_RST empties it; H_RESET too.
"""

from __future__ import annotations

from collections import deque

from imuhal_chips.mpu9250 import registers as r

FIFO_EMPTY_READ = 0xFF
"""What FIFO_R_W returns with nothing in the FIFO [UNVERIFIED]."""


class FifoModel:
    """The FIFO's bytes and its overflow status."""

    def __init__(self, size: int = r.FIFO_SIZE_BYTES) -> None:
        self.size = size
        self._bytes: deque[int] = deque()
        self.frames_dropped = 0
        """Samples that did not fit whole (FIFO_MODE 1) or pushed older bytes out (0)."""

    def __len__(self) -> int:
        return len(self._bytes)

    def reset(self) -> None:
        self._bytes.clear()

    def push(self, frame: bytes, *, stop_when_full: bool) -> bool:
        """Append one sample's bytes; True when it overflowed."""
        room = self.size - len(self._bytes)
        if len(frame) <= room:
            self._bytes.extend(frame)
            return False
        self.frames_dropped += 1
        if stop_when_full:
            return True
        for _ in range(len(frame) - room):
            self._bytes.popleft()
        self._bytes.extend(frame)
        return True

    def pop(self) -> int:
        return self._bytes.popleft() if self._bytes else FIFO_EMPTY_READ

    def count_registers(self) -> tuple[int, int]:
        """(FIFO_COUNTH, FIFO_COUNTL)."""
        n = len(self._bytes)
        return (n >> 8) & 0x1F, n & 0xFF


def frame_of(regs: bytearray) -> bytes:
    """The bytes one sample appends, from the register file after the sample was latched."""
    enabled = regs[r.FIFO_EN]
    out = bytearray()
    if enabled & r.FIFO_ACCEL:
        out += regs[r.ACCEL_XOUT_H:r.ACCEL_XOUT_H + 6]
    if enabled & r.FIFO_TEMP:
        out += regs[r.ACCEL_XOUT_H + 6:r.ACCEL_XOUT_H + 8]
    for bit, offset in ((r.FIFO_GYRO_X, 0), (r.FIFO_GYRO_Y, 2), (r.FIFO_GYRO_Z, 4)):
        if enabled & bit:
            out += regs[r.GYRO_XOUT_H + offset:r.GYRO_XOUT_H + offset + 2]
    if enabled & r.FIFO_SLV0:
        length = regs[r.I2C_SLV0_CTRL] & r.SLV_LENG
        out += regs[r.EXT_SENS_DATA_00:r.EXT_SENS_DATA_00 + length]
    return bytes(out)
