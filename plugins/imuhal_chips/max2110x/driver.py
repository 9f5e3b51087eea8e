"""MAX21100 and MAX21105 drivers (Maxim 6-axis IMUs; the MAX21100 adds an aux I2C master).

Register facts: imuhal's chip-facts notes (chips.md) sections 5 (MAX21105 user guide rev 1.4) and 6
(MAX21100, from four independent code bases; no datasheet). Tables live in registers.py,
decoding in decode.py; this module only talks to the bus and keeps time.

Per poll the driver reads one burst from SYSTEM_STATUS through TEMP_L, so the data-ready
bits and every word come from one transaction. With ``read: fifo`` it reads the chip's
FIFO instead (imuhal_chips.max2110x.fifo, which states what of each part's FIFO is known
and what is assumed) and programs INT1 for a data-ready line
(registers.INT1_DATA_READY_PLAN, likewise assumed). Samples are in the chip's sensor frame:
gyro rad/s, accel m/s^2 specific force, temperature degC.

The FIFO holds gyro and accelerometer frames only. With a slave auto-read (the MAX21100's
MAG X/Y/Z, imuhal.bus.auto_read) the copy of the slave is a register the master overwrites
at each accelerometer measurement, so under ``read: fifo`` the driver reads it a poll-grid
guard after every chip instant between its FIFO reads (``_next_read_ns``, poll plan 3), one
transfer of the slave's bytes (and TEMP with them when due): 250 transfers a second at the
seed's 250 Hz beside the FIFO's count and burst (313 a second in all with ``fifo_frames:
8``, where reading the copy only with the FIFO made 82 and lost most of the HMC5883L's
fields), for the feed to see what a register poll's burst gives it.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from functools import partial
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from imuhal.bus.auto_read import AUTO_READ, AutoReadFeed, same_feed
from imuhal.bus.base import Bus, BusKind, Link
from imuhal.bus.register_plan import IN_PLACE_ATTEMPTS, RegisterPlan, retried
from imuhal.bus.registers import RegisterView
from imuhal.core.blocks import Block, IntArray, blocks_of
from imuhal.core.clock import Clock
from imuhal.core.errors import ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.poll_plan import CHIP_CLOCK_PLAN, FIFO_RESET_PLAN
from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    Sample,
    SampleFlag,
    TemperatureSample,
)
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.drivers.base import (
    BlockPoll,
    DeviceIdentity,
    Driver,
    PollResult,
    SettingsInput,
)
from imuhal.drivers.polling import DataReady, PollGrid, ResetWatch
from imuhal.drivers.validity import (
    NAN3,
    FrozenWatch,
    LowPassWatch,
    blank_flag,
    lowpass_coefficient,
    range_flag,
)
from imuhal_chips.max2110x import decode
from imuhal_chips.max2110x.aux_bus import Max21100AuxBus
from imuhal_chips.max2110x.decode import Counts3, be_int16
from imuhal_chips.max2110x.fifo import FifoRead, FifoReader
from imuhal_chips.max2110x.registers import (
    ACCEL_RANGE_G,
    DR_CFG_TEMP_EN,
    FULL_SCALE_COUNTS,
    GYRO_RANGE_DPS,
    I2C_CFG_I2C_OFF,
    INT1_DATA_READY_PLAN,
    MAG_DATA_BYTES,
    MAG_MAP_AS_READ,
    MAG_SLV_CFG_ENABLE,
    MAX21100,
    MAX21105,
    PARTS_BY_WHO_AM_I,
    RST_SW_RESET,
    STANDARD_GRAVITY_M_S2,
    TEMP_LSB_PER_DEGC,
    PartSpec,
    Reg,
    Scales,
    Status,
    acc_cfg1,
    accel_range_from_code,
    convention_for,
    gyro_cfg1,
    gyro_range_from_code,
    odr_from_code,
    pwr_acc_cfg,
)
from imuhal_chips.max2110x.settings import Max2110xSettings, Max21100Settings, Max21105Settings

SOFT_RESET_WAIT_S = 0.010
"""Wait after a soft reset before touching registers. [UNVERIFIED: no documented figure;
10 ms is generous for an OTP reload.]"""
TEMPERATURE_PERIOD_NS = 100_000_000
"""Temperature samples are emitted at most every 100 ms (it changes slowly)."""
EARLY_FRACTION = 64
"""The poll grid steps 1/64 period short of the nominal period until it has learnt the chip's
own period (``PollGrid(track=True)``), so it creeps earlier than a chip whose clock runs up to
~1.5 % fast instead of falling behind it; a poll that finds nothing re-finds the data a guard
later. Once the period is learnt the grid steps 1/512 period short of it: about one poll in
sixty finds nothing (one in eight with the fixed early step and an exact clock). A chip more
than 1.6 % fast lets no poll find nothing: the grid fell behind it and an overrun lost a
frame every ~240 periods (issue 25: 20 in 20 s at +2 %), so it doubles its shortfall once a
nominal clock would have shown it an empty poll (``PollGrid(catch_up=True)``)."""
FROZEN_AFTER_FRAMES = 10
"""Identical gyro + accel + temperature frames in a row that mean the measurement engine
hung. At rest the quietest setting (gyro +/-2000 dps, 15 LSB/dps, 0.005 dps/sqrt(Hz) over
a 2 Hz bandwidth: about 0.1 LSB) can repeat gyro words, but the accelerometer (150 ug/sqrt(Hz),
at least 5 LSB at +/-16 g; about 1 LSB behind the seed RC board's divisor-48 filter) and
the temperature word (about 5 LSB) do not: ten repeats of the whole frame have a
probability far below once per year of samples (0.05 s at 200 Hz). It was 50: the soak on
seed-rc-vario found a frozen MAX21105 in a turbulent cruise handing out valid frames more
than their error model off the truth from the 13th on (27 in 300 s, 68 in an hour)."""
TEMPERATURE_RANGE_DEGC = (-40.0, 85.0)
"""Operating range of the die; a temperature word outside it is not a real reading."""
SIDE_READ_PLAN = 3
"""The poll plan (imuhal.core.poll_plan) from which read: fifo with an auto-read slave reads
the slave's copy a guard after every instant between the FIFO reads (``_next_read_ns``);
before it, only beside each FIFO read (a recording made then replays on that plan)."""
_MAG_OFFSET = Reg.MAG_X_H - Reg.SYSTEM_STATUS
"""Where MAG X/Y/Z (the auto-read slave's bytes) start in a MAX21100 burst."""
_SIX_WORDS = struct.Struct(">6h")
"""Gyro X, Y, Z then accel X, Y, Z after the status byte: signed big-endian words."""
_BLANK_FF = b"\xff" * _SIX_WORDS.size
_BLANK_00 = b"\x00" * _SIX_WORDS.size
_MIN = np.minimum.reduce
_MAX = np.maximum.reduce
"""The ufuncs' reductions called directly (``ndarray.min`` goes through a Python wrapper
that costs more than the arithmetic on a read's few frames)."""
_AFTER_ACCEL = Reg.ACC_X_H + 6
"""0x30: MAG X/Y/Z then TEMP on the MAX21100 (0x30..0x37), TEMP on the MAX21105 (0x30,
0x31): what read: fifo reads beside the FIFO."""
_FAST_OVERRUN = {Quantity.GYRO: int(Status.GYRO_ERR), Quantity.ACCEL: int(Status.ACC_ERR)}
"""Each channel's own overrun bit (a sample of it overwritten before it was read)."""
_GYRO_DR = int(Status.GYRO_DR)
_ACC_DR = int(Status.ACC_DR)
_OVERRUN = int(Status.GYRO_ERR | Status.ACC_ERR)
"""Either channel's overrun bit: a sample overwritten before it was read."""


class Max2110xDriver(Driver):
    """Family base. Subclasses set ``name``, ``Settings`` and ``part``."""

    part: ClassVar[PartSpec]
    channels = (Quantity.GYRO, Quantity.ACCEL, Quantity.TEMPERATURE)
    bus_kinds = frozenset({BusKind.I2C, BusKind.SPI})
    resumes_in_a_row = IN_PLACE_ATTEMPTS
    """Each ``resume()`` reads the whole plan back (``_off_plan(overdue=True)``)."""
    specified_offset: ClassVar[Mapping[Quantity, float]] = {
        Quantity.ACCEL: 0.060 * 9.80665, Quantity.GYRO: math.radians(3.0)}
    """No MAX2110x datasheet was found: +-60 mg is assumed, the consumer-MEMS class of the
    MPU-9250's specified zero-g offset (and three times the emulator's assumed 20 mg
    spread); +-3 deg/s zero-rate offset likewise (three times the assumed 1 deg/s spread,
    inside the MPU-9250's +-5)."""
    settings: Max2110xSettings

    def __init__(
        self, link: Link, settings: SettingsInput, *, device: str,
        clock: Clock,
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.regs = RegisterView(link, convention_for(link.kind))
        self.scales: Scales | None = None
        self.plan: RegisterPlan | None = None
        """The configuration the chip must hold (set by configure(), with the auto-read's
        registers once one is enabled)."""
        self._power_on_ns = 0
        self._fast: Quantity = Quantity.GYRO
        self._searching = False
        self._asked_ns: int | None = None
        """The poll time the grid last asked for (a later poll's overrun is its own)."""
        self._last_temp_ns: int | None = None
        self._idle_since: int | None = None
        """The stamp of the latest valid frame of the accounted channel while every read
        since it was good and found no new sample of it (``health.idle``)."""
        self._read_whole = False
        """The latest burst read since start() completed and was not blank (a failed or
        blank one may have cleared the data-ready bits unseen: ``_deliver_burst``)."""
        self._grid = PollGrid(1, early_fraction=EARLY_FRACTION)
        self._ready = DataReady({})
        self._watch = ResetWatch(self.settings.reset_check_s)
        self._frozen = FrozenWatch(FROZEN_AFTER_FRAMES)
        s = self.settings
        self._memory = LowPassWatch(
            {Quantity.GYRO: lowpass_coefficient(s.gyro_lpf_hz, 1.0 / s.gyro_odr_hz),
             # the accelerometer's cutoff is its ODR over the divisor (ACC_CFG1)
             Quantity.ACCEL: lowpass_coefficient(1.0 / s.accel_lpf_divisor, 1.0)},
            {Quantity.GYRO: round(1e9 / s.gyro_odr_hz),
             Quantity.ACCEL: round(1e9 / s.accel_odr_hz)},
            FULL_SCALE_COUNTS,
            # settled once what a rail input can still add is within the part's offset
            {Quantity.GYRO: math.degrees(self.specified_offset[Quantity.GYRO])
             * FULL_SCALE_COUNTS / s.gyro_range_dps,
             Quantity.ACCEL: self.specified_offset[Quantity.ACCEL] / STANDARD_GRAVITY_M_S2
             * FULL_SCALE_COUNTS / s.accel_range_g})
        self._burst_frame = b""
        self._burst_length = 0
        """The status + data burst's address byte and length (set by configure())."""
        self._streams: tuple[StreamSpec, ...] = ()
        self._feed: AutoReadFeed | None = None
        """The slave auto-read, when a driver behind the MAX21100's master asked for one:
        the slave's bytes (MAG X/Y/Z) of every burst go to it."""
        self._fifo: FifoReader | None = None
        """read: fifo: the FIFO reader (made at configure(), for the period read back)."""
        self._fifo_kept = False
        """read: fifo: configure() kept the reader (the chip restarted at its period)."""
        self._overflow_pending = False
        self._aux_temp_bytes = self.part.temp_register + 2 - _AFTER_ACCEL
        self._aux_temp_frame = bytes((self.regs.read_address(_AFTER_ACCEL,
                                                             self._aux_temp_bytes),))
        self._aux_frames = {n: bytes((self.regs.read_address(_AFTER_ACCEL, n),))
                            for n in range(1, MAG_DATA_BYTES + 1)}
        """The read frame of the slave's first n bytes (MAG X/Y/Z: the MAX21100 only)."""
        self._fifo_due_ns = 0
        """read: fifo: when the next FIFO read is due (ns, driver clock); with an auto-read
        feed the polls before it read the slave's copy only (``_side_read``)."""
        self._edges_seen = False
        """read: fifo: data-ready edges came with this poll (a read the line triggered
        reads the FIFO, whatever the time)."""
        self._on_edges = False
        """read: fifo: the current poll is a read data-ready edges triggered (the side
        reads' schedule is not followed on a line: the slave's copy is read with it)."""

    # --- identity -------------------------------------------------------------------------

    def probe(self) -> DeviceIdentity:
        expected = f"WHO_AM_I=0x{self.part.who_am_i:02X} ({self.part.part})"
        try:
            found = retried(partial(self.regs.read_u8, Reg.WHO_AM_I))
        except NackError as exc:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found="no answer (NACK)",
                hint=self._absent_hint(),
            ) from exc
        if found != self.part.who_am_i:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found=f"WHO_AM_I=0x{found:02X}", hint=self._wrong_hint(found),
            )
        self.identity = DeviceIdentity(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            identity=f"WHO_AM_I=0x{found:02X}",
        )
        return self.identity

    def _absent_hint(self) -> str:
        if self.link.kind is BusKind.I2C:
            return ("check power and SDA/SCL wiring; the MAX2110x answers at 0x58 (SA0 low) "
                    "or 0x59 (SA0 high)")
        return "check power, chip select, MISO/MOSI/SCLK wiring and SPI mode 3"

    def _wrong_hint(self, found: int) -> str:
        other = PARTS_BY_WHO_AM_I.get(found)
        if other is not None:
            return f"this is a {other.part}: use driver {other.driver}"
        if found in (0x00, 0xFF):
            return (f"the bus reads all 0x{found:02X}: nothing drives MISO/SDA; check "
                    "wiring, chip select and SPI mode 3")
        return "another chip (or a clone) answers here; check the address/chip select"

    # --- configuration --------------------------------------------------------------------

    def register_plan(self) -> dict[int, int]:
        """Bank-0 register values for the settings (address -> value), in write order."""
        s, p = self.settings, self.part
        i2c_cfg = I2C_CFG_I2C_OFF if self.link.kind is BusKind.SPI else 0x00
        return {
            Reg.I2C_CFG: i2c_cfg,
            Reg.GYRO_CFG1: gyro_cfg1(s.gyro_range_dps, s.gyro_lpf_hz),
            Reg.GYRO_CFG2: p.gyro_odr_hz[s.gyro_odr_hz],
            Reg.PWR_ACC_CFG: pwr_acc_cfg(p, s.accel_range_g),
            Reg.ACC_CFG1: acc_cfg1(p, s.accel_lpf_divisor, s.accel_odr_hz),
            # data-ready cleared once all words of a channel are read; temperature on
            Reg.DR_CFG: DR_CFG_TEMP_EN,
            **self._fifo_plan(),
            Reg.POWER_CFG: p.power_cfg_on,  # last: start measuring with everything set
        }

    def _fifo_plan(self) -> dict[int, int]:
        """read: fifo: the channels stored, the threshold (a read's frames) and the FIFO's
        mode, at the part's own addresses."""
        if self.settings.read != "fifo":
            return {}
        return self.part.fifo.plan(self.settings.fifo_frames)

    def configure(self) -> None:
        """Soft reset, program bank 0 from the tables (power-down while writing), read back
        every register written and cache the active scales. Every transfer that fails is
        repeated in place and a register that reads back wrong written again
        (``RegisterPlan.retried``, ``verify(attempts=)``), so a glitch does not start the
        soft reset over (issue 26)."""
        for reg, value in ((Reg.BANK_SELECT, 0x00), (Reg.RST_REG, RST_SW_RESET)):
            retried(partial(self.regs.write, reg, value))
        self.clock.sleep(SOFT_RESET_WAIT_S)
        self._memory.forget()  # the reset restarted the chip's filters
        for reg, value in ((Reg.BANK_SELECT, 0x00), (Reg.POWER_CFG, 0x00)):
            retried(partial(self.regs.write, reg, value))
        plan = self._checked(self.register_plan())
        plan.apply(self.regs, attempts=IN_PLACE_ATTEMPTS)
        self._power_on_ns = self.clock.now_ns()  # measurements are timed from here
        readback = plan.verify(self.regs, attempts=IN_PLACE_ATTEMPTS, clock=self.clock)
        self._program_interrupt()
        self.plan = plan
        self._watch.spread_over(len(plan.steps))
        p = self.part
        self._burst_frame = bytes((self.regs.read_address(p.burst_start, p.burst_length),))
        self._burst_length = p.burst_length
        self._use_streams(readback)

    def _program_interrupt(self) -> None:
        """read: fifo: INT1 pulses at each gyro measurement (bank 1,
        ``INT1_DATA_READY_PLAN``), for a data-ready line that triggers the reads and stamps
        each frame (``interrupt:`` in the profile; without one the pin is simply unused).
        Read back; bank 0 selected again after."""
        if self.settings.read != "fifo":
            return
        self.regs.write(Reg.BANK_SELECT, 0x01)
        for reg, value in INT1_DATA_READY_PLAN.items():
            self.regs.write(reg, value)
        got = {reg: self.regs.read_u8(reg) for reg in INT1_DATA_READY_PLAN}
        self.regs.write(Reg.BANK_SELECT, 0x00)
        if got != dict(INT1_DATA_READY_PLAN):
            raise ConfigurationError(
                f"{self.describe()}: bank 1's interrupt registers read back "
                + ", ".join(f"0x{reg:02X}=0x{v:02X}" for reg, v in got.items())
                + f"; check the bus and that this is a {self.part.part}")

    def _use_streams(self, readback: Mapping[int, int]) -> None:
        """Take scales, periods and the poll grid from the specs of the registers read back."""
        self._streams = self._specs(readback)
        gyro, accel = self._streams[0], self._streams[1]
        self.scales = Scales(
            gyro_lsb_per_dps=GYRO_RANGE_DPS[gyro_range_from_code(readback[Reg.GYRO_CFG1])][1],
            accel_lsb_per_g=ACCEL_RANGE_G[accel_range_from_code(readback[Reg.PWR_ACC_CFG])][1],
        )
        periods = {Quantity.GYRO: gyro.period_ns, Quantity.ACCEL: accel.period_ns}
        self._ready = DataReady(periods)
        self._fast = min(periods, key=lambda c: periods[c])
        # CHIP_CLOCK_PLAN: catch up with a chip 2 % fast, keep the FIFO's period at a reset
        on_clock = self.poll_plan >= CHIP_CLOCK_PLAN
        self._grid = PollGrid(periods[self._fast], early_fraction=EARLY_FRACTION, track=True,
                              catch_up=on_clock, bounded=on_clock)
        if self.settings.read == "fifo":
            # a restart at the period it had (a reset, the same settings) keeps the reader,
            # so its chip clock keeps the period it learned (FifoReader.reset in start())
            period_ns = periods[self._fast]
            self._fifo_kept = on_clock and self._fifo is not None \
                and self._fifo.period_ns == period_ns
            if not self._fifo_kept:
                self._fifo = FifoReader(self.regs, period_ns, self.clock, self.part.fifo)
            if self._fifo is not None:
                self._fifo.chip_clock.keep_unsettled = self.poll_plan >= FIFO_RESET_PLAN

    def _specs(self, regs: Mapping[int, int]) -> tuple[StreamSpec, StreamSpec, StreamSpec]:
        """Gyro, accelerometer and temperature specs from configuration register values
        read from the chip: range from GYRO_CFG1[1:0] and PWR_ACC_CFG[7:6], rates from the
        ODR codes in GYRO_CFG2[3:0] and ACC_CFG1[3:0]."""
        p = self.part
        gyro_dps = gyro_range_from_code(regs[Reg.GYRO_CFG1])
        accel_g = accel_range_from_code(regs[Reg.PWR_ACC_CFG])
        gyro_hz = odr_from_code(p.gyro_odr_hz, regs[Reg.GYRO_CFG2] & 0x0F)
        accel_hz = odr_from_code(p.accel_odr_hz, regs[Reg.ACC_CFG1] & 0x0F)
        if gyro_hz is None or accel_hz is None:
            raise ConfigurationError(
                f"{self.describe()}: the chip reads back a reserved ODR code (GYRO_CFG2 "
                f"0x{regs[Reg.GYRO_CFG2]:02X}, ACC_CFG1 0x{regs[Reg.ACC_CFG1]:02X}); check "
                f"that this is a {p.part}")
        # The poll grid sits an eighth of the fastest period after each measurement; FIFO
        # frames are stamped at the chip's instant (the temperature is still polled).
        latency_s = min(1 / gyro_hz, 1 / accel_hz) / 8
        fifo = self.settings.read == "fifo"
        frame_latency_s = 0.0 if fifo else latency_s
        source = TimeSource.CHIP_CLOCK if fifo else TimeSource.HOST_POLL
        return (
            StreamSpec(self.device, Quantity.GYRO, Frame.SENSOR, gyro_hz,
                       scale=math.radians(1.0) / GYRO_RANGE_DPS[gyro_dps][1],
                       full_scale=math.radians(gyro_dps), latency_s=frame_latency_s,
                       time_source=source),
            StreamSpec(self.device, Quantity.ACCEL, Frame.SENSOR, accel_hz,
                       scale=STANDARD_GRAVITY_M_S2 / ACCEL_RANGE_G[accel_g][1],
                       full_scale=accel_g * STANDARD_GRAVITY_M_S2, latency_s=frame_latency_s,
                       time_source=source),
            StreamSpec(self.device, Quantity.TEMPERATURE, Frame.SENSOR,
                       min(gyro_hz, 1e9 / TEMPERATURE_PERIOD_NS),
                       scale=1.0 / TEMP_LSB_PER_DEGC, latency_s=latency_s),
        )

    def streams(self) -> tuple[StreamSpec, ...]:
        """Gyro (rad/s), accelerometer (m/s^2) and temperature (degC) in the chip's sensor
        frame, from the configuration read back at ``configure()``. Full scale: the
        configured range (the chip's nominal full scale is 30000 counts, so a larger word
        is not a measurement)."""
        return self._streams

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        if self.plan is None:
            raise ConfigurationError(f"{self.describe()}: streams read before configure()")
        self._streams = self._specs(self.plan.read(self.regs))
        return self._streams

    def _checked(self, values: Mapping[int, int]) -> RegisterPlan:
        """``values`` (register -> value, in write order) as a checked plan. Read back in
        bursts over the configuration block (POWER_CFG up to ACC_CFG1 or the auto-read's
        MAG_MAP_REG, skipping GYRO_CFG3) and one read for each register beyond it."""
        return RegisterPlan.of(
            self.describe(), values, names={reg: self.part.register_name(reg) for reg in values},
            gap=1,
            hint=f"check the bus (SPI mode 3, signal integrity) and that this is a "
                 f"{self.part.part}")

    # --- sampling -------------------------------------------------------------------------

    def start(self, now_ns: int) -> int:
        # configure() may have waited on the clock since the caller read it (the base
        # recover() passes the time from before its configure()): never start in the past
        now_ns = max(now_ns, self.clock.now_ns())
        # The chip measures one period after the power mode write and every period after;
        # the poll grid sits a guard after those instants.
        self._grid.anchor(self._power_on_ns + self._grid.guard_ns)
        self._searching = False
        self._asked_ns = None
        self._ready.start(now_ns)
        self._last_temp_ns = None
        self._idle_since = None
        self._read_whole = False
        self._watch.start(now_ns)
        if self._fifo is not None:
            self._fifo.reset(restart=True, same_oscillator=self._fifo_kept)
            self._fifo_due_ns = self._fifo.next_read_ns(now_ns, self._fifo_interval_ns())
            return self._next_read_ns(now_ns)
        return self._grid.next_after(now_ns)

    def _fifo_interval_ns(self) -> int:
        return self.settings.fifo_frames * self._grid.period_ns

    def _next_read_ns(self, now_ns: int) -> int:
        """read: fifo: the next poll after one at ``now_ns``: the next FIFO read, or, with an
        auto-read feed, the next side read when it comes first. Side reads lie a poll-grid
        guard after the chip's instants, as a register poll's burst does: whole periods of
        the chip's clock (learned by the FIFO reader) before or after the FIFO read, which
        sits at an instant (+-2 us); the FIFO read itself then reads no slave byte. The
        master's copy of the slave is a register, overwritten at every accelerometer
        measurement, not a FIFO entry: read only with the FIFO every n periods, a slave
        measurement copied in between was lost when the next one came, and the slave's
        fields were stamped up to n periods after their copy (the seed paraglider's HMC5883L
        ledger was off its chip's count by -218 to +329 of about 1,498 fields with
        ``fifo_frames`` 2 to 8; tests.benchmarks.fifo_mag_ledger). Read every period, the
        feed sees what it sees with read: registers (the same ledger, nothing lost); read
        every second period, the ledger was off by +13 again and 16 fields were lost. Read
        beside the FIFO (at the FIFO read's instant +-2 us) instead of a guard after, 3
        fields in 20 s were lost (two measurements with the same bytes that the HMC5883L
        driver's status read did not prove)."""
        due = self._fifo_due_ns
        if not self._side_reads() or self._fifo is None:
            return due
        period = self._fifo.chip_clock.period_ns
        guard = self._grid.guard_ns
        # side reads a guard after the instants the FIFO reads sit at (due - k periods),
        # where a register poll reads: the first more than half a guard after now
        k = math.ceil((due + guard // 2 - now_ns) / period) - 1
        return min(due, round(due + guard - max(k, 0) * period))

    def _side_reads(self) -> bool:
        """read: fifo reads a feed's copy between the FIFO reads (``_next_read_ns``)."""
        return self._feed is not None and self.poll_plan >= SIDE_READ_PLAN

    def _side_only(self, now_ns: int) -> bool:
        """read: fifo: this poll reads the slave's copy (and the temperature when due) only,
        not the FIFO: one ``_next_read_ns`` put before the FIFO read's time, not one a
        data-ready edge triggered."""
        edges, self._edges_seen = self._edges_seen, False
        self._on_edges = edges
        return self._side_reads() and not edges and now_ns < self._fifo_due_ns

    def _side_read(self, now_ns: int) -> PollResult:
        """read: fifo, a poll between FIFO reads: the slave's copy (and the temperature when
        due), delivered to the feed as a register poll delivers it."""
        return PollResult(self._aux_and_temperature(now_ns), self._next_read_ns(now_ns))

    def poll(self, now_ns: int) -> PollResult:
        """Read one burst; emit a sample per channel with new data.

        Scheduling keeps the polls phase-locked just after the chip's measurements, so a
        late poll (another device on the bus, a busy host) still finds its sample unread:
        a poll that finds no new data on the fastest channel retries a guard later and
        re-anchors the grid where the data appeared; an overrun (a sample overwritten
        before it was read) moves the grid half a period earlier to re-acquire the phase.
        A burst of all 0x00 or all 0xFF (nothing drives the bus) is no measurement, whatever
        its data-ready bits say; nor is a frame repeated FROZEN_AFTER_FRAMES times.
        """
        if self.scales is None:
            raise ConfigurationError(f"{self.describe()}: poll() before configure()")
        if self._watch.check_due(now_ns) and self._off_plan(overdue=False):
            return PollResult([], self.restart(reset_detected=True))
        if self._fifo is not None:
            return self._poll_fifo(now_ns)
        # a read that fails may have cleared the data-ready bits: no proof across it
        since, self._idle_since = self._idle_since, None
        whole, self._read_whole = self._read_whole, False
        raw = self.regs.send(self._burst_frame, self._burst_length)
        self._read_whole = not blank_flag(raw)
        status = raw[0]
        if self._feed is not None:
            self._deliver_burst(raw, whole, now_ns)
        gyro_ready = status & _GYRO_DR
        accel_ready = status & _ACC_DR
        bad = blank_flag(raw)
        if not bad and (gyro_ready or accel_ready):
            bad = self._frozen_flag(raw)
        gx, gy, gz, ax, ay, az = _SIX_WORDS.unpack_from(raw, 1)
        samples: list[Sample] = []
        gyro_flag = self._flag_of(Quantity.GYRO, gyro_ready, bad, now_ns)
        if gyro_flag is not None:
            samples.append(self._gyro_sample((gx, gy, gz), now_ns, gyro_flag))
        accel_flag = self._flag_of(Quantity.ACCEL, accel_ready, bad, now_ns)
        if accel_flag is not None:
            samples.append(self._accel_sample((ax, ay, az), now_ns, accel_flag))
        gyro_fast = self._fast is Quantity.GYRO
        fast_ready = gyro_ready if gyro_fast else accel_ready
        self._note_idle(since, gyro_flag if gyro_fast else accel_flag, bad, now_ns)
        stale = bool(gyro_flag) or bool(accel_flag)
        if gyro_ready and (
            self._last_temp_ns is None or now_ns - self._last_temp_ns >= TEMPERATURE_PERIOD_NS
        ):
            self._last_temp_ns = now_ns
            samples.append(self._temperature_sample(be_int16(raw, len(raw) - 2), now_ns, bad))
        if stale:
            return PollResult(samples, self._after_stale(now_ns))
        self._watch.fresh_poll()
        if fast_ready and status & _FAST_OVERRUN[self._fast]:
            # a sample of the accounted channel overwritten unread: the frame ledger's proof
            # of a lost frame the stamps can hide (a grid that drifted past an instant)
            self.health.overrun_ns = self.health.skipped_ns = now_ns
        return PollResult(samples, self._next_poll_ns(now_ns, bool(fast_ready),
                                                      bool(status & _OVERRUN)))

    def _deliver_burst(self, raw: bytes, whole: bool, now_ns: int) -> None:
        """Hand the slave's copy in burst ``raw`` to the feed, saying whether the
        accelerometer measured since the burst before (its data-ready set): the chip copies
        the slave at each accelerometer measurement (ACC_CFG2 [3:1] = 0), so a clear bit
        is no copy since, a hung engine's burst included (``AutoReadFeed.deliver``'s
        ``master_fresh``). Unsaid for a burst after one that failed or came blank (it may
        have cleared the bit unseen: ``whole`` False) and for a blank one (no status)."""
        assert self._feed is not None
        fresh = bool(raw[0] & _ACC_DR) if whole and self._read_whole else None
        self._feed.deliver(now_ns, raw[_MAG_OFFSET:_MAG_OFFSET + self._feed.length],
                           master_fresh=fresh)

    def _note_idle(self, since: int | None, fast_flag: SampleFlag | None, bad: SampleFlag,
                   now_ns: int) -> None:
        """A read at ``now_ns`` whose accounted channel got ``fast_flag`` (None: no new
        sample, and not overdue): a valid frame starts a run of reads; a good read that
        found no new sample since the latest valid frame (``since``, every read since alike)
        proves the chip measured nothing since (``health.idle``: the frame ledger's proof of
        a hung chip, issue 25). An overdue one (STALE) found nothing new either."""
        if fast_flag is not None and not fast_flag:
            self._idle_since = now_ns
        elif not bad and since is not None and (fast_flag is None
                                                or fast_flag == SampleFlag.STALE):
            self._idle_since = since
            self.health.idle = (since, now_ns)

    def _flag_of(self, channel: Quantity, ready: int, bad: SampleFlag,
                 now_ns: int) -> SampleFlag | None:
        """The flags of ``channel``'s sample in this burst (OK: new data), or None when it
        has none to report: not ready, and not yet overdue. A ready sample in a bad burst
        keeps the burst's flags; an overdue one is STALE as well."""
        if ready and not bad:
            self._ready.fresh(channel, now_ns)
            return SampleFlag.OK
        if ready:
            return bad
        if self._ready.overdue(channel, now_ns):
            return SampleFlag.STALE | bad
        return None

    def _after_stale(self, now_ns: int) -> int:
        """A poll that reported stale or bad data: the configuration is checked when due,
        and the chip restarted after too many such polls; else the next point of the grid."""
        if self._watch.check_due(now_ns, overdue=True) and self._off_plan(overdue=True):
            return self.restart(reset_detected=True)
        if self._watch.stale_poll():
            return self.restart(reset_detected=False)
        return self._grid.next_after(now_ns)

    def _next_poll_ns(self, now_ns: int, fast_ready: bool, overrun: bool) -> int:
        """Keeps the polls phase-locked just after the fastest channel's measurements: an
        overrun moves the grid half a period earlier, data found after a search re-anchors
        it, no data retries a guard later. An overrun found by a poll that came more than a
        guard after the time it asked for (a host stall, a poll put off) is that poll's
        lateness, not a grid behind the chip: re-anchored half a period earlier, the grid
        sat mid-period, and a put-off poll kept it there, so the frame ledger's count
        across it rounded to a frame too many (the fault matrix's ``jitter``)."""
        asked_ns, self._asked_ns = self._asked_ns, None
        late = asked_ns is not None and now_ns - asked_ns > self._grid.guard_ns
        if fast_ready and overrun and not late:
            self._grid.anchor(now_ns - self._grid.period_ns // 2)
        elif fast_ready and self._searching:
            # The data appeared after the poll a guard before the retry asked for: a retry
            # that came late (the host's one thread held by another device's poll) is
            # located where it was asked for, not where it came, whose lateness the
            # tracking grid took for chip periods longer than they are (1.6 ms over 20
            # periods: a grid that crept a period late and skipped an instant unseen)
            self._grid.locate(now_ns if asked_ns is None else min(now_ns, asked_ns))
        self._searching = not fast_ready
        if not fast_ready:
            self._asked_ns = now_ns + self._grid.guard_ns
            return self._asked_ns
        self._asked_ns = self._grid.next_after(now_ns)
        return self._asked_ns

    # --- read: fifo -------------------------------------------------------------------------

    @property
    def builds_blocks(self) -> bool:
        """Only read: fifo decodes its polls into blocks (a register poll is one frame)."""
        return self._fifo is not None

    def poll_blocks(self, now_ns: int) -> BlockPoll:
        """``poll`` as blocks. read: fifo decodes a read's frames at once into the gyro and
        accelerometer blocks' arrays (the same products as the per-frame conversion, so the
        same floats and flags, tests/chips/test_max2110x_fifo_blocks.py); a read with a
        blank or frozen frame, and read: registers, go through the frames' samples."""
        if self._fifo is None or self.scales is None:
            return super().poll_blocks(now_ns)
        if self._watch.check_due(now_ns) and self._off_plan(overdue=False):
            return BlockPoll([], self.restart(reset_detected=True))
        if self._side_only(now_ns):
            side = self._side_read(now_ns)
            return BlockPoll(blocks_of(side.samples) if side.samples else [],
                             side.next_poll_ns)
        got, samples, now_ns, next_ns = self._read_fifo(now_ns)
        blocks = self._frame_blocks(got)
        if blocks is None:
            samples += self._frame_samples(got)
            blocks = []
        result = self._fifo_result(samples, got, now_ns, next_ns)
        return BlockPoll((blocks_of(result.samples) if result.samples else []) + blocks,
                         result.next_poll_ns)

    def _poll_fifo(self, now_ns: int) -> PollResult:
        """read: fifo: the slave's bytes and the temperature (when due) from the data
        registers, then every whole frame the FIFO holds, stamped on the chip's clock (or
        with its edges); no frame for longer than the stale policy allows reports STALE.
        Between two FIFO reads, a poll reads the slave's bytes only (``_next_read_ns``)."""
        if self._side_only(now_ns):
            return self._side_read(now_ns)
        got, samples, now_ns, next_ns = self._read_fifo(now_ns)
        samples += self._frame_samples(got)
        return self._fifo_result(samples, got, now_ns, next_ns)

    def _read_fifo(self, now_ns: int) -> tuple[FifoRead, list[Sample], int, int]:
        """The reads of a FIFO poll: the data registers' samples (slave bytes, temperature),
        the FIFO's frames, the time after them and the next read's."""
        assert self._fifo is not None
        self._count_overflow()
        # with a feed, the side reads read the slave's copy and the temperature, unless a
        # line triggers the reads (the pipeline then keeps no deadline of the driver's)
        samples = self._aux_and_temperature(now_ns) \
            if not self._side_reads() or self._on_edges else []
        got = self._fifo.read()
        if got.reset:
            self._overflow_pending = True
            if not got.frames:
                self._count_overflow()
        now_ns = max(now_ns, self.clock.now_ns())
        self._fifo_due_ns = self._fifo.next_read_ns(now_ns, self._fifo_interval_ns())
        if self._feed is not None and not self._side_reads():
            # before SIDE_READ_PLAN the slave's next copy comes with that read
            self._feed.next_ns = self._fifo_due_ns
        return got, samples, now_ns, self._next_read_ns(now_ns)

    def _fifo_result(self, samples: list[Sample], got: FifoRead, now_ns: int,
                     next_ns: int) -> PollResult:
        """A FIFO poll's outcome: frames keep the channels fresh; none for longer than the
        stale policy allows reports STALE samples."""
        if got.frames or got.held:
            self._ready.fresh(Quantity.GYRO, now_ns)
            self._ready.fresh(Quantity.ACCEL, now_ns)
            self._watch.fresh_poll()
            return PollResult(samples, next_ns)
        stale = [self._no_frame(channel, now_ns) for channel in (Quantity.GYRO, Quantity.ACCEL)]
        if not any(s is not None for s in stale):
            return PollResult(samples, next_ns)
        samples += [s for s in stale if s is not None]
        return PollResult(samples, self._after_stale(now_ns))

    def _count_overflow(self) -> None:
        """A FIFO reset counts in ``health.fifo_overflows``; one that handed out the frames
        the full FIFO kept counts with the next read, so the loss the pipeline's ledger
        finds after those frames (the frames not written, before the next read's) is
        charged to it (the ledger takes the count before it takes a read's frames)."""
        if self._overflow_pending:
            self._overflow_pending = False
            self.health.fifo_overflows += 1

    def _no_frame(self, channel: Quantity, now_ns: int) -> Sample | None:
        """A STALE NaN sample of ``channel`` when it is overdue, else None."""
        flag = self._flag_of(channel, 0, SampleFlag.OK, now_ns)
        if flag is None:
            return None
        make = self._gyro_sample if channel is Quantity.GYRO else self._accel_sample
        return make((0, 0, 0), now_ns, flag)

    def _aux_and_temperature(self, now_ns: int) -> list[Sample]:
        """MAG X/Y/Z (the slave's copy) and TEMP in one burst, when a feed takes the
        slave's bytes or a temperature sample is due (every TEMPERATURE_PERIOD_NS): neither
        is in the FIFO, so both are read as polling reads them, stamped with the read. The
        slave's bytes alone (``feed.length``) when no temperature is due: one small
        transfer at each side read (``_next_read_ns``)."""
        temp_due = (self._last_temp_ns is None
                    or now_ns - self._last_temp_ns >= TEMPERATURE_PERIOD_NS)
        feed = self._feed
        if feed is None and not temp_due:
            return []
        if not temp_due and self._side_reads():
            assert feed is not None
            feed.deliver(now_ns, self.regs.send(self._aux_frames[feed.length], feed.length))
            return []
        raw = self.regs.send(self._aux_temp_frame, self._aux_temp_bytes)
        if feed is not None:
            feed.deliver(now_ns, raw[:feed.length])
        if not temp_due:  # before SIDE_READ_PLAN: MAG through TEMP beside every FIFO read
            return []
        self._last_temp_ns = now_ns
        return [self._temperature_sample(be_int16(raw, self._aux_temp_bytes - 2), now_ns,
                                         blank_flag(raw))]

    def _frame_samples(self, got: FifoRead) -> list[Sample]:
        """Gyro and accelerometer samples of FIFO frames (gyro X, Y, Z, accel X, Y, Z)."""
        samples: list[Sample] = []
        for frame, t_ns in zip(got.frames, got.stamps_ns, strict=True):
            gx, gy, gz, ax, ay, az = _SIX_WORDS.unpack(frame)
            bad = blank_flag(frame) or self._frozen.observe("frame", frame)
            samples.append(self._gyro_sample((gx, gy, gz), t_ns, bad))
            samples.append(self._accel_sample((ax, ay, az), t_ns, bad))
        return samples

    def _frame_blocks(self, got: FifoRead) -> list[Block] | None:
        """The frames of ``got`` as the gyro and accelerometer blocks ``_frame_samples``
        would give frame by frame, decoded on arrays; None when a frame is blank or would be
        FROZEN (then frame by frame)."""
        frames = got.frames
        if not frames:
            return []
        data = b"".join(frames)
        # a blank frame is 12 equal bytes 0x00 or 0xFF: none in the burst, none to look for
        # frame by frame (two searches in C)
        if (_BLANK_FF in data or _BLANK_00 in data) and any(blank_flag(f) for f in frames):
            return None
        if not self._frozen.observe_all("frame", frames):
            return None
        assert self.scales is not None
        n = len(frames)
        counts = np.frombuffer(data, dtype=">i2").reshape(n, 6)
        # int16 counts times a float: each count exact in float64, then the product, as
        # decode's per-frame conversion computes it
        gyro = np.asarray(counts[:, 0:3] * (math.radians(1.0) / self.scales.gyro_lsb_per_dps),
                          np.float64)
        accel = np.asarray(counts[:, 3:6] * (STANDARD_GRAVITY_M_S2 / self.scales.accel_lsb_per_g),
                           np.float64)
        stamps = got.stamps_ns
        flags_g, flags_a = self._frame_flags(counts, stamps)
        t0 = stamps[0]  # stamps never go back (FifoFrames)
        offsets = np.array([t - t0 for t in stamps], np.int64)
        return [Block(GyroSample, self.device, frame=Frame.SENSOR, spec=None, t0_ns=t0,
                      offsets_ns=offsets, values=gyro, flags=flags_g),
                Block(AccelSample, self.device, frame=Frame.SENSOR, spec=None, t0_ns=t0,
                      offsets_ns=offsets, values=accel, flags=flags_a)]

    def _frame_flags(self, counts: npt.NDArray[np.int16], stamps_ns: list[int]
                     ) -> tuple[IntArray, IntArray]:
        """The gyro and accelerometer flags of a read's frames (SATURATED, and the chip's
        filter memory after a clip, frame by frame as ``_frame_samples`` gives them)."""
        memory = self._memory
        # no word at the rail, no rail input hidden by the filter and no window open:
        # every frame OK, without a look frame by frame
        gyro_quiet = memory.quiet_block(Quantity.GYRO, counts[:, 0:3], stamps_ns)
        if memory.quiet_block(Quantity.ACCEL, counts[:, 3:6], stamps_ns) and gyro_quiet:
            return np.zeros(len(stamps_ns), np.int64), np.zeros(len(stamps_ns), np.int64)
        clipped = np.abs(counts.astype(np.int32)) >= FULL_SCALE_COUNTS
        sat_g: list[bool] = np.asarray(clipped[:, 0:3].any(axis=1), dtype=bool).tolist()
        sat_a: list[bool] = np.asarray(clipped[:, 3:6].any(axis=1), dtype=bool).tolist()
        rows: list[list[int]] = counts.tolist()
        flags_g: list[int] = []
        flags_a: list[int] = []
        for t_ns, row, g, a in zip(stamps_ns, rows, sat_g, sat_a, strict=True):
            fg = SampleFlag.SATURATED if g else SampleFlag.OK
            fa = SampleFlag.SATURATED if a else SampleFlag.OK
            # a channel whose block was quiet was observed whole already
            flags_g.append(fg if gyro_quiet else
                           fg | memory.observe(Quantity.GYRO, t_ns, row[0:3], fg))
            flags_a.append(fa | memory.observe(Quantity.ACCEL, t_ns, row[3:6], fa))
        return np.array(flags_g, np.int64), np.array(flags_a, np.int64)

    def data_ready(self, edges_ns: Sequence[int]) -> None:
        """read: fifo: each frame is stamped with its own data-ready edge."""
        if self._fifo is not None:
            self._edges_seen = self._edges_seen or bool(edges_ns)
            self._fifo.data_ready(list(edges_ns))

    def drain(self, now_ns: int) -> list[Sample]:
        """read: fifo: the frames held for their time stamps."""
        if self._fifo is None:
            return []
        self._count_overflow()
        return self._frame_samples(self._fifo.drain())

    @property
    def polls_after_instants(self) -> bool:
        """Polled, its grid searches the chip's instants (EARLY_FRACTION)."""
        return self._fifo is None

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """The faster of gyro and accelerometer, one frame per its output period."""
        if self.scales is None:
            return None
        return self._fast, self._grid.period_ns

    def resume(self, now_ns: int) -> int | None:
        """One transfer of a poll failed: when the configuration still reads back as
        written, the chip kept its state (a glitch on the wire), so poll again at once
        instead of a soft reset and reconfiguration (which loses about 10 ms of data);
        anything else gets the full recovery. The retry reads the sample the failed burst
        missed while it is still the newest, stamped about when it was due. Waiting for the
        next point of the grid instead read it there a period late when the grid (which
        creeps early of the chip) came just before the next measurement, and kept the
        grid a period behind the chip until it crept past a measurement: a loss counted
        where the chip lost nothing, and one missed where it did (the frame ledger's count
        against the chip's, tests/integration/test_poll_stamped_accounting.py).

        The retry was once taken back: with it the seed paraglider board's HMC5883L handed
        out torn fields (X and Z of one measurement, Y of the next) at 1 % bus errors. The
        retry only moved the timing; the cause was the HMC5883L driver's one-shot read of
        its six data bytes while the auto-read ran, which left the chip's data lock half
        released (imuhal_chips.hmc5883l.driver, configure())."""
        if self.scales is None or self._off_plan(overdue=True):
            return None
        return max(now_ns, self.clock.now_ns())

    def filter_memory_outputs(self) -> dict[Quantity, int]:
        """Outputs after one input at the rail that each channel's low-pass can still carry
        it by the part's specified offset or more (``LowPassWatch``): the gyro's bandwidth
        (GYRO_CFG1) and the accelerometer's cutoff, its ODR over the output-filter divisor
        (ACC_CFG1): 16 and 26 at the seed RC vario's 10 Hz and ODR / 48 (3 deg/s of 1000,
        60 mg of 8 g)."""
        return {q: self._memory.settling_outputs(q) for q in (Quantity.GYRO, Quantity.ACCEL)}

    def _frozen_flag(self, raw: bytes) -> SampleFlag:
        """FROZEN when the gyro, accel and temperature words repeat FROZEN_AFTER_FRAMES
        times in a row while the chip reports new data."""
        return self._frozen.observe("frame", raw[1:13] + raw[-2:])

    def _temperature_sample(self, counts: int, now_ns: int, bad: SampleFlag) -> Sample:
        if bad:
            return TemperatureSample(t_ns=now_ns, device=self.device, flags=bad,
                                     temperature_degc=math.nan)
        temp = decode.temp_counts_to_degc(counts)
        flags = range_flag([temp], *TEMPERATURE_RANGE_DEGC)
        return TemperatureSample(t_ns=now_ns, device=self.device, temperature_degc=temp,
                                 flags=flags)

    def _gyro_sample(self, counts: Counts3, now_ns: int, flags: SampleFlag) -> Sample:
        assert self.scales is not None
        if flags:
            value = NAN3  # stale, blank or frozen: not a measurement
        else:
            value = decode.gyro_counts_to_rad_s(counts, self.scales.gyro_lsb_per_dps)
            if decode.saturated(counts):
                flags |= SampleFlag.SATURATED
            settling = self._memory.observe(Quantity.GYRO, now_ns, counts, flags)
            if settling:  # (an enum operation costs a Python call)
                flags |= settling
        return GyroSample.build(now_ns, self.device, flags, Frame.SENSOR, value)

    def _accel_sample(self, counts: Counts3, now_ns: int, flags: SampleFlag) -> Sample:
        assert self.scales is not None
        if flags:
            value = NAN3
        else:
            value = decode.accel_counts_to_m_s2(counts, self.scales.accel_lsb_per_g)
            if decode.saturated(counts):
                flags |= SampleFlag.SATURATED
            settling = self._memory.observe(Quantity.ACCEL, now_ns, counts, flags)
            if settling:
                flags |= settling
        return AccelSample.build(now_ns, self.device, flags, Frame.SENSOR, value)

    def _off_plan(self, *, overdue: bool) -> bool:
        """Whether the chip no longer holds its plan (a silent reset, a brown-out, or
        nothing answering): the next check step, or every register when data are overdue."""
        if self.plan is None:
            return True
        if overdue:  # the whole plan, now: a read without side effects, repeated in place
            return retried(partial(self.plan.lost, self.regs)) is not None
        return self.plan.check_next(self.regs) is not None


class Max21105Driver(Max2110xDriver):
    """Maxim MAX21105 6-axis IMU on I2C (0x58/0x59) or SPI (mode 3)."""

    name = "max21105"
    description = "Maxim MAX21105 3-axis gyroscope + 3-axis accelerometer (I2C/SPI)"
    Settings = Max21105Settings
    part = MAX21105


class Max21100Driver(Max2110xDriver):
    """Maxim MAX21100 6-axis IMU with an aux I2C master (bus ``aux``) for a magnetometer."""

    name = "max21100"
    description = ("Maxim MAX21100 3-axis gyroscope + 3-axis accelerometer (I2C/SPI) with an "
                   "I2C master exposed as child bus 'aux'")
    Settings = Max21100Settings
    part = MAX21100
    child_bus_kinds: ClassVar[Mapping[str, BusKind]] = {"aux": BusKind.I2C}
    child_bus_features: ClassVar[Mapping[str, frozenset[str]]] = {
        "aux": frozenset({AUTO_READ})}

    def __init__(
        self, link: Link, settings: SettingsInput, *, device: str,
        clock: Clock,
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self._aux: Bus | None = None

    def child_buses(self) -> dict[str, Bus]:
        if self._aux is None:
            self._aux = Max21100AuxBus(
                f"{self.link.bus.name}/{self.device}/aux", self.regs, self.clock,
                dr_cfg=lambda: self.plan.get(Reg.DR_CFG, DR_CFG_TEMP_EN) if self.plan
                else DR_CFG_TEMP_EN,
                enable_auto_read=self.enable_auto_read)
        return {"aux": self._aux}

    def register_plan(self) -> dict[int, int]:
        """The base plan, with the slave auto-read's registers (when one was asked for)
        before DR_CFG and POWER_CFG, so a reconfiguration after a reset restores it."""
        plan = super().register_plan()
        if self._feed is None:
            return plan
        out: dict[int, int] = {}
        for reg, value in plan.items():
            if reg == Reg.DR_CFG:
                out.update(self._auto_read_plan(self._feed))
            out[reg] = value
        return out

    @staticmethod
    def _auto_read_plan(feed: AutoReadFeed) -> dict[int, int]:
        """har-in-air's sequence (facts section 6, steps 1 and 4), with the slave's bytes
        kept as read: MAG_MAP_REG 0x00 (not har-in-air's 0x08 remap of the HMC5883L's X, Z,
        Y order) and MSB first (MAG_SLV_CFG bit 6 clear), so MAG X/Y/Z hold the slave's
        bytes in its register order and byte order and the slave's driver converts them as
        if it had read them itself. Enable last."""
        return {
            Reg.ACC_CFG2: 0x00,  # [3:1] = 0: the slave at the accelerometer rate
            Reg.MAG_SLV_ADD: feed.target,
            Reg.MAG_SLV_REG: feed.register,
            Reg.MAG_MAP_REG: MAG_MAP_AS_READ,
            Reg.MAG_SLV_CFG: MAG_SLV_CFG_ENABLE | feed.length,
        }

    def enable_auto_read(self, target: int, register: int, length: int) -> AutoReadFeed:
        """Program the slave auto-read (one slave, at most six bytes) and return its feed;
        the same request again returns the same feed. Registers written now and verified,
        and part of every later configuration and read-back."""
        where = f"{self.describe()}: slave auto-read of 0x{target:02X}"
        if not 1 <= length <= MAG_DATA_BYTES:
            raise ConfigurationError(f"{where}: {length} bytes asked; the master keeps 1 to "
                                     f"{MAG_DATA_BYTES} (MAG X/Y/Z)")
        feed = same_feed(self._feed, target, register, length, where=where)
        if feed is not None:
            return feed
        if self.scales is None:
            raise ConfigurationError(f"{where}: asked before the MAX21100 was configured")
        # The slave's bytes are copied at each accelerometer measurement and reach the
        # host with the next burst, a poll-grid guard after it; with read: fifo with the
        # next side read, a guard after the next instant (``_next_read_ns``), or, before
        # SIDE_READ_PLAN, with the next FIFO read (up to its interval later)
        period_ns = round(1e9 / self.settings.accel_odr_hz)
        beside_fifo = self._fifo is not None and self.poll_plan < SIDE_READ_PLAN
        after_ns = self._grid.guard_ns + (self._fifo_interval_ns() if beside_fifo else 0)
        feed = AutoReadFeed(target, register, length, latency_ns=period_ns + after_ns)
        if not beside_fifo:
            feed.period_ns = period_ns  # a read per sample, burst or side read
        auto_read = self._checked(self._auto_read_plan(feed))
        auto_read.apply(self.regs)
        auto_read.verify(self.regs)
        self._feed = feed
        self.plan = self._checked(self.register_plan())
        self._watch.spread_over(len(self.plan.steps))
        return feed
