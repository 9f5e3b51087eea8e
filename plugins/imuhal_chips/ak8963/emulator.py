"""AK8963 emulator: register file, measurement timing and status semantics, fed by physics.

Bus face (I2C; the first written byte is the register pointer, further bytes are written to
successive registers; reads auto-increment, wrapping 0x0C -> 0x00 and 0x12 -> 0x10):
- WIA 0x48, INFO, ST1 (DRDY, DOR), HXL..HZH little-endian, ST2 (HOFL, BITM), CNTL1 (BIT,
  MODE), CNTL2 (SRST), ASTC, I2CDIS, ASAX..ASAZ (readable only in fuse-ROM mode, else 0x00).
- Writing CNTL1 re-initialises ST1..ST2. Continuous modes 1/2 measure at 8/100 Hz, single
  mode measures once (7.2 ms) and returns to power-down.
- Reading a data register clears DRDY and DOR and protects the data until ST2 is read; a
  measurement finishing meanwhile is held and appears (with DRDY) when ST2 ends the read. A
  measurement finishing while DRDY is still set overwrites the data and sets DOR.
- HOFL is set when |X| + |Y| + |Z| >= 4912 uT; each axis also clips at the data range.
- Its own clock: continuous measurements complete every 1/8 s or 1/100 s divided by
  1 + ``oscillator_error`` (default 0; the register map states no tolerance for the
  AK8963's internal oscillator, so tests and scripts set up to +-2 %, issue 25), counted
  from the CNTL1 write; each takes the truth of its own completion instant
  (``pull_physics``), whether the host reads it then or a master (the MPU-9250's slave 0,
  ``EmulatedBus.transfer_at``) copies it later.

Physics face: ``physics.magnetic_field_ut`` in the AK8963's own axes (uT), divided by the
sensitivity (0.15 or 0.6 uT/LSB) times the part's ASA adjustment, so the driver's Hadj
recovers the true field. Sensitivities and the adjustment are this module's own, written
from the register map (Hadj = H * ((ASA - 128) * 0.5 / 128 + 1)), never the driver's.

Faults: ``wia`` (clone), ``stuck_data_ready`` (no measurement completes while it lasts; the
continuous mode then resumes on its own cadence, nothing dated inside the hang), ``silent_reset()``,
``absent`` and bus errors through the bus.

Source of facts: MPU-9250 Register Map rev 1.4 section 5; imuhal shared chip facts section 4.
"""

from __future__ import annotations

import random
import struct

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.samples import Quantity
from imuhal.emulation import ChipEmulator, HangsBetweenTransfers
from imuhal_chips.ak8963 import registers as r
from imuhal_chips.ak8963.error_spec import AK8963_ERROR_SPEC

DEFAULT_ASA = (176, 177, 165)
"""Fuse-ROM adjustment of the emulated part (values from the shared ASA examples)."""

_SENSITIVITY = {True: (0.15, 32760), False: (0.6, 8190)}
"""CNTL1.BIT set (16-bit output) or clear (14-bit) -> (uT per LSB, largest |count|)."""
_PERIOD_S_BY_MODE = {0b0010: 1 / 8, 0b0110: 1 / 100}
"""CNTL1.MODE continuous measurement mode 1 (8 Hz) and mode 2 (100 Hz)."""
_MEASUREMENT_S = 7.2e-3
"""Single measurement time (max, register map section 5)."""
_NEW_DATA = r.ST1_DRDY | r.ST1_DOR
"""ST1's bits a data read clears."""
_RANGE_UT = 4912.0
"""Measurement range: HOFL when |X| + |Y| + |Z| reaches it."""


def _adjustment(asa: int) -> float:
    """The register map's sensitivity adjustment: Hadj = H * ((ASA - 128) * 0.5 / 128 + 1)."""
    return (asa - 128) * 0.5 / 128 + 1


class AK8963Emulator(HangsBetweenTransfers, ChipEmulator):
    """Register-level stand-in for an AK8963 (standalone or inside an MPU-9250)."""

    chip = "ak8963"
    error_spec = AK8963_ERROR_SPEC
    models_stuck_data_ready = True
    conformance_sweep = True
    pulls_physics = True
    min_output_period_s = _MEASUREMENT_S  # back-to-back single measurements

    def __init__(self, clock: Clock | None = None, *,
                 asa: tuple[int, int, int] = DEFAULT_ASA) -> None:
        super().__init__(clock)
        self.asa = asa
        self.asa_read: list[int] | None = None
        """What the fuse ROM reads when it differs from ``asa`` (fault injection); the
        sensor element still follows ``asa``."""
        self.wia = r.WIA
        """What WIA reads (fault injection: a clone or another part)."""
        self.stuck_data_ready = False
        self.resets = 0
        self.mode_violations = 0
        """Mode changes that skipped power-down (the datasheet forbids them)."""
        self._oscillator_error = 0.0
        self._pointer = 0
        self._reset()

    # -- fault injection --------------------------------------------------------------------

    def corrupt_trim(self, rng: random.Random, bits: int = 1) -> str:
        """Flip ``bits`` random bits of the fuse-ROM sensitivity adjustment (ASAX..ASAZ)."""
        stored = list(self.asa) if self.asa_read is None else self.asa_read
        changed = []
        for _ in range(bits):
            axis, bit = rng.randrange(3), rng.randrange(8)
            stored[axis] ^= 1 << bit
            changed.append(f"ASA{'XYZ'[axis]} bit {bit}")
        self.asa_read = stored
        return "fuse ROM " + ", ".join(changed)

    def silent_reset(self) -> None:
        """The chip resets on its own: power-down, registers at their defaults."""
        self.resets += 1
        self._reset()

    # -- conformance face -------------------------------------------------------------------

    def _resolution(self) -> tuple[float, int]:
        """(uT per LSB before adjustment, largest |count|) at the current CNTL1.BIT."""
        return _SENSITIVITY[bool(self._cntl1 & r.CNTL1_BIT)]

    def noise_period_s(self, channel: Quantity) -> float | None:
        """Continuous mode 1 / 2: 1/8 s / 1/100 s; None otherwise (single measurements
        come at the host's pace)."""
        if channel is not Quantity.MAG:
            return None
        return _PERIOD_S_BY_MODE.get(self._mode())

    def resolution(self, channel: Quantity) -> float:
        """The largest per-axis LSB (uT) at the current resolution and this part's ASA."""
        if channel is not Quantity.MAG:
            raise ValueError(f"the AK8963 has no {channel.value} channel")
        return self._resolution()[0] * max(_adjustment(a) for a in self.asa)

    def full_scale(self, channel: Quantity) -> float:
        """The smallest per-axis range (uT), at most the 4912 uT overflow limit."""
        if channel is not Quantity.MAG:
            raise ValueError(f"the AK8963 has no {channel.value} channel")
        ut_per_lsb, max_count = self._resolution()
        axis = max_count * ut_per_lsb * min(_adjustment(a) for a in self.asa)
        return min(axis, _RANGE_UT)

    @property
    def oscillator_error(self) -> float:
        """The internal oscillator's frequency error as a fraction (0.02: 2 % fast, each
        continuous-mode period 1/1.02 of the nominal); takes effect from the next period."""
        return self._oscillator_error

    @oscillator_error.setter
    def oscillator_error(self, fraction: float) -> None:
        self.checked_oscillator_error(fraction)
        self._oscillator_error = fraction

    def _period_ns(self, mode: int) -> int:
        return round(_PERIOD_S_BY_MODE[mode] * 1e9 / (1.0 + self._oscillator_error))

    # -- state ------------------------------------------------------------------------------

    def _reset(self) -> None:
        self._cntl1 = 0x00
        self._astc = 0x00
        self._clear_outputs()

    def _clear_outputs(self) -> None:
        self._st1 = 0x00
        self._st2 = 0x00
        self._data = bytearray(6)
        self._protected = False
        self._held: tuple[bytes, int] | None = None
        self._next_ns: int | None = None

    def _mode(self) -> int:
        return self._cntl1 & r.MODE_MASK

    def _start_mode(self) -> None:
        mode = self._mode()
        now = self.now_ns()
        if mode in _PERIOD_S_BY_MODE or mode == r.MODE_SINGLE:
            self._next_ns = now + round(_MEASUREMENT_S * 1e9)
        else:
            self._next_ns = None

    def _advance(self) -> None:
        now = self.now_ns()
        if self.stuck_data_ready:
            self._pass_hung(now)
            return
        while self._next_ns is not None and self._next_ns <= now:
            self.pull_physics(self._next_ns)
            self._complete(self._measure())
            mode = self._mode()
            if mode == r.MODE_SINGLE:
                self.record_measurements(self._next_ns, 0, 1)
                self._cntl1 &= ~r.MODE_MASK
                self._next_ns = None
            else:
                period = self._period_ns(mode)
                # Long gaps: skip ahead, keeping the last two measurements (enough for DOR).
                missed = (now - self._next_ns) // period
                skipped = max(missed - 1, 0)
                self.record_measurements(self._next_ns, period, 1 + skipped)
                self._next_ns += (skipped + 1) * period

    def _pass_hung(self, now: int) -> None:
        """The engine hangs (``stuck_data_ready``): the continuous-mode instants due by
        ``now`` pass with no measurement, none recorded, so after the hang the chip measures
        on its own cadence again. Left due, the first read after the hang would complete
        one dated inside it, copied up to a period later than any real measurement can be
        (behind the MPU-9250 a sample then carries the measurement before the one its stamp
        follows), and record every hung instant as measured when no CNTL1 write came
        between."""
        mode = self._mode()
        due = self._next_ns
        if due is None or due > now or mode not in _PERIOD_S_BY_MODE:
            return
        period = self._period_ns(mode)
        self._next_ns = due + ((now - due) // period + 1) * period

    def _measure(self) -> tuple[bytes, int]:
        field = self.physics.magnetic_field_ut or (0.0, 0.0, 0.0)
        ut_per_lsb, max_count = self._resolution()
        counts = []
        for value, asa in zip(field, self.asa, strict=True):
            count = round(value / (ut_per_lsb * _adjustment(asa)))
            counts.append(max(-max_count, min(max_count, count)))
        st2 = r.ST2_BITM if self._cntl1 & r.CNTL1_BIT else 0
        if sum(abs(v) for v in field) >= _RANGE_UT:
            st2 |= r.ST2_HOFL
        return struct.pack("<hhh", *counts), st2

    def _complete(self, result: tuple[bytes, int]) -> None:
        if self._protected:
            if self._held is not None:
                self._st1 |= r.ST1_DOR
            self._held = result
            return
        if self._st1 & r.ST1_DRDY:
            self._st1 |= r.ST1_DOR
        self._data[:] = result[0]
        self._st2 = result[1]
        self._st1 |= r.ST1_DRDY

    # -- bus face ---------------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self._advance()
        if write:
            self._pointer = write[0]
            for offset, value in enumerate(write[1:]):
                self._write(write[0] + offset, value)
        out = bytearray()
        for _ in range(read_len):
            out.append(self._read(self._pointer))
            self._pointer = self._increment(self._pointer)
        return bytes(out)

    def idle_answer(self, kind: BusKind, write: bytes, read_len: int) -> bytes | None:
        """The data read a bus master repeats (the MPU-9250's slave 0: ST1 or HXL on to
        ST2, the register pointer written first) changes nothing while no new measurement
        is there (DRDY and DOR clear, nothing protected or held), none falls due by now,
        and the pointer already stands past ST2, where the read leaves it: :meth:`bus_transfer`
        would leave every register, the pointer and the schedule as they are."""
        if len(write) != 1 or write[0] not in (r.REG_ST1, r.REG_HXL) \
                or write[0] + read_len - 1 != r.REG_ST2:
            return None
        if (self._pointer != self._increment(r.REG_ST2) or self._st1 & _NEW_DATA
                or self._protected or self._held is not None):
            return None
        due = self._next_ns
        if due is not None and due <= self.now_ns():
            return None
        block = bytes(self._data) + bytes((self._st2,))
        return block if write[0] == r.REG_HXL else bytes((self._st1,)) + block

    @staticmethod
    def _increment(address: int) -> int:
        if address == r.REG_ASTC:
            return r.REG_WIA
        if address == r.REG_ASAX + 2:
            return r.REG_ASAX
        return (address + 1) & 0xFF

    def _read(self, address: int) -> int:
        if address == r.REG_WIA:
            return self.wia
        if address == r.REG_INFO:
            return 0x9A
        if address == r.REG_ST1:
            return self._st1
        if r.REG_HXL <= address < r.REG_ST2:
            self._protected = True
            self._st1 &= ~(r.ST1_DRDY | r.ST1_DOR)
            return self._data[address - r.REG_HXL]
        if address == r.REG_ST2:
            value = self._st2
            self._st1 &= ~(r.ST1_DRDY | r.ST1_DOR)
            self._protected = False
            if self._held is not None:
                held, self._held = self._held, None
                self._complete(held)
            return value
        if address == r.REG_CNTL1:
            return self._cntl1
        if address == r.REG_ASTC:
            return self._astc
        if r.REG_ASAX <= address <= r.REG_ASAX + 2:
            stored = self.asa if self.asa_read is None else self.asa_read
            return stored[address - r.REG_ASAX] if self._mode() == r.MODE_FUSE_ROM else 0
        return 0x00

    def _write(self, address: int, value: int) -> None:
        if address == r.REG_CNTL1:
            old, new = self._mode(), value & r.MODE_MASK
            if old != r.MODE_POWER_DOWN and new != r.MODE_POWER_DOWN:
                self.mode_violations += 1
            self._cntl1 = value & (r.CNTL1_BIT | r.MODE_MASK)
            self._clear_outputs()
            self._start_mode()
        elif address == r.REG_CNTL2:
            if value & r.CNTL2_SRST:
                self.resets += 1
                self._reset()
        elif address == r.REG_ASTC:
            self._astc = value & 0x40
        # WIA, INFO, status, data and ASA are read-only
