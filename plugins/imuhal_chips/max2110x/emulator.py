"""Register-level emulators of the MAX21100 and MAX21105 (facts/chips.md sections 5, 6).

Bus face: a 64-address register file (0x00..0x1F banked by BANK_SELECT 0x22, 0x20..0x3F
common), the address byte (SPI bit 7 read; bit 6 = 1 no auto-increment, on I2C too),
power-on defaults and soft reset (RST_REG bit 3), read-only identity/status/data registers,
data-ready and overrun bits with the three DR_CFG clear modes, big/little-endian data
(I2C_CFG bit 1), I2C slave disable on I2C_CFG bit 0, and measurements on ``self.clock`` at
the configured ODRs (first sample one period after the power mode or ODR is written).
MAX21100 only: the I2C master, performing real transfers on the ``aux`` EmulatedBus:
- one-shot byte transactions (DR_CFG [5:4] trigger, MAG_SLV_ADD / I2C_MST_ADD / I2C_MST_DATA);
- the slave auto-read (facts section 6, steps 4-5): with MAG_SLV_CFG bit 7 set, every
  2^ACC_CFG2[3:1]-th accelerometer measurement (0x06 <- 0x00: each one) reads MAG_SLV_CFG
  [2:0] bytes from register MAG_SLV_REG of the slave at MAG_SLV_ADD in one transaction and
  stores them as MAG X, Y, Z (0x30..0x35): paired MSB first (bit 6 set: LSB first), ordered
  by MAG_MAP_REG [5:3] (0x00 as read, 0x08 the HMC5883L's X, Z, Y to X, Y, Z; other codes
  [UNVERIFIED], see ``_MAG_CHANNEL_ORDER``) and negated per axis by MAG_MAP_REG [2:0]
  (INV_X bit 0 .. INV_Z bit 2, [SS]). A byte count other than six is [UNVERIFIED]: all are
  read, the first six at most stored, fewer replace only the first bytes of the block. A
  transaction the slave NACKs or that fails leaves MAG X/Y/Z as they were (what I2C
  masters' copies of a slave do; no source describes the MAX21100's), counted in
  ``slave_read_failures``: the host sees the same words again, never a made-up value. The
  slave is read as at the accelerometer measurement's own instant
  (``EmulatedBus.transfer_at``), though the emulator carries it out at the first access
  after it: a slave with a clock of its own answers with what it had measured by then.
  MAG_SLV_CFG bits 5..3 (MAG_SAFE,
  MAG_GRP, I2C speed), the MAG_OFS registers and the mag data-ready bits of SYSTEM_STATUS
  (in conflict between sources) are not modelled.

Physics face: each measurement takes the inputs of its own instant (``pull_physics``: an
emulated board hands over the truth of that instant, whenever the host reads), encoded with
the configured sensitivity, rounded to counts and clipped at +/-30000 (the nominal full scale;
what silicon outputs beyond it is undocumented, so the emulator saturates there). A bare
emulator (no board) uses what ``set_physics`` gave it last.

Own clock (issue 25 item 1): the chip measures on its internal oscillator, each channel
every 1 / ODR x 1 / (1 + ``oscillator_error``), counted from the write that set its power
mode or rate. The datasheets give no tolerance for the internal oscillator (facts/chips.md
sections 5, 6 state none), so the default error is 0 and a test or script sets up to the
+-2 % issue 25 asks for; a change takes effect from the next measurement on. The instants of
the faster channel (the one the driver accounts for; the gyro on a tie) are recorded
(``measured_ns``), so a test can count what the chip produced.

FIFO (emulator_fifo.py states what is known and what is assumed, each once, and where each
part keeps its settings: MAX21105 FIFO_STORE 0x17, FIFO_THS 0x18, FIFO_CFG 0x19; MAX21100
FIFO_TH 0x17, FIFO_CFG 0x18): normal mode, gyro and accel stores, FIFO_COUNT in words,
FIFO_STATUS (data_lost, read_empty, ovthold, full, empty), FIFO_DATA popped a byte per byte
read; with the FIFO on, every measurement is latched in turn (none skipped while the host is
away) and a frame written for each, so a host stall shows as the chip's buffering would keep it.

Fault injection: ``who_am_i`` (set another value: a clone or the sibling part),
``stuck_data_ready`` (the measurement engine hangs: no new data, data-ready never set; a soft
reset cures it), ``silent_reset()`` (a brown-out: every register back to power-on defaults
without the host being told), ``absent`` (base class) and bus errors via the EmulatedBus.
INT1 (emulator_int.py states what is the MAX21105's and what is assumed for both parts): a
50 us active-high pulse at each measurement whose data-ready source bank 1 selects, driving
a profile's ``interrupt:`` line on an emulated board.

Not modelled: the FIFO's interrupt and snapshot modes, latched and motion interrupts, parity
address modes, self-test, OIS modes and on-chip fusion.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, NackError
from imuhal.core.samples import Quantity
from imuhal.emulation import (
    ChipEmulator,
    DisturbedLowPass,
    EmulatedBus,
    PhysicalInputs,
    PlannedInputs,
    world_counts,
)
from imuhal_chips.max2110x import emulator_int as intp
from imuhal_chips.max2110x.emulator_fifo import MAX21100_FIFO, MAX21105_FIFO, FifoMap, Max2110xFifo
from imuhal_chips.max2110x.error_spec import MAX21100_ERROR_SPEC, MAX21105_ERROR_SPEC
from imuhal_chips.max2110x.registers import (
    ACC_CFG2_MAG_RATE_MASK,
    ACC_CFG2_MAG_RATE_SHIFT,
    ACCEL_ON_MODES,
    ADDRESS_MASK,
    DR_CFG_CLEAR_SHIFT,
    DR_CFG_ONESHOT_MASK,
    DR_CFG_ONESHOT_READ,
    DR_CFG_ONESHOT_WRITE,
    DR_CFG_TEMP_EN,
    GYRO_ON_MODES,
    I2C_CFG_I2C_OFF,
    I2C_CFG_LITTLE_ENDIAN,
    MAG_DATA_BYTES,
    MAG_MAP_INVERT_MASK,
    MAG_MAP_SHIFT,
    MAG_SLV_CFG_ENABLE,
    MAG_SLV_CFG_LENGTH_MASK,
    MAG_SLV_CFG_SWAP,
    MAX21100,
    MAX21105,
    NO_INCREMENT_BIT,
    POWER_MODE_SHIFT,
    READ_BIT,
    RST_SW_RESET,
    PartSpec,
    Reg,
    Status,
)

# Conversion facts written here from the MAX21100/MAX21105 datasheets (sensitivity tables;
# GYRO_CFG1[1:0] and PWR_ACC_CFG[7:6] full-scale codes), never taken from the driver's
# setting tables, so a wrong sensitivity in the driver shows as a wrong rate or force.
_GYRO_LSB_PER_DPS_BY_CODE = (15.0, 30.0, 60.0, 120.0)
"""GYRO_CFG1[1:0]: 00 = +/-2000, 01 = 1000, 10 = 500, 11 = 250 dps."""
_ACCEL_LSB_PER_G_BY_CODE = (1875.0, 3750.0, 7500.0, 15000.0)
"""PWR_ACC_CFG[7:6]: 00 = +/-16, 01 = 8, 10 = 4, 11 = 2 g."""
# Low-pass filters (datasheet GYRO_CFG1[5:2] normal-mode bandwidth table, Hz; ACC_CFG1[5:4]
# output filter as a divisor of the accelerometer ODR: the cutoff is ODR / divisor).
_GYRO_BANDWIDTH_HZ_BY_CODE = (2.0, 4.0, 6.0, 8.0, 10.0, 14.0, 22.0, 32.0, 50.0, 75.0, 100.0,
                              150.0, 200.0, 250.0, 300.0, 400.0)
_ACCEL_LPF_ODR_DIVISOR_BY_CODE = (48, 22, 9, 3)
_COUNTS_AT_FULL_SCALE = 30000
"""Every range is 30000 counts wide (e.g. 2000 dps x 15 LSB/dps); outputs clip there."""
_TEMP_LSB_PER_DEGC = 256.0
_G_M_S2 = 9.80665
"""Standard gravity: the accelerometer's sensitivity is specified per g."""

ONESHOT_DURATION_NS = 100_000
"""A one-shot aux byte transaction completes 100 us after its trigger (about 4 bytes at
400 kHz); I2C_MST_DATA reads the previous value until then."""
ABSENT_SLAVE_BYTE = 0xFF
"""What a one-shot read returns when the slave does not acknowledge (released bus)."""

_GYRO_WORDS = frozenset(range(Reg.GYRO_X_H, Reg.GYRO_X_H + 6))
_ACCEL_WORDS = frozenset(range(Reg.ACC_X_H, Reg.ACC_X_H + 6))
_CONFIG_REGS = frozenset({Reg.POWER_CFG, Reg.GYRO_CFG1, Reg.GYRO_CFG2, Reg.PWR_ACC_CFG,
                          Reg.ACC_CFG1})
_GYRO, _ACCEL = 0, 1
"""Indexes of the two measurement channels in the per-channel lists (an Enum-keyed dict
lookup costs more than the rest of a register access)."""
_CHANNELS = (Quantity.GYRO, Quantity.ACCEL)
_DATA_READY = ((_GYRO, _GYRO_WORDS, int(Status.GYRO_DR)),
               (_ACCEL, _ACCEL_WORDS, int(Status.ACC_DR)))
"""Per channel: its data registers and the data-ready bit reading them clears."""
_DATA_FIRST = int(Reg.GYRO_X_H)
"""The data words run from here to the end of the common area (0x3F)."""
_WORDS_BE = struct.Struct(f">{(0x40 - _DATA_FIRST) // 2}H")
_WORDS_LE = struct.Struct(f"<{(0x40 - _DATA_FIRST) // 2}H")
_AXES_BE, _AXES_LE = struct.Struct(">3H"), struct.Struct("<3H")
"""One channel's three words, as ``_WORDS_BE`` / ``_WORDS_LE`` lay each out."""
_PAIR_BE, _PAIR_LE = struct.Struct(">6H"), struct.Struct("<6H")
"""The gyro's three words then the accelerometer's (0x24..0x2F, in that order), likewise."""
_WORD_BE, _WORD_LE = struct.Struct(">H"), struct.Struct("<H")

# The bus face runs for every SPI transaction, about 2600 per simulated second on the seed
# board (each aux byte is five of them); an IntEnum member lookup costs as much as the rest
# of a register access in CPython, so the hot paths compare against plain ints.
_I2C_MST_DATA = int(Reg.I2C_MST_DATA)
_I2C_MST_ADD = int(Reg.I2C_MST_ADD)
_MAG_SLV_ADD = int(Reg.MAG_SLV_ADD)
# SYSTEM_STATUS's bits as plain ints: the status byte stays an int (an IntFlag operation
# builds a flag object through the enum machinery, several times a register access's cost)
_GYRO_DR, _GYRO_ERR = int(Status.GYRO_DR), int(Status.GYRO_ERR)
_ACC_DR, _ACC_ERR = int(Status.ACC_DR), int(Status.ACC_ERR)
_DR_BITS = _GYRO_DR | _ACC_DR
_ERR_BITS = _GYRO_ERR | _ACC_ERR
_DR_CFG = int(Reg.DR_CFG)
_MAG_SLV_CFG = int(Reg.MAG_SLV_CFG)
_MAG_SLV_REG = int(Reg.MAG_SLV_REG)
_MAG_MAP_REG = int(Reg.MAG_MAP_REG)
_ACC_CFG2 = int(Reg.ACC_CFG2)
_MAG_X_H = int(Reg.MAG_X_H)
_MAG_CHANNEL_ORDER = ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0),
                      (0, 1, 2), (0, 1, 2))
"""MAG_MAP_REG [5:3] -> which slave word (0 = first read) becomes MAG X, Y, Z. Codes 0 (as
read) and 1 (A, C, B: the HMC5883L's X, Z, Y to X, Y, Z) are documented; 2..5 are
[UNVERIFIED], taken as the remaining permutations in lexicographic order (the order codes 0
and 1 follow); 6 and 7 [UNVERIFIED] keep the order read."""
_I2C_CFG = int(Reg.I2C_CFG)
_SYSTEM_STATUS = int(Reg.SYSTEM_STATUS)
_GYRO_X_H = int(Reg.GYRO_X_H)
_ACC_X_H = int(Reg.ACC_X_H)
_POWER_CFG = int(Reg.POWER_CFG)
_PWR_ACC_CFG = int(Reg.PWR_ACC_CFG)
_NEVER = float("inf")
_FIFO_COUNT = int(Reg.FIFO_COUNT)
_FIFO_STATUS = int(Reg.FIFO_STATUS)
_FIFO_DATA = int(Reg.FIFO_DATA)


AHEAD_NS = ChipEmulator.PULL_AHEAD_NS
"""How far past a FIFO fill or a latch the emulator announces its coming pulls (the base's
``PULL_AHEAD_NS``): numpy's per-call cost makes the truth of a fill of 8 alone dearer
vectorised than one by one, of a few hundred cheaper (tests/benchmarks/bench_truths.py)."""


def _encode(value: float, per_count: float, limit: int) -> int:
    """``value`` (SI) in counts of ``per_count``, rounded and clipped to +/-``limit``."""
    if not math.isfinite(value):
        return limit if value > 0 else -limit
    return max(-limit, min(limit, round(value / per_count)))


def _encode_rows(values: np.ndarray, per_count: float, limit: int) -> np.ndarray | None:
    """:func:`_encode` of every element of ``values`` (int64, the shape of ``values``), by the same
    operations: the quotient rounded half to even (``np.rint``, as ``round``) and clipped,
    a value that is not finite at the limit of its sign (NaN at the negative one). None
    where a finite value's quotient is not (``round`` would raise): left to ``_encode``."""
    with np.errstate(all="ignore"):
        quotient = values / per_count
        finite = np.isfinite(values)
        if not np.isfinite(quotient[finite]).all():
            return None
        counts = np.where(finite, np.clip(np.rint(quotient), -limit, limit),
                          np.where(values > 0, limit, -limit))
    return counts.astype(np.int64)


class Max2110xEmulator(ChipEmulator):
    """Family base; subclasses set ``chip``, ``part`` and their rate tables."""

    min_output_period_s = 1.0 / 8000.0  # the fastest gyro ODR code of both parts

    part: ClassVar[PartSpec]
    models_stuck_data_ready = True
    pulls_physics = True
    fifo_map: ClassVar[FifoMap]
    """The part's FIFO registers (emulator_fifo.py: one model, each part's map)."""
    gyro_odr_by_code: ClassVar[tuple[float, ...]]
    """GYRO_CFG2 ODR code -> Hz, written here from the part's datasheet (not the driver's)."""
    accel_odr_by_code: ClassVar[tuple[float, ...]]
    """ACC_CFG1 ODR code -> Hz, likewise."""

    def __init__(self, clock: Clock | None = None, *, name: str | None = None) -> None:
        super().__init__(clock)
        self.name = name or self.chip
        self.who_am_i = self.part.who_am_i
        self.stuck_data_ready = False
        self._oscillator_error = 0.0
        self.power_on_resets = 0
        self._plan_counts: list[tuple[PlannedInputs, float, np.ndarray | None, list | None]
                                | None] = [None, None]
        """Per channel: (plan, SI per count, every row's counts as an array and as lists) of
        the latest plan encoded."""
        self._plan_temperature: tuple[PlannedInputs, list | None] | None = None
        """(plan, every row's temperature counts) likewise."""
        self._plan_frames: tuple[PlannedInputs, float, float, bytes] | None = None
        """(plan, gyro and accelerometer SI per count, every row's FIFO frame packed) of the
        latest plan a fill was latched from (``_latch_fill``)."""
        self.fast_paths = True
        """The paths written for the common case: a FIFO fill's planned measurements
        latched at once, on the plan's arrays (:meth:`_latch_fill`), and both channels on
        one clock caught up as a pair (:meth:`_advance_pair`); False: the general paths
        (the reference the tests compare them with). The same registers, FIFO bytes and
        pulls either way."""
        self.fills_latched_at_once = 0
        """FIFO fills whose measurements (but the last instant's) were latched at once
        (since construction)."""
        self.pairs_latched_at_once = 0
        """Instants whose gyro and accelerometer measurements were latched together from
        the board's plan (``_latch_pair_planned``; since construction)."""
        self.power_on_reset()

    # --- state ----------------------------------------------------------------------------

    def power_on_reset(self) -> None:
        """Every register to its power-on default; measurements stop (power-down)."""
        self.banks = [bytearray(32) for _ in range(3)]
        for reg, value in self.part.bank0_defaults.items():
            self.banks[0][reg] = value
        self.bank = 0
        self.status = 0
        self._i2c_pointer = 0
        """Register (and no-increment bit) an I2C read without a register byte starts at."""
        self.words: dict[int, int] = {}  # high-byte address -> int16 value
        self._data_image: bytearray | None = None
        """Registers 0x24..0x3F as the bus reads them, kept up to date in place as words
        latch (``_store_axes``); None: to be rebuilt from ``words`` (after a change of the
        byte order)."""
        # Per channel (_GYRO, _ACCEL): registers read since the latch, next measurement,
        # measurement period and SI units per count; the last two follow the configuration
        # registers, which change only through _restart_timing.
        self._read_since_latch: list[set[int]] = [set(), set()]
        self._next_ns: list[int | None] = [None, None]
        self._started_ns: list[int] = [0, 0]
        """When each channel's timing last restarted (its first measurement a period on)."""
        self._period_ns: list[int] = [0, 0]
        self._per_count: list[float] = [0.0, 0.0]
        self._mst_data = 0
        self._mst_pending: tuple[int, int] | None = None
        self._wake_ns: float = _NEVER
        self._ahead_until_ns = -1
        """The latest instant already announced to the board (``_announce_instants``)."""
        self.fifo = Max2110xFifo(self.fifo_map)
        """The FIFO (empty after every reset)."""
        self._lowpass = (DisturbedLowPass(), DisturbedLowPass())
        """Per channel: its low-pass on what a value fault changed in the ADC's words
        (imuhal.sim.lowpass; restarted by every reset)."""
        self.stuck_data_ready = False
        self.power_on_resets += 1

    def silent_reset(self) -> None:
        """Fault: the chip resets (brown-out) without the host knowing."""
        self.power_on_reset()

    def bank0(self, reg: int) -> int:
        return self.banks[0][reg]

    # --- physics face ---------------------------------------------------------------------

    def set_physics(self, inputs: PhysicalInputs) -> None:
        if self.physics_source is None:
            self._advance()  # measurements due before the change use the old values
        super().set_physics(inputs)

    def set_planned(self, planned: PlannedInputs, index: int) -> None:
        """Row ``index`` of the board's plan, kept with the plan (``keep_planned``): a latch
        takes the row's counts, encoded for the whole plan at once (``_encode_rows``: the
        counts ``_encode`` gives the row's values)."""
        self.keep_planned(planned, index)

    def _planned_counts(self, plan: PlannedInputs, row: int, index: int) -> list[int] | None:
        """The counts channel ``index`` latches from row ``row`` of ``plan`` (None: the
        plan's values do not all encode; the row's inputs are encoded one by one)."""
        counts = self._plan_encoded(plan, index)[3]
        return None if counts is None else counts[row]

    def _plan_encoded(self, plan: PlannedInputs, index: int
                      ) -> tuple[PlannedInputs, float, np.ndarray | None, list | None]:
        """(plan, SI per count, counts, counts as lists) of channel ``index`` for every row
        of ``plan`` at the present sensitivity, encoded once per plan and sensitivity."""
        k = self._per_count[index]
        cached = self._plan_counts[index]
        if cached is None or cached[0] is not plan or cached[1] != k:
            values = plan.angular_rate_rad_s if index == _GYRO else plan.specific_force_m_s2
            counts = _encode_rows(values, k, _COUNTS_AT_FULL_SCALE)
            if counts is not None and counts.size \
                    and int(np.abs(counts).max()) >= _COUNTS_AT_FULL_SCALE:
                # a word at the rail: its residual runs through the low-pass, row by row
                # (``_latch``)
                counts = None
            cached = self._plan_counts[index] = (
                plan, k, counts, None if counts is None else counts.tolist())
        return cached

    def _planned_temperature(self, plan: PlannedInputs, row: int) -> int | None:
        """The temperature word's counts from row ``row`` of ``plan``, as ``_planned_counts``."""
        cached = self._plan_temperature
        if cached is None or cached[0] is not plan:
            encoded = _encode_rows(plan.temperature_degc, 1.0 / _TEMP_LSB_PER_DEGC, 32767)
            cached = self._plan_temperature = (
                plan, None if encoded is None else encoded.tolist())
        counts = cached[1]
        return None if counts is None else counts[row]

    @property
    def oscillator_error(self) -> float:
        """The internal oscillator's frequency error as a fraction (0.02: 2 % fast, every
        period 1/1.02 of the datasheet's); takes effect from the next measurement."""
        return self._oscillator_error

    @oscillator_error.setter
    def oscillator_error(self, fraction: float) -> None:
        self.checked_oscillator_error(fraction)
        self._advance()  # what is due now was measured on the old clock
        old = self._period_ns
        self._oscillator_error = fraction
        self._ahead_until_ns = -1
        for index, channel in enumerate(_CHANNELS):
            odr = self._odr_hz(channel)
            due = self._next_ns[index]
            if due is None or not odr:
                continue
            # count on from the latest measurement with the new period
            self._period_ns[index] = self._period_of(odr)
            self._next_ns[index] = due - old[index] + self._period_ns[index]
        self._schedule()

    def _period_of(self, odr_hz: float) -> int:
        return round(1e9 / (odr_hz * (1.0 + self._oscillator_error)))

    def _gyro_lsb_per_dps(self) -> float:
        return _GYRO_LSB_PER_DPS_BY_CODE[self.bank0(Reg.GYRO_CFG1) & 0x03]

    def _accel_lsb_per_g(self) -> float:
        return _ACCEL_LSB_PER_G_BY_CODE[self.bank0(Reg.PWR_ACC_CFG) >> 6 & 0x03]

    def resolution(self, channel: Quantity) -> float:
        """SI units per count for the current configuration."""
        if channel is Quantity.GYRO:
            return math.radians(1.0) / self._gyro_lsb_per_dps()
        if channel is Quantity.ACCEL:
            return _G_M_S2 / self._accel_lsb_per_g()
        if channel is Quantity.TEMPERATURE:
            return 1.0 / _TEMP_LSB_PER_DEGC
        raise ValueError(f"{self.chip} has no {channel.value} channel")

    def full_scale(self, channel: Quantity) -> float:
        """Largest SI magnitude the chip reports before saturating (current configuration)."""
        if channel is Quantity.TEMPERATURE:
            return 32767 / _TEMP_LSB_PER_DEGC
        return _COUNTS_AT_FULL_SCALE * self.resolution(channel)

    def _latch(self, index: int) -> None:
        bank0 = self.banks[0]
        gyro = index == _GYRO
        if gyro:
            first, enable_reg = _GYRO_X_H, _POWER_CFG
            dr, err = _GYRO_DR, _GYRO_ERR
        else:
            first, enable_reg = _ACC_X_H, _PWR_ACC_CFG
            dr, err = _ACC_DR, _ACC_ERR
        planned = self.planned
        x, y, z = self._channel_words(index, planned)
        enabled = bank0[enable_reg] & 0x07 if self.part.has_aux_master else 0x07
        if enabled != 0x07:
            x, y, z = (c if enabled & (1 << axis) else 0 for axis, c in enumerate((x, y, z)))
        self._store_axes(first, x, y, z)
        if gyro and bank0[_DR_CFG] & DR_CFG_TEMP_EN:
            temperature = None if planned is None else self._planned_temperature(*planned)
            if temperature is None:
                p = self.physics
                t = p.temperature_degc if p.temperature_degc is not None else 25.0
                temperature = _encode(t, 1.0 / _TEMP_LSB_PER_DEGC, 32767)
            self._store_word(self.part.temp_register, temperature)
        if self.status & dr:
            self.status |= err  # the previous sample was never read: it is lost
        self.status |= dr
        self._read_since_latch[index] = set()

    def _channel_words(self, index: int, planned: tuple[PlannedInputs, int] | None
                       ) -> tuple[int, int, int]:
        """Channel ``index``'s three output words from the inputs standing (the plan's row,
        encoded with the whole plan, where ``planned``), through its low-pass where a word
        is at the rail, a value fault replaced the input, or the filter still carries
        either (``_filtered``; a plan with a word at the rail is encoded row by row)."""
        gyro = index == _GYRO
        counts = None if planned is None else self._planned_counts(*planned, index)
        if counts is not None:
            x, y, z = counts
            if not self._lowpass[index].active:
                return x, y, z
            assert planned is not None
            plan, row = planned
            rows = plan.angular_rate_rad_s if gyro else plan.specific_force_m_s2
            return self._filtered(index, (x, y, z), rows[row].tolist())
        p = self.physics
        values = (p.angular_rate_rad_s if gyro else p.specific_force_m_s2) or (0.0, 0.0, 0.0)
        k = self._per_count[index]
        x, y, z = (_encode(v, k, _COUNTS_AT_FULL_SCALE) for v in values)
        if self.undisturbed is not None or self._lowpass[index].active \
                or _COUNTS_AT_FULL_SCALE in (abs(x), abs(y), abs(z)):
            return self._filtered(index, (x, y, z), values)
        return x, y, z

    def _filtered(self, index: int, words: tuple[int, int, int],
                  values: Sequence[float]) -> tuple[int, int, int]:
        """Channel ``index``'s output words when its ADC words (``words``, cut at the rail,
        from ``values``: what the chip measures, SI) differ from what the world would make
        of them without a rail or a value fault (``undisturbed`` if a fault replaced them,
        else ``values`` themselves), or its low-pass still carries such a difference: the
        world's words plus what the filter carries (imuhal.sim.lowpass), at the bandwidth
        and ODR the registers select."""
        channel = _CHANNELS[index]
        bandwidth = self.noise_bandwidth_hz(channel)
        period = self.noise_period_s(channel)
        if bandwidth is None or period is None:
            return words
        clean = self.undisturbed
        if clean is not None:
            values = (clean.angular_rate_rad_s if index == _GYRO
                      else clean.specific_force_m_s2) or (0.0, 0.0, 0.0)
        world = world_counts(values, self._per_count[index], _COUNTS_AT_FULL_SCALE)
        t_ns = self.physics_t_ns if self.physics_t_ns is not None else self.now_ns()
        return self._lowpass[index].output(t_ns, world, words, bandwidth, period,
                                           -_COUNTS_AT_FULL_SCALE, _COUNTS_AT_FULL_SCALE)

    def _store_axes(self, first: int, x: int, y: int, z: int) -> None:
        """Three data words from register ``first`` on (int16 values), in ``words`` and
        in the register image as the bus reads them (each latch writes its bytes in place:
        rebuilding the image at the next read cost more than the latch)."""
        words = self.words
        words[first] = x
        words[first + 2] = y
        words[first + 4] = z
        image = self._data_image
        if image is not None:
            layout = _AXES_LE if self.banks[0][_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN else _AXES_BE
            layout.pack_into(image, first - _DATA_FIRST, x & 0xFFFF, y & 0xFFFF, z & 0xFFFF)

    def _store_word(self, high: int, value: int) -> None:
        """One data word (an int16 value), as :meth:`_store_axes`."""
        self.words[high] = value
        image = self._data_image
        if image is not None:
            layout = _WORD_LE if self.banks[0][_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN else _WORD_BE
            layout.pack_into(image, high - _DATA_FIRST, value & 0xFFFF)

    # --- timing ---------------------------------------------------------------------------

    def _odr_hz(self, channel: Quantity) -> float | None:
        """The output data rate the configuration codes select (None: a reserved code)."""
        if channel is Quantity.GYRO:
            table, code = self.gyro_odr_by_code, self.bank0(Reg.GYRO_CFG2) & 0x0F
        else:
            table, code = self.accel_odr_by_code, self.bank0(Reg.ACC_CFG1) & 0x0F
        return table[code] if code < len(table) else None

    def noise_period_s(self, channel: Quantity) -> float | None:
        """1 / the ODR the configuration codes select (temperature: the gyro's). None: a
        reserved code, or the channel is powered down (it outputs nothing at any rate)."""
        if channel is Quantity.TEMPERATURE:
            channel = Quantity.GYRO
        if channel not in _CHANNELS or not self._active(channel):
            return None
        odr = self._odr_hz(channel)
        return 1.0 / odr if odr else None

    def noise_bandwidth_hz(self, channel: Quantity) -> float | None:
        """The low-pass filter's cutoff the configuration codes select: the gyro's
        bandwidth code (GYRO_CFG1[5:2]; temperature: the gyro's), the accelerometer's ODR
        over its output-filter divisor (ACC_CFG1[5:4]). None: powered down or a reserved
        rate code."""
        if channel is Quantity.TEMPERATURE:
            channel = Quantity.GYRO
        if channel not in _CHANNELS or not self._active(channel):
            return None
        if channel is Quantity.GYRO:
            return _GYRO_BANDWIDTH_HZ_BY_CODE[(self.bank0(Reg.GYRO_CFG1) >> 2) & 0x0F]
        odr = self._odr_hz(channel)
        divisor = _ACCEL_LPF_ODR_DIVISOR_BY_CODE[(self.bank0(Reg.ACC_CFG1) >> 4) & 0b11]
        return odr / divisor if odr else None

    def _active(self, channel: Quantity) -> bool:
        mode = (self.bank0(Reg.POWER_CFG) >> POWER_MODE_SHIFT) & 0x0F
        return mode in (GYRO_ON_MODES if channel is Quantity.GYRO else ACCEL_ON_MODES)

    def _restart_timing(self) -> None:
        now = self.now_ns()
        self._ahead_until_ns = -1  # the instants announced so far are on the old timing
        for index, channel in enumerate(_CHANNELS):
            odr = self._odr_hz(channel)
            if self._active(channel) and odr:
                self._period_ns[index] = self._period_of(odr)
                self._next_ns[index] = now + self._period_ns[index]
                self._started_ns[index] = now
            else:
                self._next_ns[index] = None
            self._per_count[index] = self.resolution(channel)
        self._schedule()

    def _schedule(self) -> None:
        """Note when ``_advance`` next has something to do (a measurement or the end of a
        one-shot transaction), so the accesses in between skip it."""
        wake: float = _NEVER
        for t in self._next_ns:
            if t is not None and t < wake:
                wake = t
        if self._mst_pending is not None and self._mst_pending[0] < wake:
            wake = self._mst_pending[0]
        self._wake_ns = wake

    def _counted(self) -> int:
        """The channel whose instants are recorded: the faster (the gyro on a tie)."""
        next_ns, periods = self._next_ns, self._period_ns
        return _GYRO if next_ns[_ACCEL] is None or (
            next_ns[_GYRO] is not None and periods[_GYRO] <= periods[_ACCEL]) else _ACCEL

    def _advance(self) -> None:
        now = self.clock.now_ns()
        if now < self._wake_ns:
            return
        if self._fifo_frame_channel() is not None:
            self._advance_each(now)
        else:
            self._advance_newest(now)
        if self._mst_pending is not None and now >= self._mst_pending[0]:
            self._mst_data = self._mst_pending[1]
            self._mst_pending = None
        self._schedule()

    def _advance_newest(self, now: int) -> None:
        """The measurements due by ``now``: each channel's newest is latched (the data
        registers keep one sample), the ones before it only counted (an overrun)."""
        next_ns = self._next_ns
        periods = self._period_ns
        due = next_ns[_GYRO]
        if due is not None and due == next_ns[_ACCEL] and periods[_GYRO] == periods[_ACCEL] \
                and self.fast_paths:
            self._advance_pair(now, due, periods[_GYRO])
            return
        counted = self._counted()
        due_now = sorted((due + (now - due) // periods[i] * periods[i], i)
                         for i, due in enumerate(next_ns) if due is not None and now >= due)
        if due_now and self.physics_ahead is not None and due_now[-1][0] > self._ahead_until_ns:
            # each channel's newest measurement pulls its inputs (one instant twice when
            # both channels measure then): while the host reads every measurement, the
            # pulls are every instant of each channel, in order
            self._announce_instants(due_now[0][0], now, each_channel=True)
        for newest, index in due_now:  # in the order the chip measured them
            due = next_ns[index]
            assert due is not None
            period = periods[index]
            missed = (newest - due) // period
            next_ns[index] = newest + period
            if self.stuck_data_ready:
                continue
            if index == counted:
                self.record_measurements(due, period, missed + 1)
            if missed:
                self.status |= _GYRO_ERR if index == _GYRO else _ACC_ERR
            self.pull_physics(newest)  # the newest measurement, with its instant's inputs
            self._latch(index)
            if index == _ACCEL:
                self._accel_latched(missed + 1, newest)

    def _advance_pair(self, now: int, due: int, period: int) -> None:
        """:meth:`_advance_newest` for both channels on one clock (the same period and
        phase: every bundled board's), due at ``due``: the same
        steps in the same order, written out for the pair (the gyro first, then the
        accelerometer, each pulling its inputs of the newest instant). Nothing before
        ``due`` (a wake for a one-shot transaction's end)."""
        if now < due:
            return
        missed = (now - due) // period
        newest = due + missed * period
        if self.physics_ahead is not None and newest > self._ahead_until_ns:
            self._announce_instants(newest, now, each_channel=True)
        self._next_ns[_GYRO] = self._next_ns[_ACCEL] = newest + period
        if self.stuck_data_ready:
            return
        self.record_measurements(due, period, missed + 1)  # the gyro, counted on a tie
        if missed:
            self.status |= _GYRO_ERR | _ACC_ERR
        # Both pulls taken from the board's plan in one step (the instant is announced
        # twice, once per channel: rows ``first`` and ``first + 1``), when it can give them
        take = self.physics_rows
        taken = None if take is None or self.frozen else take((newest, newest))
        if taken is None or not self._latch_pair_planned(*taken):
            if taken is not None:  # taken, but not latched at once: row by row, as pulled
                self.keep_planned(taken[0], taken[1])
            else:
                self.pull_physics(newest)
            self._latch(_GYRO)
            if taken is not None:
                self.keep_planned(taken[0], taken[1] + 1)
            else:
                self.pull_physics(newest)
            self._latch(_ACCEL)
        self._accel_latched(missed + 1, newest)

    def _latch_pair_planned(self, plan: PlannedInputs, row: int) -> bool:
        """:meth:`_latch` of the gyro from row ``row`` of ``plan`` then of the accelerometer
        from row ``row + 1`` (both pulls of one instant, taken at once by
        :meth:`_advance_pair`), written out for the common case: every axis on and the
        plan's counts encoded (``_plan_encoded``). The same words, register image,
        temperature word, status bits and reads-since-latch. False, latching nothing, where
        that case does not hold."""
        bank0 = self.banks[0]
        if self.part.has_aux_master and (bank0[_POWER_CFG] & 0x07 != 0x07
                                         or bank0[_PWR_ACC_CFG] & 0x07 != 0x07):
            return False
        if self._lowpass[_GYRO].active or self._lowpass[_ACCEL].active:
            return False  # a residual still fades through a low-pass: row by row
        gyro = self._plan_encoded(plan, _GYRO)[3]
        accel = self._plan_encoded(plan, _ACCEL)[3]
        if gyro is None or accel is None:
            return False
        gx, gy, gz = gyro[row]
        ax, ay, az = accel[row + 1]
        words = self.words
        words[_GYRO_X_H] = gx
        words[_GYRO_X_H + 2] = gy
        words[_GYRO_X_H + 4] = gz
        words[_ACC_X_H] = ax
        words[_ACC_X_H + 2] = ay
        words[_ACC_X_H + 4] = az
        image = self._data_image
        if image is not None:  # the gyro's words then the accelerometer's, from 0x24
            (_PAIR_LE if bank0[_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN else _PAIR_BE).pack_into(
                image, 0, gx & 0xFFFF, gy & 0xFFFF, gz & 0xFFFF, ax & 0xFFFF, ay & 0xFFFF,
                az & 0xFFFF)
        if bank0[_DR_CFG] & DR_CFG_TEMP_EN:  # the gyro's latch writes it, from its row
            temperature = self._planned_temperature(plan, row)
            if temperature is None:
                p = plan.row(row)
                t = p.temperature_degc if p.temperature_degc is not None else 25.0
                temperature = _encode(t, 1.0 / _TEMP_LSB_PER_DEGC, 32767)
            self._store_word(self.part.temp_register, temperature)
        status = self.status
        if status & _GYRO_DR:
            status |= _GYRO_ERR  # the previous sample was never read: it is lost
        if status & _ACC_DR:
            status |= _ACC_ERR
        self.status = status | _GYRO_DR | _ACC_DR
        self._read_since_latch = [set(), set()]
        self.pairs_latched_at_once += 1
        return True

    def _advance_each(self, now: int) -> None:
        """The measurements due by ``now``, every one latched in the order the chip made
        them (the FIFO stores each): after all channels due at an instant are latched, a
        frame is written when the FIFO's frame channel measured then."""
        next_ns = self._next_ns
        periods = self._period_ns
        # both channels on one clock (the same period and phase): each instant latches both
        paired = next_ns[_GYRO] is not None and next_ns[_GYRO] == next_ns[_ACCEL] \
            and periods[_GYRO] == periods[_ACCEL]
        events: list[tuple[int, int]] = []
        for index, due in enumerate(next_ns):
            if due is None:
                continue
            t = due
            while t <= now:
                events.append((t, index))
                t += periods[index]
            next_ns[index] = t
        events.sort()
        if events and self.physics_ahead is not None and events[-1][0] > self._ahead_until_ns:
            self._announce_instants(events[0][0], now)
        start, taken = 0, None
        if paired and len(events) > 2 and self.fast_paths:
            start, taken = self._latch_fill(events)
        self._latch_each(events, start, taken)

    def _latch_each(self, events: list[tuple[int, int]], start: int,
                    taken: tuple[PlannedInputs, int] | None) -> None:
        """``events`` from index ``start`` on latched one by one, in order, each instant
        pulling its inputs once; ``taken``: the plan and first row of the inputs of every
        instant but the last, already taken from the board (``_latch_fill``)."""
        periods = self._period_ns
        counted = self._counted()
        frame_channel = self._fifo_frame_channel()
        taken_until = 0 if taken is None else len(events) - 2
        pulled = None
        for k in range(start, len(events)):
            t, index = events[k]
            if self.stuck_data_ready:
                continue
            if index == counted:
                self.record_measurements(t, periods[index], 1)
            if t != pulled:  # the gyro and the accelerometer of one instant see one world
                if taken is not None and k < taken_until:
                    self.keep_planned(taken[0], taken[1] + k // 2)
                else:
                    self.pull_physics(t)
                pulled = t
            self._latch(index)
            if index == _ACCEL:
                self._accel_latched(1, t)
            last_at_t = k + 1 == len(events) or events[k + 1][0] != t
            if last_at_t and any(e == (t, frame_channel) for e in events[max(0, k - 1):k + 1]):
                self._fifo_write()

    def _latch_fill(self, events: list[tuple[int, int]]
                    ) -> tuple[int, tuple[PlannedInputs, int] | None]:
        """The measurements of ``events`` (both channels at each instant, gyro first, in
        time order) but the last instant's, latched at once: their inputs taken from the
        board's plan in one step (``physics_rows``), their counts the plan's rows encoded
        for the whole plan, their FIFO frames packed by one numpy call and written together,
        the slave auto-read following each accelerometer measurement in turn. The same
        registers, status bits, FIFO bytes, pulls and recorded instants as latching them
        one by one; the last instant is latched one by one by the caller, so what it leaves
        standing (the data words, the inputs, the board's latest update) is as before.

        Returns (events latched, None), or (0, None) where it does not apply (the chip hung
        or frozen, an axis disabled, the FIFO not storing both channels or overwriting its
        oldest frames, instants the board did not plan), or (0, (plan, first row)) when the
        rows were taken but the plan's values do not all encode at once: the caller then
        latches them one by one from those rows."""
        take = self.physics_rows
        if take is None or self.stuck_data_ready or self.frozen:
            return 0, None
        bank0 = self.banks[0]
        fifo = self.fifo
        if self.part.has_aux_master and (bank0[_POWER_CFG] & 0x07 != 0x07
                                         or bank0[_PWR_ACC_CFG] & 0x07 != 0x07):
            return 0, None
        if fifo.storing != (True, True) or fifo.cfg & fifo.map.overrun:
            return 0, None
        instants = [t for t, _ in events[0:-2:2]]
        taken = take(instants)
        if taken is None:
            return 0, None
        plan, first = taken
        frames = self._planned_frames(plan)
        if frames is None or self._lowpass[_GYRO].active or self._lowpass[_ACCEL].active:
            return 0, taken
        n = len(instants)
        self.record_measurements(instants[0], self._period_ns[_GYRO], n)
        # The data words, the temperature word and what was read since the latch are the
        # last instant's, which the caller latches; of these measurements only the status
        # stays: each channel's data-ready, and its overrun, for the last instant's latch
        # overwrites a sample never read.
        self.status |= _GYRO_DR | _GYRO_ERR | _ACC_DR | _ACC_ERR
        for t in instants:
            self._accel_latched(1, t)
        fifo.push_frames(frames[12 * first:12 * (first + n)], 12)
        self.fills_latched_at_once += 1
        return 2 * n, None

    def _planned_frames(self, plan: PlannedInputs) -> bytes | None:
        """Every row of ``plan`` as the FIFO frame it latches (the gyro's words then the
        accelerometer's, big-endian: ``_fifo_write``), packed by one numpy call once per plan
        and sensitivity; None where the plan's values do not all encode at once."""
        k_gyro, k_accel = self._per_count
        cached = self._plan_frames
        if cached is None or cached[0] is not plan or cached[1] != k_gyro \
                or cached[2] != k_accel:
            gyro = self._plan_encoded(plan, _GYRO)[2]
            accel = self._plan_encoded(plan, _ACCEL)[2]
            if gyro is None or accel is None:
                return None
            cached = self._plan_frames = (
                plan, k_gyro, k_accel,
                np.concatenate((gyro, accel), axis=1).astype(">i2").tobytes())
        return cached[3]

    def _announce_instants(self, first_ns: int, now: int, *, each_channel: bool = False
                           ) -> None:
        """Tell the board (``physics_ahead``) the instants at which the chip will pull its
        inputs from ``first_ns`` to ``PULL_AHEAD_NS`` past ``now``, as the clock stands: every
        instant at which a channel measures, once (the FIFO's path pulls once per instant),
        or once per channel measuring then (``each_channel``: the path that latches each
        channel's newest). The inputs of a FIFO fill's instants and of the next ones then
        come from one vectorised call. Pulls a later change of rate or clock, or a host
        that skips measurements, moves are computed when they happen (the board hands
        out what it computed only while the pulls come as announced), so nothing depends
        on this guess."""
        assert self.physics_ahead is not None
        until = now + self.PULL_AHEAD_NS
        instants = []
        for index, due in enumerate(self._next_ns):
            if due is None:
                continue
            period = self._period_ns[index]
            # the instants measured in this fill, then the coming ones (next_ns moved on)
            start = due - (due - first_ns) // period * period
            instants.append(np.arange(start, until + 1, period, dtype=np.int64))
        if instants:
            merged = np.concatenate(instants)
            self.physics_ahead((np.sort(merged, kind="stable") if each_channel
                                else np.unique(merged)).tolist())
        self._ahead_until_ns = until

    # --- FIFO (emulator_fifo.py: one model, each part's registers; what is assumed) -----

    def _fifo_frame_channel(self) -> int | None:
        """The channel at whose measurements the FIFO writes a frame: the faster measuring
        stored channel (the gyro on a tie); None: the FIFO stores nothing."""
        gyro, accel = self.fifo.storing
        gyro = gyro and self._next_ns[_GYRO] is not None
        accel = accel and self._next_ns[_ACCEL] is not None
        if gyro and accel:
            return _GYRO if self._period_ns[_GYRO] <= self._period_ns[_ACCEL] else _ACCEL
        if gyro or accel:
            return _GYRO if gyro else _ACCEL
        return None

    def _fifo_frame_words(self) -> int:
        return 3 * sum(self.fifo.storing)

    def _fifo_write(self) -> None:
        """Write one frame of the stored channels' latest words (gyro, then accel) to the
        FIFO, big-endian."""
        gyro, accel = self.fifo.storing
        image = self._data_image
        if gyro and accel and image is not None and not (
                self.banks[0][_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN):
            # gyro then accel words, big-endian: the image's first twelve bytes as they stand
            self.fifo.push(bytes(image[:12]))
            return
        firsts = ((_GYRO_X_H,) if gyro else ()) + ((_ACC_X_H,) if accel else ())
        words = self.words
        values = [words.get(first + 2 * axis, 0) for first in firsts for axis in range(3)]
        self.fifo.push(struct.pack(f">{len(values)}h", *values))

    def _fifo_register(self, reg: int) -> int:
        """FIFO_COUNT (words), FIFO_STATUS (read-to-clear bits) or a byte popped from
        FIFO_DATA; 0x3F (RST_REG) reads 0."""
        fifo = self.fifo
        if reg == _FIFO_COUNT:
            return min(fifo.words(), 0xFF)
        if reg == _FIFO_STATUS:
            return fifo.status(self._fifo_frame_words())
        if reg == _FIFO_DATA:
            return fifo.pop()
        return 0

    # --- INT1 pin (emulator_int.py: what is the MAX21105's and what is assumed) ------------

    models_interrupt = True

    def interrupt_pin(self) -> tuple[bool, int]:
        """Active high, a 50 us pulse [UNVERIFIED]."""
        return True, intp.INT_PULSE_NS

    def interrupt_after(self, after_ns: int) -> int | None:
        """The first measurement instant after ``after_ns`` of a channel whose data-ready
        drives INT1 (bank 1: INT_CFG_2 INT1 enable, INT_MSK bit 7, INT_SRC_SEL gyro_dr or
        acc_dr, INT_TMO_CFG 0 unlatched); None: the pin stays quiet."""
        self._advance()
        bank1 = self.banks[1]
        if (self.absent or self.stuck_data_ready or not bank1[intp.INT_CFG_2] & intp.INT1_ENABLE
                or not bank1[intp.INT_MSK] & intp.INT_MSK_ENABLE or bank1[intp.INT_TMO_CFG]):
            return None
        found: list[int] = []
        for index, source in ((_GYRO, intp.SRC_GYRO_DR), (_ACCEL, intp.SRC_ACCEL_DR)):
            due = self._next_ns[index]
            if due is None or not bank1[intp.INT_SRC_SEL] & source:
                continue
            period = self._period_ns[index]
            # the channel's instants run ... due - period, due, due + period ... from its
            # first measurement after the write that started it
            t = due - max(0, (due - after_ns - 1) // period) * period if after_ns < due \
                else due + ((after_ns - due) // period + 1) * period
            found.append(max(t, self._started_ns[index] + period))
        return min(found, default=None)

    # --- bus face -------------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        spi = kind is BusKind.SPI
        if not spi and self.banks[0][_I2C_CFG] & I2C_CFG_I2C_OFF:
            raise NackError(f"{self.name}: I2C slave disabled (I2C_CFG bit 0)")
        if self.clock.now_ns() >= self._wake_ns:
            self._advance()
        if spi and len(write) == 2 and not write[0] & READ_BIT:
            # One register written over SPI (every configuration write, and four of these
            # per aux master byte): the general path below, for this case alone.
            self._write(write[0] & ADDRESS_MASK, write[1])
            return bytes(read_len)
        if not write:
            if spi:
                raise BusError(f"{self.name}: a transaction must start with an address byte")
            # I2C: a read without a register byte continues from the register pointer.
            first = self._i2c_pointer | READ_BIT
        else:
            first = write[0]
        reg = first & ADDRESS_MASK
        increment = not first & NO_INCREMENT_BIT
        is_read = bool(first & READ_BIT) if spi else read_len > 0
        if spi and is_read and len(write) > 1:
            raise BusError(f"{self.name}: SPI read with data bytes after the address")
        step = 1 if increment else 0  # the address pointer moves by this after each byte
        for value in write[1:]:
            self._write(reg, value)
            reg = (reg + step) & ADDRESS_MASK
        if not is_read:
            if not spi:
                self._i2c_pointer = reg | (first & NO_INCREMENT_BIT)
            return bytes(read_len) if spi else b""
        out = self._read_burst(reg, read_len, step)
        if not spi:
            self._i2c_pointer = ((reg + read_len * step) & ADDRESS_MASK) | (
                first & NO_INCREMENT_BIT)
        return out

    def _read_burst(self, reg: int, read_len: int, step: int) -> bytes:
        """``read_len`` bytes from ``reg`` on, the pointer moving by ``step`` (0 or 1) after
        each. Reads have no side effects, so a burst is served as a slice of the register
        image; one register (status polls, the aux master's data) is read directly."""
        touched: Sequence[int]
        if read_len <= 1 or not step:
            touched = (reg,) if read_len else ()
            if reg == _FIFO_DATA:
                out = self.fifo.pop_many(read_len)  # each byte pops one
            else:
                out = bytes((self._read(reg),)) * read_len
        elif reg + read_len > _FIFO_COUNT:
            # the FIFO's registers have side effects: byte by byte, the pointer wrapping
            touched = [(reg + k) & ADDRESS_MASK for k in range(read_len)]
            out = bytes(self._read(r) for r in touched)
        elif reg >= _SYSTEM_STATUS:
            # status and data words only (every poll's burst): from the data image, which
            # the latches keep up to date, without the banked registers before them
            touched = range(reg, reg + read_len)
            data = self._data_image
            if data is None:
                data = self._data_image = self._data_bytes()
            if reg == _SYSTEM_STATUS:
                out = bytes((self.status,)) + data[:read_len - 1]
            else:
                out = bytes(data[reg - _DATA_FIRST:reg - _DATA_FIRST + read_len])
        elif reg + read_len <= ADDRESS_MASK + 1:
            touched = range(reg, reg + read_len)
            out = self._image()[reg:reg + read_len]
        else:  # the pointer wraps past 0x3F
            touched = [(reg + k) & ADDRESS_MASK for k in range(read_len)]
            image = self._image()
            out = bytes([image[r] for r in touched])
        self._after_read(touched)
        return out

    def _image(self) -> bytes:
        """The 64 registers as reads see them now (the selected bank, then the common
        area): what ``_read`` returns for each address."""
        bank = self.bank
        if bank > 2:
            low = bytes(32)
        elif bank == 0 and self.part.has_aux_master:
            b0 = self.banks[0]
            low = bytes(b0[:_I2C_MST_DATA]) + bytes((self._mst_data,)) + \
                bytes(b0[_I2C_MST_DATA + 1:])
        else:
            low = bytes(self.banks[bank])
        data = self._data_image
        if data is None:
            data = self._data_image = self._data_bytes()
        return low + bytes((self.who_am_i, self.part.revision, bank & 0x0F, self.status)) + data

    def _data_bytes(self) -> bytearray:
        """Registers 0x24..0x3F as ``_read`` gives them: each word in the configured byte
        order, a word never latched reads 0 (up to the temperature word: 0 too), the FIFO
        and unmodelled registers beyond it read 0."""
        words, limit = self.words, self.part.temp_register + 2
        values = [(words.get(high, 0) & 0xFFFF) if high in words or high < limit else 0
                  for high in range(_DATA_FIRST, 0x40, 2)]
        little = self.banks[0][_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN
        return bytearray((_WORDS_LE if little else _WORDS_BE).pack(*values))

    def _read(self, reg: int) -> int:
        if reg < 0x20:
            if self.bank > 2:
                return 0
            if reg == _I2C_MST_DATA and self.bank == 0 and self.part.has_aux_master:
                return self._mst_data
            return self.banks[self.bank][reg]
        if reg >= _FIFO_COUNT:
            return self._fifo_register(reg)
        if reg >= _GYRO_X_H:  # data words first: they are most of every burst
            high = reg & ~1
            if high in self.words or reg < self.part.temp_register + 2:
                word = self.words.get(high, 0) & 0xFFFF
                big_endian = not self.banks[0][_I2C_CFG] & I2C_CFG_LITTLE_ENDIAN
                first_byte = word >> 8 if big_endian else word & 0xFF
                second_byte = word & 0xFF if big_endian else word >> 8
                return first_byte if reg == high else second_byte
            return 0  # FIFO and unmodelled registers
        if reg == Reg.SYSTEM_STATUS:
            return self.status
        if reg == Reg.WHO_AM_I:
            return self.who_am_i
        if reg == Reg.REVISION:
            return self.part.revision
        if reg == Reg.BANK_SELECT:
            return self.bank & 0x0F
        return 0  # unreachable: 0x20..0x23 are the four above

    def _after_read(self, touched: Sequence[int]) -> None:
        mode = (self.banks[0][_DR_CFG] >> DR_CFG_CLEAR_SHIFT) & 0x03
        if _SYSTEM_STATUS in touched:
            if mode == 2:
                self.status &= ~_DR_BITS
            self.status &= ~_ERR_BITS
        if not self.status & _DR_BITS:
            return
        span = touched if type(touched) is range else None
        for index, regs, dr in _DATA_READY:
            if not self.status & dr:
                # Nothing to clear, and what was read since the latch no longer matters:
                # the bit comes back only with the next latch, which forgets it.
                continue
            seen = self._read_since_latch[index]
            if span is not None:  # a burst: the channel's registers it covers, by bounds
                first = _GYRO_X_H if index == _GYRO else _ACC_X_H
                seen.update(range(max(span.start, first), min(span.stop, first + 6)))
            else:
                seen.update(regs.intersection(touched))
            if (mode == 0 and len(seen) == 6) or (mode == 1 and seen):
                self.status &= ~dr

    def _write(self, reg: int, value: int) -> None:
        if reg < 0x20:
            if self.bank > 2:
                return
            self.banks[self.bank][reg] = value
            if self.bank == 0:
                if reg == _I2C_CFG:
                    self._data_image = None  # the byte order of the data words
                self._bank0_written(reg, value)
            return
        if reg == Reg.BANK_SELECT:
            self.bank = value & 0x0F
        elif reg == Reg.RST_REG and value & RST_SW_RESET:
            self.power_on_reset()
        # identity, status and data registers are read-only: writes are ignored

    def _oneshot(self, *, write: bool) -> None:
        """Aux master transaction; only the MAX21100 has the master."""

    def _accel_latched(self, measurements: int, instant_ns: int) -> None:
        """``measurements`` accelerometer measurements completed (the latest latched, at
        ``instant_ns``): the MAX21100's slave auto-read follows them."""

    def _bank0_written(self, reg: int, value: int) -> None:
        if reg in _CONFIG_REGS:
            self._restart_timing()
        if reg in self.fifo_map.registers:
            self.fifo.write(reg, value)
        if reg == _DR_CFG and self.part.has_aux_master:
            trigger = value & DR_CFG_ONESHOT_MASK
            if trigger == DR_CFG_ONESHOT_WRITE:
                self._oneshot(write=True)
            elif trigger == DR_CFG_ONESHOT_READ:
                self._oneshot(write=False)
            # the trigger field is a command, not a setting
            self.banks[0][reg] = value & ~DR_CFG_ONESHOT_MASK


class Max21105Emulator(Max2110xEmulator):
    """MAX21105 (WHO_AM_I 0xB4): gyro + accel + temperature at 0x30."""

    chip = "max21105"
    error_spec = MAX21105_ERROR_SPEC
    conformance_sweep = True
    part = MAX21105
    fifo_map = MAX21105_FIFO
    gyro_odr_by_code = (8000.0, 4000.0, 2000.0, 800.0, 400.0, 200.0, 100.0, 50.0, 25.0, 10.0)
    accel_odr_by_code = (2000.0, 800.0, 400.0, 200.0, 100.0, 50.0, 25.0, 10.0,
                         *(5.0,) * 8)  # 1xxx: 5 Hz


class Max21100Emulator(Max2110xEmulator):
    """MAX21100 (WHO_AM_I 0xB2): gyro + accel + temperature at 0x36, aux I2C master."""

    chip = "max21100"
    error_spec = MAX21100_ERROR_SPEC
    conformance_sweep = True
    part = MAX21100
    fifo_map = MAX21100_FIFO
    gyro_odr_by_code = (8000.0, 4000.0, 2000.0, 1000.0, 500.0, 250.0, 125.0, 62.5, 31.25,
                        15.625, 7.8125, 3.90625)
    accel_odr_by_code = (2000.0, 1000.0, 500.0, 250.0, 125.0, 62.5, 31.25)

    def __init__(self, clock: Clock | None = None, *, name: str | None = None) -> None:
        self._aux = EmulatedBus(f"{name or self.chip}/aux", BusKind.I2C)
        self.slave_reads = 0
        """Auto-read transactions the slave answered (since construction)."""
        self.slave_read_failures = 0
        """Auto-read transactions that failed (NACK, bus error): MAG X/Y/Z kept their data."""
        super().__init__(clock, name=name)

    def power_on_reset(self) -> None:
        super().power_on_reset()
        self._accel_count = 0
        """Accelerometer measurements since power-on: the auto-read follows every 2^code-th."""
        self._slave_block = bytes(MAG_DATA_BYTES)
        """The slave's bytes as last read (slave register order), before swap and map."""
        self._slave_stored: tuple[bytes, int, int] | None = None
        """(bytes, MAG_SLV_CFG swap bit, MAG_MAP_REG) that MAG X/Y/Z were last stored from:
        a copy of the same bytes with the same settings stores the same words."""

    def child_buses(self) -> dict[str, EmulatedBus]:
        return {"aux": self._aux}

    def _accel_latched(self, measurements: int, instant_ns: int) -> None:
        """Slave auto-read: with MAG_SLV_CFG enabled, every 2^ACC_CFG2[3:1]-th accelerometer
        measurement reads the slave's data into MAG X/Y/Z (0x30..0x35), at the instant of
        the newest (a slave with a clock of its own answers with what it had by then)."""
        bank0 = self.banks[0]
        cfg = bank0[_MAG_SLV_CFG]
        if not cfg & MAG_SLV_CFG_ENABLE:
            return
        every = 1 << ((bank0[_ACC_CFG2] & ACC_CFG2_MAG_RATE_MASK) >> ACC_CFG2_MAG_RATE_SHIFT)
        before = self._accel_count
        self._accel_count = before + measurements
        if self._accel_count // every != before // every:
            self._read_slave(cfg, instant_ns)

    def _read_slave(self, cfg: int, instant_ns: int) -> None:
        """One auto-read transaction: MAG_SLV_REG written to the slave at MAG_SLV_ADD, then
        the byte count read (repeated start); the bytes are paired (bit 6: each pair LSB
        first), mapped and inverted by MAG_MAP_REG, and stored as MAG X, Y, Z words (read
        out in the configured byte order like every data word). A transaction that fails
        (the slave NACKs, is absent, or the wire fails) changes nothing: the registers keep
        the last data, as I2C masters' copies of a slave do."""
        count = cfg & MAG_SLV_CFG_LENGTH_MASK
        if not count:
            return
        bank0 = self.banks[0]
        try:
            data = self._aux.transfer_at(instant_ns, bank0[_MAG_SLV_ADD] & 0x7F,
                                         bytes((bank0[_MAG_SLV_REG],)), count)
        except (BusError, OSError):
            self.slave_read_failures += 1
            return
        self.slave_reads += 1
        kept = min(count, MAG_DATA_BYTES)
        block = data[:kept] + self._slave_block[kept:]
        self._slave_block = block
        swap = cfg & MAG_SLV_CFG_SWAP
        mapping = bank0[_MAG_MAP_REG]
        stored = (block, swap, mapping)
        if stored == self._slave_stored:
            return  # the same bytes and settings: MAG X/Y/Z hold these words already
        self._slave_stored = stored
        slave_words = []
        for i in (0, 2, 4):
            high, low = (block[i + 1], block[i]) if swap else (block[i], block[i + 1])
            word = high << 8 | low
            slave_words.append(word - 0x10000 if word & 0x8000 else word)
        order = _MAG_CHANNEL_ORDER[(mapping >> MAG_MAP_SHIFT) & 0x07]
        invert = mapping & MAG_MAP_INVERT_MASK
        # two's complement negation in 16 bits (-(-32768) reads -32768 again)
        x, y, z = (-value if invert >> axis & 1 else value
                   for axis, value in enumerate(slave_words[o] for o in order))
        self._store_axes(_MAG_X_H, x, y, z)

    def _oneshot(self, *, write: bool) -> None:
        """Carry out a one-shot byte transaction on the aux bus (result after 100 us)."""
        bank0 = self.banks[0]
        slave = bank0[_MAG_SLV_ADD] & 0x7F
        register = bank0[_I2C_MST_ADD]
        done = self.clock.now_ns() + ONESHOT_DURATION_NS
        try:
            if write:
                self._aux.transfer(slave, bytes([register, bank0[_I2C_MST_DATA]]), 0)
                return
            value = self._aux.transfer(slave, bytes([register]), 1)[0]
        except (BusError, OSError):
            if write:
                return
            value = ABSENT_SLAVE_BYTE
        self._mst_pending = (done, value)
        self._wake_ns = min(self._wake_ns, done)
