"""HMC5883L driver (Honeywell 3-axis magnetometer, I2C 0x1E).

Register facts: HMC5883L datasheet Form 900405 Rev E and Linux hmc5843_core.c, summarised in
imuhal's chip-facts notes (chips.md, section 3). Tables in registers.py, decoding in decode.py.

The driver runs the chip in continuous mode and polls at the output rate: per poll it reads
the status register and, when RDY is set, the Mode register and the six data bytes X, Z, Y
in one transaction (the chip locks its data outputs from the Mode or first data byte read
until all six are read, so the triple is coherent even when a bus splits the read into byte
transactions, as the MAX21100's aux master does). Samples: MagSample in uT, sensor frame.

Why Mode rides with every data read: a chip reset (brown-out, ESD) returns Config A/B and
Mode to their power-on values (0x10, 0x20, single measurement); the chip then measures once,
at the power-on gain, goes idle and keeps RDY set and those data bytes (RDY is cleared only
when the chip starts writing new data). Read alone, the data bytes look like a new field at
every poll until FROZEN or the periodic read-back catches them (up to 28 fields, 0.4 s, at
75 Hz). With Mode in the same read (one byte more; Config A/B, which a reset changes only
with Mode, stay in the periodic read-back), the first poll after a reset sees that the chip
left continuous mode: that poll's sample is flagged STALE (its bytes are no measurement of
the configured chip), counted, and the chip is reconfigured.

``mode: single`` (read directly only; the seed rc profile): the chip measures once per Mode
write (single-measurement mode, 6 ms, up to 160 Hz by the datasheet) and goes idle. The
driver writes Mode at each point of its own cadence (``odr_hz`` on the host's clock), reads
Config A through the data in one transaction 6.12 ms later (a chip clock 2 % slow is done
by then; Mode still single: not done, read again 0.5 ms later) and stamps the field at the
measurement's end, 6 ms after the write. Production is host-paced, as the MS5611's: the
chip makes exactly the fields the driver starts, so on any chip clock none is handed out
twice or lost unseen (continuous mode read directly cannot place its polls: RDY stays set,
and a clock 2 % off repeats or skips one field in 50 unseen). A start more than half a
period late slides the cadence, and a measurement not done by the next start was never
made (a hung chip, which the next Mode write restarts): both are slots counted as not
converted (``DeviceHealth.not_converted_ns``). Config A/B in every read show a silent reset
(the power-on values) as Mode does in continuous mode, so no periodic read-back is made.
ArduPilot's AP_Compass_HMC5843 reads its HMC5883L the same way (read, then a Mode write of
single, every 13.3 ms). Per field: the Mode write (2 bytes) and the 9-byte read, where
continuous mode reads status and Mode with the data (two transactions as well).

Two chip habits shape configure(): the first measurement after a gain change still uses the
old gain (so the first sample after configure is dropped), and reading the mode register
locks the data outputs until the six data bytes are read (so the read-back is followed by one
throw-away data read).

``read: auto`` (behind a master that can auto-read, imuhal.bus.auto_read: the MAX21100's
``imu/aux``): the master reads the six data bytes at each of its own measurements and the
driver takes them from the master's burst, with no transaction of its own; configuration,
identity and the periodic read-back still use one-shot transactions. The status register is
not among the six bytes, so a copy whose bytes differ from the previous ones is a new
measurement (unless it equals the last sample handed out: one that comes back after a blank
or a master reset is not new); a copy that stays the same is no proof that nothing was
measured (a still field repeats its six bytes, about one field in 500 at +/-1.3 Ga): once a
copy made after the chip's next instant has come unchanged, one status read tells (RDY set:
the chip measured the same bytes, handed out when the next change shows it was no late copy
the master's failed reads held back, and no measurement follows that change within a
period; RDY clear before the next measurement could be writing:
the chip hung, its slot not measured; ``_repeat_by_status``). Bytes that stay the same for
longer than a healthy chip's noise allows (``unchanged_periods``) are a chip that stopped or
a master whose reads fail (it keeps the last data): flagged STALE at each poll after that,
FROZEN once they have not changed for FROZEN_AFTER_FRAMES periods, never valid. Such a run
reads the status register (which locks no output): RDY clear twice, 0.5 ms apart, is a chip
whose data-ready is stuck (its engine hung) and the frame ledger counts its slots as not
measured (issue 25; ``_hung_by_status``). A reset the master's copies show as
zeros (the data registers' power-on value) followed by the reset chip's one measurement in
single mode: the configuration is read back before that measurement is handed out
(``_reset_behind_blank``, also when the zeros ended the poll before); so is the first change
after a status read proved the chip idle (``_reset_behind_hang``: a chip unplugged and
plugged back in while the master delivered nothing, whose zeros never reached the driver).
Found off the plan behind copies handed out in the same poll, the chip is reconfigured at
the next poll, so those fields end the ledger's segment of the old cadence. A restart makes
the driver doubt the master's copies for DOUBT_NS (a read-back off the plan is mostly a
failing wire, whose failed master reads make false repeats). Latency: the master copies a
measurement at its next accelerometer measurement and the host reads it with the next
burst (``AutoReadFeed.latency_ns``: one accelerometer period plus the IMU's poll guard,
4.5 ms at 250 Hz); the driver polls that long plus its own guard (1/8 period) after each
measurement instant and stamps the sample with the poll's time, about 6 ms after the
measurement at the seed's rates (one-shot: 1.7 ms). A poll that finds the bytes unchanged
looks once more one latency later (a copy a failed read or burst delayed; what it finds
is stamped with the IMU burst that delivered it), then waits for the next measurement.
On a chip clock off its nominal period (issue 25: up to +-2 %) the grid follows the
chip's instants: a poll more than a latency and a guard after the delivery of the change
it finds moves it earlier, one whose look again found the change delivered after it a
guard later (``_steer``); on the nominal clock neither happens. A slow chip's grid stays up
to a latency early of its instants (its polls come before the copies, whose looks again
find them): while it does (``_ahead``), a copy that waited for a poll (after a stall, or
left by a poll that skipped its look again) is stamped by its delivery, not by the poll,
and the periodic read-back, whose read of Mode locks the outputs, waits for a poll that
takes a fresh change (``_read_back_now``).
Every copy that changed since the previous poll is taken (``AutoReadFeed.take``), not only
the latest: when the master's reads bring two measurements between two polls (FIFO reads
at the IMU's own instants, or the look a latency later), the older is handed out too,
stamped with its delivery, or, when the master delivered nothing for a while before it (its
recovery, the host's polls late: the copy may have waited a field period in the chip), on
the driver's grid where a poll on time would have stamped its measurement
(``_after_pause``; ``imuhal.bus.auto_read.stamp_on_cadence`` for a master that reports its
failed reads). The newest copy a late poll takes more than a latency and a guard after its
delivery is stamped at the grid point a poll on time would have taken it at
(``_on_time_point``). A master that delivers bursts while its own chip hung
(``AutoReadFeed.copied_ns``: the MAX21100's accelerometer data-ready clear) made no copy
in them: the status read proves no repeat from them, and reads again once the chip's
second instant after its latest field is past (``_look_past_second_instant``).
A reconfiguration under ``read: auto`` reads no data byte itself: the master's next copy
(all six bytes in one transaction) releases the lock reading Mode set; six one-shot reads
straddling a copy would leave it half released and tear every later copy.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Literal

from pydantic import model_validator

from imuhal.bus.auto_read import (
    AutoReadBus,
    AutoReadFeed,
    Copy,
    require_auto_read,
    stamp_on_cadence,
)
from imuhal.bus.base import BusKind, Link
from imuhal.bus.register_plan import RegisterPlan
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.poll_plan import CHIP_CLOCK_PLAN, READ_BACK_PLAN
from imuhal.core.samples import Frame, MagSample, Quantity, Sample, SampleFlag
from imuhal.core.streams import StreamSpec
from imuhal.drivers.base import (
    DeviceIdentity,
    Driver,
    DriverSettings,
    PollResult,
    SettingsInput,
)
from imuhal.drivers.polling import (
    STALE_AFTER_PERIODS,
    DataReady,
    PollGrid,
    ResetWatch,
    reset_check_field,
)
from imuhal.drivers.settings import SlaveRead, table_setting
from imuhal.drivers.validity import NAN3, FilterMemory, FrozenWatch, blank_flag
from imuhal_chips.hmc5883l import decode
from imuhal_chips.hmc5883l.registers import (
    AVERAGING,
    CRA_RATE_SHIFT,
    DATA_LAST,
    DATA_MIN,
    IDENTITY,
    MODE_CONTINUOUS,
    MODE_IDLE,
    MODE_MD_MASK,
    MODE_SINGLE,
    ODR_BY_CODE,
    ODR_HZ,
    RANGE_GAUSS,
    STATUS_LOCK,
    STATUS_RDY,
    Reg,
    config_a,
    config_b,
    gain_from_config_b,
)

AFTER_DELIVERY_PLAN = 2
"""The poll plan (imuhal.core.poll_plan) from which, under ``read: auto``, the driver looks
no sooner than its master's next delivery (``Hmc5883lDriver._next_look``)."""
NOT_READY_RETRY_NS = 500_000
"""RDY is low for about 250 us while the chip writes new data: retry this much later."""
FROZEN_AFTER_FRAMES = 30
"""Identical data frames in a row that mean the chip stopped measuring. The quietest setting
(+/-8.1 Ga, 230 LSB/Ga, 2 mG noise: about 0.5 LSB per axis) repeats a three-axis frame with
probability about 0.2; 30 in a row (0.4 s at 75 Hz), about 1e-21 per sample."""
NOISE_FLOOR_GAUSS = 0.002
"""Datasheet noise floor (2 mG): the standard deviation of one axis's output."""
MODE_AND_DATA = DATA_LAST - Reg.MODE + 1
"""One read from the Mode register through the last data byte: every field comes with the
mode the chip measured it in (see the module docstring)."""
MAGNITUDE_STEP = 0.1
"""read: auto: a copy whose field magnitude differs from the field before it by more than
this fraction has the configuration read back before it is handed out. A reset chip's one
measurement at the power-on gain (1090 LSB/Ga) reads the field scaled by 1090 over the
configured gain: at least 20 % off for every other range (1370: 0.80; 820: 1.33). A
rotation keeps the magnitude, and a hard iron |h| changes it by at most |h| times the angle
turned in one field period, so an honest 10 % step needs a violent turn near strong iron,
and costs only the read-back."""
STATUS_BITS = STATUS_LOCK | STATUS_RDY
"""The status register's defined bits; the others read 0 (a line nothing drives reads
0xFF)."""
DOUBT_NS = 1_000_000_000
"""read: auto: how long a sign of failing master reads stops repeats being proved (75
fields at the seed's rate; a wire that failed once likely fails again)."""
STEER_FIELDS = 6
"""read: auto: the grid moves later when the polls on time of this many fields in a row
came less than a guard after the master's deliveries of their fields (``_steer``)."""
CLOCK_TOLERANCE = 0.02
"""How far the chip's output period may be off its nominal one (a fraction): the datasheet
states no tolerance for the output rates; issue 25's +-2 %, as the emulator allows."""
SINGLE_MEASUREMENT_NS = 6_000_000
"""mode: single: a measurement is ready this long after the Mode write that starts it (the
datasheet's wait; its end is the sample's stamp)."""
SINGLE_WAIT_NS = round(SINGLE_MEASUREMENT_NS / (1 - CLOCK_TOLERANCE))
"""mode: single: the read comes this long after the Mode write, when a chip clock 2 % slow
has finished too (6.12 ms)."""
CONFIG_TO_DATA = DATA_LAST - Reg.CONFIG_A + 1
"""mode: single: one read from Config A through the last data byte: the configuration (a
silent reset's power-on values), the mode (idle once the measurement is done) and the
field."""
REPEAT_ODDS = 1e-12
"""How rarely a healthy chip's six data bytes may stay the same for ``unchanged_periods``
output periods (about once in 400 years of 75 Hz output)."""


def unchanged_periods(gain_lsb_per_gauss: float) -> int:
    """Output periods in a row for which a healthy chip may repeat its six data bytes:
    with sigma = noise floor x gain counts per axis, one axis repeats with probability about
    1 / (2 sqrt(pi) sigma) (the FrozenWatch rule), a frame with p = that cubed, k frames in a
    row with p**k; the smallest k with p**k below REPEAT_ODDS. 5 at the default +/-1.3 Ga,
    19 at +/-8.1 Ga."""
    sigma = NOISE_FLOOR_GAUSS * gain_lsb_per_gauss
    p = min(1.0, 1.0 / (2.0 * math.sqrt(math.pi) * sigma)) ** 3
    if p >= 1.0:
        return FROZEN_AFTER_FRAMES
    return max(1, math.ceil(math.log(REPEAT_ODDS) / math.log(p)))


class Hmc5883lSettings(DriverSettings):
    """HMC5883L settings; defaults are the seed's: +/-1.3 Ga, 75 Hz, 8-sample average."""

    range_gauss: table_setting(RANGE_GAUSS, "Ga") = 1.3  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Field range +/- gauss: 0.88, 1.3, 1.9, 2.5, 4.0, 4.7, 5.6, 8.1 (sets the gain)."""
    odr_hz: table_setting(ODR_HZ, "Hz") = 75  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Continuous-mode output rate, Hz: 0.75, 1.5, 3, 7.5, 15, 30, 75."""
    averaging: table_setting(AVERAGING, "samples", kind=int) = 8  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Samples averaged per output: 1, 2, 4, 8."""
    reset_check_s: float = reset_check_field()
    """How often (s) the configuration is read back to catch a silent chip reset."""
    read: SlaveRead = "one-shot"
    """How the data are read: ``one-shot``, by the driver at each poll (status, then the six
    data bytes), on any I2C bus; ``auto``, by the I2C master the chip sits behind, at its
    own rate, handed over in the master's burst (a bus offering slave auto-read: the
    MAX21100's ``imu/aux``)."""
    mode: Literal["continuous", "single"] = "continuous"
    """How the chip measures: ``continuous``, at ``odr_hz`` on its own oscillator (whose
    error the datasheet does not bound: a clock 2 % off repeats or skips a field in 50
    unseen, RDY staying set); ``single`` (``read: one-shot`` only), one measurement per
    field, started by the driver's Mode write at ``odr_hz`` on the host's clock, so every
    field handed out is one the host asked for and none is repeated or lost unseen on any
    chip clock (one more 2-byte write per field; see ``Hmc5883lDriver._poll_single``)."""

    @model_validator(mode="after")
    def _single_needs_the_driver(self) -> Hmc5883lSettings:
        if self.mode == "single" and self.read == "auto":
            raise ValueError("mode 'single' needs the driver to start each measurement, and "
                             "with read: auto the master reads the chip on its own: use "
                             "read: one-shot, or mode: continuous")
        return self


class Hmc5883lDriver(Driver):
    """Honeywell HMC5883L on I2C: directly, or behind another chip's I2C master."""

    name = "hmc5883l"
    description = "Honeywell HMC5883L 3-axis magnetometer (I2C 0x1E)"
    Settings = Hmc5883lSettings
    channels = (Quantity.MAG,)
    bus_kinds = frozenset({BusKind.I2C})
    settings: Hmc5883lSettings

    def __init__(
        self, link: Link, settings: SettingsInput, *, device: str,
        clock: Clock,
    ) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.gain_lsb_per_gauss: float | None = None
        self.regs = RegisterView(link)
        self.plan: RegisterPlan | None = None
        """What Config A/B and Mode must hold (set by configure())."""
        self._streams: tuple[StreamSpec, ...] = ()
        self._mode_written_ns = 0
        self._configuring = False
        """A configure() began and has not completed (a bus error broke it: ``resume``)."""
        self._written: RegisterPlan | None = None
        """The plan that configure() wrote in full, until it completes."""
        self._skip_next = False
        self._grid = PollGrid(round(1e9 / self.settings.odr_hz))
        self._ready = DataReady({Quantity.MAG: self._grid.period_ns})
        self._watch = ResetWatch(self.settings.reset_check_s)
        self._frozen = FrozenWatch(FROZEN_AFTER_FRAMES)
        self._memory = FilterMemory({Quantity.MAG: self.filter_memory_outputs()},
                                    {Quantity.MAG: self._grid.period_ns})
        if self.settings.read == "auto":
            require_auto_read(link.bus, who=self.describe(), bus_name=link.bus.name,
                              example="slave auto-read, e.g. the MAX21100's imu/aux",
                              fix="use read: one-shot")
        # read: auto (see the module docstring)
        self._feed: AutoReadFeed | None = None
        self._emitted: bytes | None = None
        """The bytes of the last sample handed out."""
        self._stamped_ns = 0
        """The time stamp of the last sample handed out (read: auto)."""
        self._cadence_ns: int | None = None
        """The stamp of the latest field since configure() (the chip's cadence runs from
        it; a reconfiguration restarts the chip's measurements with a new phase)."""
        self._locked_ns = 0
        """read: auto: when the driver last read Mode, which locks the data outputs until
        the master's next copy reads them: that copy holds a measurement from before."""
        self._locked_before_ns = 0
        """read: auto: the Mode read before ``_locked_ns`` (copies delivered before that
        one were read under it)."""
        self._blank_since_ns: int | None = None
        """read: auto: the master's copies have been blank since (its registers reset)."""
        self._unread_lock = False
        """read: auto: no copy but blank ones has come since configure(): the master has
        read no data since configure() read Mode (``_unlocking``)."""
        self._restart_due = False
        """read: auto: the chip read back off its plan; reconfigure it at the next poll."""
        self._ended_zeros = False
        """read: auto: the previous poll's copies handed out a field and ended with all-zero
        bytes (``_reset_behind_blank``)."""
        self._settle_ns = 0
        """Bytes that changed before this are from before configure() or its first
        measurement (still at the old gain)."""
        self._fresh_ns = 0
        self._unchanged_limit_ns = 0
        self._retrying = False
        """The previous poll found the bytes unchanged and this one looks again."""
        self._asked_ns: int | None = None
        """read: auto: when the previous poll asked to be polled next."""
        self._looked_ns: int | None = None
        """read: auto: the poll, on time, that found the bytes unchanged and looks again
        (None: it came late)."""
        self._steered = False
        """read: auto: ``_steer`` moved the grid since configure() (the chip's clock is off
        its nominal period)."""
        self._afters: deque[int] = deque(maxlen=STEER_FIELDS)
        """read: auto: how long after the master's delivery of its field each of the latest
        polls on time came (``_steer``; negative: the field came after the poll)."""
        self._idle_from: int | None = None
        """read: auto: the stamp of the latest sample handed out while it was valid and its
        copy is the master's latest change (None otherwise): the field a hang proof counts
        from (``_hung_by_status``)."""
        self._hang_read: int | None = None
        """read: auto: 0 while no status read was made in this run of unchanged copies, else
        when one found RDY clear; None once one found RDY set or none is to be made."""
        self._hung_after_ns = 0
        """read: auto: unchanged copies this long are more than a measuring chip repeats
        (``unchanged_periods``)."""
        self._repeat_after_ns = 0
        """read: auto: a delivery this long after the latest change carries a copy made
        after the chip's next measurement (``_repeat_by_status``)."""
        self._change_ns: int | None = None
        """read: auto: the delivery of the latest change taken (``_doubt_copies``)."""
        self._doubt_until_ns = 0
        """read: auto: no repeat is proved before this (``_doubt_copies``)."""
        self._hung_ns: int | None = None
        """read: auto: when a status read proved the chip hung in this run of unchanged
        copies (its next change may prove the hang's slots, ``health.adjacent``)."""
        self._repeat: tuple[int, int] | None = None
        """read: auto: a measurement of the same bytes as the latest field that a status
        read proved: its stamp and the earliest delivery of the measurement after it
        (``_repeated``)."""
        self._not_ready = False
        """read: one-shot: the previous poll found RDY clear (the chip let an instant pass
        unmeasured: reading never clears RDY)."""
        self._single_ns: int | None = None
        """mode: single: when the Mode write started the measurement not read yet."""
        self._due_ns = 0
        """mode: single: when the next measurement is due to start (the driver's cadence)."""

    # --- bus helpers (plain I2C register protocol: write pointer, then read) --------------

    def _read(self, register: int, length: int) -> bytes:
        return self.link.transfer(bytes([register]), length)

    # --- identity -------------------------------------------------------------------------

    def probe(self) -> DeviceIdentity:
        expected = "ID registers 0x0A..0x0C = 'H43'"
        try:
            found = self._read(Reg.ID_A, 3)
        except NackError as exc:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found="no answer (NACK)",
                hint="check power and SDA/SCL wiring and pull-ups; the HMC5883L is at 0x1E",
            ) from exc
        if found != IDENTITY and _partly_unanswered(found):
            # Behind an I2C master a byte the slave did not acknowledge reads 0xFF: the right
            # chip on a noisy bus, not another chip. A transient error: probed again.
            raise BusError(f"{self.describe()}: {_show(found)}: the bytes "
                           "read 0xFF went unanswered (a noisy bus to the chip)")
        if found != IDENTITY:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=expected, found=_show(found), hint=_identity_hint(found),
            )
        self.identity = DeviceIdentity(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            identity="ID=H43",
        )
        return self.identity

    # --- configuration --------------------------------------------------------------------

    def register_plan(self) -> RegisterPlan:
        """Config A, Config B, Mode (registers 0x00..0x02) for the settings, continuous mode
        last. Checked as one step (one 3-byte read): reading Mode locks the data outputs
        until the six data bytes are read, so every check pays that read anyway."""
        s = self.settings
        return RegisterPlan.of(self.describe(), {
            Reg.CONFIG_A: config_a(s.averaging, s.odr_hz),
            Reg.CONFIG_B: config_b(s.range_gauss),
            # mode: single: idle until the driver starts each measurement (_poll_single)
            Reg.MODE: MODE_CONTINUOUS if s.mode == "continuous" else MODE_IDLE,
        }, names={Reg.CONFIG_A: "Config A", Reg.CONFIG_B: "Config B", Reg.MODE: "Mode"},
            checks=[(Reg.CONFIG_A, Reg.CONFIG_B, Reg.MODE)], burst_write=True,
            hint="check the bus")

    def configure(self) -> None:
        """Write Config A/B and continuous mode, read them back, release the data lock."""
        plan = self.register_plan()
        self._configuring, self._written = True, None
        plan.apply(self.regs)
        self._mode_written_ns = self.clock.now_ns()  # continuous measurements start here
        self._written = plan
        self._configured_as(plan, plan.read(self.regs))

    def _configured_as(self, plan: RegisterPlan, got: dict[int, int]) -> None:
        """configure() after its writes: ``got`` is the plan's read-back."""
        self._locked_before_ns, self._locked_ns = self._locked_ns, self.clock.now_ns()
        if self.settings.read != "auto":
            self._read(Reg.X_MSB, 6)  # reading MODE locked the outputs; six data reads unlock
        # read: auto: the master's next copy reads the six bytes in one transaction and
        # releases the lock. Six one-shot reads here would straddle one of its copies (one
        # a millisecond, a copy every accelerometer period), which would release the lock
        # midway; the one-shot reads after it would lock it again with part of the six read,
        # and from then on every copy would end a byte or more into the next measurement
        # (a torn field: X and Z of one measurement, Y of the next) until Mode is written.
        plan.confirm(got)
        self.plan = plan
        config = bytes((got[Reg.CONFIG_A], got[Reg.CONFIG_B]))
        spec = self._spec(config)
        self.gain_lsb_per_gauss = gain_from_config_b(got[Reg.CONFIG_B])
        self._grid = PollGrid(spec.period_ns)
        self._ready = DataReady({Quantity.MAG: self._grid.period_ns})
        self._skip_next = True  # its first measurement still uses the previous gain
        self._idle_from, self._not_ready = None, False
        if self.settings.read == "auto":
            assert isinstance(self.link.bus, AutoReadBus)
            restarted = self._feed is not None
            feed = self._feed = self.link.bus.auto_read(self.link.target, Reg.X_MSB, 6)
            feed.take()  # copies from before this configuration
            self._unread_lock = True
            self._cadence_ns = None
            period = self._grid.period_ns
            self._settle_ns = self._mode_written_ns + period + feed.latency_ns
            self._unchanged_limit_ns = round(
                (unchanged_periods(self.gain_lsb_per_gauss) + STALE_AFTER_PERIODS) * period)
            self._hung_after_ns = unchanged_periods(self.gain_lsb_per_gauss) * period
            self._repeat_after_ns = round(period * (1 + CLOCK_TOLERANCE)) + feed.latency_ns
            self._idle_from, self._hang_read, self._repeat = None, None, None
            self._afters.clear()
            self._steered = False
            self._hung_ns = self._change_ns = None
            # a reconfiguration after the first (the chip read back off its plan, or kept
            # producing nothing): on a wire that fails, the one-shot read-back's unanswered
            # bytes (0xFF) look like a reset, and the master's reads of the chip fail as
            # well, unreported; a copy they held back looks like a repeat (``_doubt_copies``)
            self._doubt_until_ns = self.clock.now_ns() + DOUBT_NS if restarted else 0
        self._streams = (self._spec(config),)  # with the auto-read's latency, when there is one
        self._configuring, self._written = False, None

    def start(self, now_ns: int) -> int:
        # configure() may have waited on the clock since the caller read it (the base
        # recover() passes the time from before its configure()): never start in the past
        now_ns = max(now_ns, self.clock.now_ns())
        # Poll a guard (1/8 period) after each measurement instant, counted from the Mode
        # write. RDY stays set in continuous mode, so unlike the MAX2110x the phase cannot
        # be searched for; a chip clock off by a few percent occasionally repeats or skips
        # one output (each sample is still coherent thanks to the data lock): mode: single
        # does not (_poll_single). Under read: auto the master's deliveries move the grid
        # with the chip's clock (_steer).
        latency = self._feed.latency_ns if self._feed is not None else 0
        self._grid.anchor(self._mode_written_ns + latency + self._grid.guard_ns)
        self._ready.start(now_ns)
        self._fresh_ns = now_ns
        self._retrying = False
        self._watch.start(now_ns)
        if self.settings.mode == "single":
            self._single_ns, self._due_ns = None, now_ns
            return now_ns
        return self._grid.next_after(now_ns)

    # --- sampling -------------------------------------------------------------------------

    def _spec(self, config: bytes) -> StreamSpec:
        """The field's spec from Config A (rate, DO[4:2]) and Config B (gain, GN[7:5]) as
        read from the chip. Full scale: the largest field a data word can carry at that gain
        (uT), the most negative count before the overflow value, through this driver's
        conversion."""
        rate_hz = ODR_BY_CODE.get((config[0] >> CRA_RATE_SHIFT) & 0x07)
        if rate_hz is None:
            raise ConfigurationError(f"{self.describe()}: Config A reads back 0x{config[0]:02X}"
                                     ", a reserved output rate; check the bus")
        gain = gain_from_config_b(config[1])
        latency_s = 0.0 if self._feed is None else self._feed.latency_ns * 1e-9
        # mode: single stamps each field at its measurement's end, not a poll's guard later
        guard_s = 0.0 if self.settings.mode == "single" else 1 / (8 * rate_hz)
        return StreamSpec(
            self.device, Quantity.MAG, Frame.SENSOR, float(rate_hz),
            scale=decode.counts_to_ut((1, 0, 0), gain)[0],
            full_scale=abs(decode.counts_to_ut((DATA_MIN, 0, 0), gain)[0]),
            latency_s=latency_s + guard_s)

    def streams(self) -> tuple[StreamSpec, ...]:
        """The magnetic field (uT, sensor frame) as configured at the last read-back."""
        return self._streams

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        if self.plan is None:
            raise ConfigurationError(f"{self.describe()}: streams read before configure()")
        # Config A and B only: reading MODE would lock the data outputs
        self._streams = (self._spec(self._read(Reg.CONFIG_A, 2)),)
        return self._streams

    def poll(self, now_ns: int) -> PollResult:
        if self.gain_lsb_per_gauss is None:
            raise ConfigurationError(f"{self.describe()}: poll() before configure()")
        if self._restart_due:  # found off the plan by the poll before (``_reset_at``)
            self._restart_due = False
            return PollResult([], self.restart(reset_detected=True))
        if self.settings.mode == "single":
            return self._poll_single(now_ns)
        if self._read_back_now(now_ns) and self._watch.check_due(now_ns) \
                and self._off_plan():
            return PollResult([], self.restart(reset_detected=True))
        if self._feed is not None:
            result = self._poll_auto(now_ns)
            self._asked_ns = result.next_poll_ns
            return result
        status = self._read(Reg.STATUS, 1)[0]
        if status & STATUS_RDY:
            sample, configured = self._sample(now_ns)
            # RDY found after reads without it: the measurement read now is the one the
            # grid's next point aims at (its instant within the retry before now)
            after_now = now_ns + self._grid.guard_ns if self._not_ready else now_ns
            self._not_ready = False
            self._idle_from = None
            if not configured:
                # a reset chip (single measurement, then idle): its data are no field
                # measured in continuous mode as configured
                return PollResult([sample], self.restart(reset_detected=True))
            if not sample.flags & (SampleFlag.BLANK | SampleFlag.FROZEN):
                self._ready.fresh(Quantity.MAG, now_ns)
                self._watch.fresh_poll()
                if self._skip_next:
                    # measured at the old gain: its counts say nothing of the field, and
                    # what the averaging carries over is the same field at another scale
                    self._skip_next = False
                    self._memory.forget()
                    return PollResult([], self._grid.next_after(after_now))
                if sample.valid:
                    self._idle_from = now_ns
                return PollResult([sample], self._grid.next_after(after_now))
        else:
            self._not_ready = True
            if self._idle_from is not None:
                # RDY clear: an instant passed without a measurement (reading never clears
                # it), and every read since the latest valid field's found it clear
                self.health.idle = (self._idle_from, now_ns)
            if not self._ready.overdue(Quantity.MAG, now_ns):
                return PollResult([], now_ns + NOT_READY_RETRY_NS)
            sample = MagSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                               mag_ut=NAN3, flags=SampleFlag.STALE)
        return self._no_measurement(sample, now_ns)

    def _read_back_now(self, now_ns: int) -> bool:
        """read: auto: whether a periodic read-back due now may be made at this poll. It
        reads Mode, which locks the data outputs until the master's next copy: a
        measurement the chip makes meanwhile waits in the chip and reaches the master's
        copy after that one, a master period later than the feed's latency allows (7.8 ms
        after its measurement at -2 %, where the fields beside it came 1.4 ms after theirs:
        a gap of 1.5 periods, one field counted lost where none was). So it is made at a
        poll that takes a change delivered within a latency and a guard before it (the
        chip's next measurement then lies past the master's next copy, as on every poll on
        time of a grid on the chip's phase), or once no field has been taken for
        two periods (a chip that stopped): a grid early of a slow chip's instants
        (``_steer``) puts it off to its look again. Not steered (a chip on its nominal
        clock), for other reads, and on a poll plan before READ_BACK_PLAN: always."""
        feed = self._feed
        if feed is None or self.poll_plan < READ_BACK_PLAN or not self._ahead() \
                or now_ns - self._fresh_ns > 2 * self._grid.period_ns:
            return True
        return bool(feed.fresh) and \
            now_ns - feed.changed_ns <= feed.latency_ns + self._grid.guard_ns

    def _poll_auto(self, now_ns: int) -> PollResult:
        """``read: auto``: the bytes the master delivered (see the module docstring)."""
        assert self._feed is not None
        data = self._feed.data
        frozen = self._frozen.observe(Quantity.MAG, data) if data is not None \
            else SampleFlag.OK
        changes = self._feed.take()
        if not changes:
            self._read_again(data)
            proved = self._repeat_by_status(now_ns)
            if proved is not None:
                return proved
            self._hung_by_status(now_ns)
        if changes:
            repeat, self._repeat = self._repeat, None
            after_reset = self._reset_behind_blank(changes, now_ns) or \
                self._reset_behind_jump(changes, now_ns) or \
                self._reset_behind_hang(changes, now_ns)
            if after_reset is not None:
                return after_reset
            samples, blank = self._taken(changes, repeat, self._steer(changes, now_ns))
            self._ended_zeros = bool(samples) and not any(changes[-1].data)
            last = samples[-1] if samples else blank
            self._idle_from = last.t_ns if last is not None and last.valid else None
            self._hang_read = 0 if self._idle_from is not None else None
            if samples:
                self._fresh_ns = now_ns
                self._retrying = False
                self._watch.fresh_poll()
                return PollResult(samples, self._next_look(now_ns))
            if blank is None:  # from before configure() settled, or handed out before
                return PollResult([], self._next_look(now_ns))
            sample = blank
        elif now_ns - self._fresh_ns <= self._unchanged_limit_ns:
            return self._look_again(now_ns)
        else:
            sample = MagSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                               mag_ut=NAN3, flags=frozen or SampleFlag.STALE)
        return self._no_measurement(sample, now_ns)

    def _taken(self, changes: list[Copy], repeat: tuple[int, int] | None,
               now_ns: int) -> tuple[list[Sample], Sample | None]:
        """read: auto: the samples of a poll's ``changes`` (``_measurements``), after the
        repeat a status read proved before them when the first can be the measurement after
        it (``_repeated``); a hang's slots proved by the first copy after it."""
        repeated = self._repeated(repeat, changes)
        since, hung_ns, self._hung_ns = self._idle_from, self._hung_ns, None
        samples, blank = self._measurements(changes, now_ns, late=self._retrying)
        self._doubt_copies(changes, bool(samples), bool(repeated), repeat is not None,
                           now_ns, hung=hung_ns is not None)
        samples[:0] = repeated
        if since is not None and hung_ns is not None and samples and not repeated \
                and changes[0].t_ns < hung_ns + round(
                    self._grid.period_ns * (1 - CLOCK_TOLERANCE)):
            # the first copy after a read that proved the chip hung, delivered sooner
            # than a resumed chip's second measurement: its first, so the chip made
            # nothing between the field before the hang and this one
            self.health.adjacent = (since, samples[0].t_ns)
        return samples, blank

    def _read_again(self, data: bytes | None) -> None:
        """read: auto, a poll with no change: a master that delivered non-blank bytes since
        configure() read the chip (the bytes it had before, again: the feed survives a
        restart, and a copy equal to the one before is no change), which released the lock
        configure()'s read of Mode set (``_unread_lock``)."""
        assert self._feed is not None
        if data is not None and any(data) and self._feed.t_ns > self._mode_written_ns:
            self._unread_lock = False

    def _look_again(self, now_ns: int) -> PollResult:
        """read: auto, a poll that found no change: when to look next."""
        assert self._feed is not None
        retrying = self._retrying
        look_ns = None if retrying and not self._steered else self._repeat_look(now_ns)
        if retrying and look_ns is not None:
            # a grid that follows a chip clock off its nominal period (``_steer``) can lie
            # closer after the copies than the nominal one: the look once more came before
            # the master's first copy that a status read can prove a repeat with (a slow
            # chip's, until the grid moves later); look after that copy too, or a field
            # that repeated its bytes is lost
            return PollResult([], look_ns)
        if not retrying:
            self._looked_ns = now_ns if now_ns == self._asked_ns else None
        if look_ns is not None and look_ns < now_ns + self._feed.latency_ns:
            # the look once more, sooner: what it finds is stamped by its delivery
            self._retrying = True
            return PollResult([], look_ns)
        if not self._retrying:
            # The master's copy may have come a burst late (a failed slave read or IMU
            # burst): look once more one delivery latency later, else the measurement
            # is lost when the next one overwrites it.
            self._retrying = True
            return PollResult([], now_ns + self._feed.latency_ns)
        self._retrying = False
        return PollResult([], self._grid.next_after(now_ns))

    def _steer(self, changes: list[Copy], now_ns: int) -> int:
        """read: auto: keeps the poll grid a latency and a guard after the chip's own
        instants, which a chip clock off its nominal period moves along the grid (issue 25:
        up to +-2 %, 0.27 ms a field at 75 Hz); returns the time to stamp the poll's field
        at (``now_ns`` but below).

        A poll on time whose one change the master delivered at ``d``, a delivery after
        one on time (``_steady``): its measurement came before ``d`` and at most the
        feed's latency before it, so a poll on a grid a latency and a guard after the
        chip's instants comes at most a latency and a guard after ``d``. On the nominal
        clock it always does (2.9 to 6.0 ms after ``d`` of 6.2 at the seed's rates), and
        nothing here moves. Later, the grid lags the chip (a clock fast): it moves
        earlier by the excess, and the field is stamped where the moved grid's point lay.
        Left alone, the lag grew by 0.27 ms a field, and a copy older than a latency and a
        guard was stamped at its delivery (``_measurements``), up to 6 ms earlier after its
        measurement than the fields beside it: the frame ledger rounds each gap to whole
        periods and counted a field lost where none was (+60 in 20 s at +2 %), and the poll
        a period behind took two copies.

        Polls on time that came less than a guard after the deliveries of their fields,
        STEER_FIELDS fields in a row (a poll that found nothing, whose look again found its
        field, came before the delivery), run ahead of the chip (a clock slow): the grid
        moves a guard later. Left alone, the polls came ever earlier before the copies,
        their looks again stamped them at delivery, and once a look again came before the
        copy too, the next poll stamped it a period later (+102 in 20 s at -2 %). A copy
        that failed master reads delayed (the MAX21100 does not report them) comes late
        too, but one is no proof: moved at each such field, a grid on the nominal clock
        under 10 % bus errors came to lag its chip, and a poll a millisecond late then
        stamped its copy at the delivery (a field counted lost where none was)."""
        feed, grid = self._feed, self._grid
        assert feed is not None
        if len(changes) != 1 or self.poll_plan < CHIP_CLOCK_PLAN or not self._steady(changes[0]):
            return now_ns
        due = self._looked_ns if self._retrying else now_ns
        # a poll late (put off, a stalled host) or off the grid (a status read's look):
        # nothing of the grid's phase
        if due is None or (due != self._asked_ns and not self._retrying):
            return now_ns
        point = grid.point_at_or_before(due)
        if point != due:
            return now_ns
        after = due - changes[0].t_ns
        late = after - feed.latency_ns - grid.guard_ns
        afters = self._afters
        if late > 0 and not self._retrying:
            # stamped at the moved point when the field before was stamped at the point
            # before it (polls on time, the grid's cadence); after one stamped otherwise (by
            # its delivery: a poll put off by a stall, a slow chip's look again) this copy
            # may have waited a period for this poll, which skipped its look again (the
            # grid early of a slow chip): its delivery, as the field before's
            ahead = self._ahead()
            grid.anchor(point - late)
            afters.clear()
            self._steered = True
            return changes[0].t_ns if ahead else now_ns - late
        afters.append(after)
        if len(afters) == afters.maxlen and max(afters) < grid.guard_ns:
            grid.anchor(point + grid.guard_ns)
            afters.clear()
            self._steered = True
        return now_ns

    def _ahead(self) -> bool:
        """read: auto: the grid runs ahead of the chip's instants: ``_steer`` moved it (a
        chip clock off its nominal period) and a poll on time since it last moved came
        before the master's delivery of its field (its look again found it). A slow chip's
        grid stays so, up to a latency early (moved a guard later only after STEER_FIELDS
        such fields), and most of its fields are stamped by their deliveries, so a poll's
        own time is no stamp for a copy that waited for it."""
        return self._steered and any(after < 0 for after in self._afters)

    def _steady(self, copy: Copy) -> bool:
        """read: auto: ``copy`` is a new field delivered one master period after the
        delivery before it (no pause: the host's polls late, the master's own recovery),
        with no read of Mode between them (the lock it sets holds a measurement back until
        the master's next copy), after configure() settled: its delivery came within the
        feed's latency after its measurement, as far as the deliveries tell (``_steer``)."""
        assert self._feed is not None
        period, after = self._feed.period_ns, copy.after_ns
        if not period or after is None or copy.t_ns - after > period * 3 // 2:
            return False
        if any(after < locked <= copy.t_ns
               for locked in (self._locked_ns, self._locked_before_ns)):
            return False
        return copy.t_ns >= self._settle_ns and copy.data != self._emitted \
            and not blank_flag(copy.data)

    def _next_look(self, now_ns: int) -> int:
        """read: auto, after a poll that found the master's copies: the next grid point,
        or (poll plan 2, imuhal.core.poll_plan) the master's next delivery when it says one
        and that comes later (a FIFO read every n frames: ``AutoReadFeed.next_ns``), as no
        new copy can be found before it. Polled at the same time as the master, it comes
        after it (a device behind another's bus ranks after it)."""
        next_ns = self._grid.next_after(now_ns)
        assert self._feed is not None
        delivery_ns = self._feed.next_ns
        if delivery_ns > next_ns and self.poll_plan >= AFTER_DELIVERY_PLAN:
            return delivery_ns
        return next_ns

    def _repeat_by_status(self, now_ns: int) -> PollResult | None:
        """read: auto: the master's copies have not changed since the latest valid field's
        (``feed.changed_ns``), although a copy made after the chip's next measurement has
        come: the latest delivery lies more than ``_repeat_after_ns`` (a period at the
        slowest clock, CLOCK_TOLERANCE, and the feed's latency) after that change, and the
        measurement behind a change was made before its delivery. So the chip measured the
        same six bytes again (a field still to within a count: about 0.2 % of fields at
        +/-1.3 Ga), or it hung, or the master's reads of it failed; its copies, without
        the status register, cannot tell these apart, and value equality is no proof that
        nothing was measured. The status register tells the first two apart: RDY set is a
        chip that measures (a hang leaves RDY clear until it measures again), RDY clear
        twice, NOT_READY_RETRY_NS apart (a data write holds it clear 250 us), a hung chip
        (``health.idle``: its slots are not measured, issue 25). A repeat is not handed out
        yet: a master whose reads failed since the change shows the same, and the next
        change tells (``_repeated``). One read per such run, at most one repeat per change
        (two in a row are rarer than 1 in 10^5 fields), never past a period more, so FIFO
        reads 2.4 fields apart and a chip that stopped keep the rules of ``_poll_auto``.
        None: nothing proved, poll on as before."""
        assert self._feed is not None
        feed = self._feed
        # from the master's latest copy, not its latest delivery: a hung master (its own
        # data-ready clear) delivers its copy of before again, made before the chip's
        # next instant whatever the chip did since (``AutoReadFeed.copied_ns``)
        unchanged = feed.copied_ns - feed.changed_ns
        copied = self._repeat_after_ns <= unchanged
        # the master's copies paused (its chip hung too, the host stalled): RDY alone can
        # still prove a hang, once the chip's next instant and its data write are past
        paused = not copied and bool(feed.period_ns) \
            and now_ns - feed.copied_ns > feed.period_ns + NOT_READY_RETRY_NS // 4 \
            and now_ns >= feed.changed_ns + NOT_READY_RETRY_NS // 2 + round(
                self._grid.period_ns * (1 + CLOCK_TOLERANCE))
        if not self._armed() or not (paused or copied) \
                or unchanged >= self._repeat_after_ns + self._grid.period_ns:
            return None
        status = self._read(Reg.STATUS, 1)[0]
        if status & ~STATUS_BITS:
            # no chip drives the line (an unplugged one reads 0xFF): its reads fail, and
            # so may the master's; nothing proved in this run
            self._hang_read = None
            return None
        # a hung master (delivering, copying nothing): read again past the chip's second
        # instant, whatever this read found (``_look_past_second_instant``)
        look = None if copied else self._look_past_second_instant(now_ns)
        if status & STATUS_RDY:
            if not copied:
                return look  # not hung so far; the copies may yet prove a repeat
            self._hang_read = None  # no hang in this run: the chip measures
            if now_ns < self._doubt_until_ns:
                # the master's reads failed lately (a late copy looks the same): nothing
                return None
            # stamped where an on-time poll would have found it: a period after the field
            # it repeats (the grid's point), never after this poll
            stamp = min(self._stamped_ns + self._grid.period_ns, now_ns)
            self._repeat = (stamp, self._next_instant_ns())
            self._retrying = False
            return PollResult([], self._grid.next_after(now_ns))
        if look is not None:
            return look
        if now_ns < self._next_instant_ns():
            # no measurement could be writing its data now: the chip let its instant pass
            assert self._idle_from is not None  # _armed()
            self.health.idle = (self._idle_from, now_ns)
            self._hang_read, self._hung_ns = None, now_ns
            return None
        self._hang_read = now_ns
        return PollResult([], now_ns + NOT_READY_RETRY_NS)

    def _look_past_second_instant(self, now_ns: int) -> PollResult | None:
        """read: auto, a status read while the master delivers but copies nothing (its own
        chip hung: ``AutoReadFeed.copied_ns`` behind ``t_ns``): read again once the chip's
        second measurement after the latest change must have been written (two periods at
        the slowest clock after its delivery, and the write's 250 us). RDY then tells
        whether the chip let that instant pass. Sooner, RDY set proves nothing, and RDY
        clear proves a hang a frame ledger cannot use (its reads must reach 1.5 periods
        past the field's stamp, imuhal.pipeline.accounting); on the grid, a master's
        recovery holding the host can put the read off until the master copies again, and
        that copy then comes with no proof of how many measurements the chip made before
        it hung (the fault matrix hangs both chips at once). None: poll on as before (a
        master still copying, or paused as a whole: a stalled host; the read is past)."""
        assert self._feed is not None
        feed = self._feed
        look_ns = feed.changed_ns + round(2 * self._grid.period_ns * (1 + CLOCK_TOLERANCE)) \
            + NOT_READY_RETRY_NS // 2
        if feed.copied_ns >= feed.t_ns or look_ns <= now_ns:
            return None
        return PollResult([], look_ns)

    def _armed(self) -> bool:
        """A status read may yet prove a repeat or a hang in this run of unchanged copies:
        none made, the latest sample valid and its copy the master's latest change, no
        repeat proved since that change."""
        return self._hang_read == 0 and self._idle_from is not None and self._repeat is None

    def _next_instant_ns(self) -> int:
        """The earliest the chip's second measurement after the latest change can start
        writing its data (clearing RDY): that change's measurement came at most the feed's
        latency before its delivery, the next two at most two periods at the fastest clock
        later, less the 250 us a write holds RDY clear."""
        assert self._feed is not None
        feed, period = self._feed, self._grid.period_ns
        return feed.changed_ns - feed.latency_ns + round(2 * period * (1 - CLOCK_TOLERANCE)) \
            - NOT_READY_RETRY_NS // 2

    def _repeat_look(self, now_ns: int) -> int | None:
        """When to look next for the first copy a status read can prove something with
        (``_repeat_by_status``): right after the master's first delivery at least
        ``_repeat_after_ns`` after the latest change (its deliveries come ``period_ns``
        apart), so a hang's RDY is read before the measurement after it can set it again.
        None: no such look (nothing to prove, the master says no period, or that copy has
        come)."""
        assert self._feed is not None
        feed = self._feed
        bound = feed.changed_ns + self._repeat_after_ns
        step = feed.period_ns
        if not step or feed.t_ns >= bound or not self._armed() \
                or now_ns >= self._next_instant_ns():
            return None
        margin = step // 16  # after the master's poll of the same moment
        deliveries = -(-(bound - feed.t_ns) // step)
        look = feed.t_ns + deliveries * step + margin
        return look if look > now_ns else now_ns + step  # deliveries paused: one later

    def _doubt_copies(self, changes: list[Copy], handed_out: bool, repeated: bool,
                      proved: bool, now_ns: int, *, hung: bool = False) -> None:
        """Doubt the master's copies for DOUBT_NS after a sign that its reads of the chip
        fail (the MAX21100 reports no failed slave read; a failed one keeps the copy
        before, which looks like a repeat): a repeat a status read proved whose next change
        came too soon for it, or a change delivered later than a measuring chip's next
        copy (the first of ``changes``, after unbroken deliveries) with no repeat proved
        before it and no hang (``hung``). A
        hang or an unproved repeat shows the same and costs only the repeats of the next
        DOUBT_NS, counted lost as before."""
        assert self._feed is not None
        first = changes[0]
        # from a change handed out only (not one from before configure() settled)
        previous, self._change_ns = self._change_ns, \
            changes[-1].t_ns if handed_out else None
        feed = self._feed
        late = previous is not None and not proved and not hung \
            and first.after_ns is not None \
            and first.t_ns - first.after_ns <= feed.latency_ns \
            and first.t_ns - previous > self._repeat_after_ns
        if late or (proved and not repeated):
            self._doubt_until_ns = now_ns + DOUBT_NS

    def _repeated(self, repeat: tuple[int, int] | None, changes: list[Copy]) -> list[Sample]:
        """The repeat a status read proved (``_repeat_by_status``: its stamp, and the
        earliest delivery of the measurement after it), handed out when the next change
        (the first of ``changes``) can be that later measurement: delivered after the
        earliest time the chip's second instant after the change could be copied (two
        periods at the fastest clock after the change's measurement, which came at most the
        feed's latency before its delivery), and followed in ``changes`` by no change
        sooner than the chip's third instant could be copied (a period at the fastest clock
        later). A change delivered sooner, or one a measurement followed within less than a
        period, is the measurement the repeat stood for, copied late (the master's reads
        failed until then; at 10 % bus errors two in a row delayed a copy 8 ms, past the
        first bound, and the next measurement came 4 ms after it): no repeat. Nor before a
        blank copy."""
        first = changes[0]
        if repeat is None or first.t_ns < repeat[1] or blank_flag(first.data) \
                or self._emitted is None or first.t_ns < self._stamped_ns:
            return []
        third_ns = repeat[1] + round(self._grid.period_ns * (1 - CLOCK_TOLERANCE))
        if any(c.t_ns < third_ns and not blank_flag(c.data) for c in changes[1:]):
            return []
        stamp = repeat[0]
        sample = self._decoded(self._emitted, stamp, SampleFlag.OK)
        if not sample.valid:
            return []
        self._stamped_ns = self._cadence_ns = stamp
        return [sample]

    def _hung_by_status(self, now_ns: int) -> None:
        """read: auto: the master's copies have not changed since the latest valid field's
        for ``unchanged_periods`` (more than a measuring chip repeats its bytes: the chip
        stopped, or the master's reads of it fail, which its copies, without the status
        register, cannot tell apart). The status register then tells: RDY clear at two
        polls, longer apart than the 250 us a data write holds it clear, is a chip whose
        data-ready is stuck, whose engine hung; it answered, so the master's reads reach it
        (a chip unplugged reads 0xFF, RDY set; one that froze keeps RDY set). The reads
        found nothing new since that field (``health.idle``, for the frame ledger's count
        of a hung chip's slots, issue 25). Reading the status register locks no data
        output. Made only in such a run, which a healthy chip's odds (REPEAT_ODDS) rule
        out."""
        assert self._feed is not None
        feed, first = self._feed, self._hang_read
        if first is None or self._idle_from is None \
                or (not first and feed.t_ns - feed.changed_ns < self._hung_after_ns) \
                or (first and now_ns - first < NOT_READY_RETRY_NS):
            return
        if self._read(Reg.STATUS, 1)[0] & STATUS_RDY:
            self._hang_read = None
        elif not first:
            self._hang_read = now_ns
        else:
            self.health.idle = (self._idle_from, now_ns)
            self._hang_read, self._hung_ns = None, now_ns

    def _reset_behind_jump(self, changes: list[Copy], now_ns: int) -> PollResult | None:
        """A copy whose field magnitude jumped (MAGNITUDE_STEP) from the one before it: a
        reset chip's measurement at its power-on gain when the master's reads missed the
        zeros before it (they failed for the whole measurement time, about 6 ms). Checked
        like ``_reset_behind_blank``: off the plan, the copies before it are handed out,
        it is STALE and the chip reconfigured; on the plan it is a field like any other.
        None: nothing to do."""
        previous = self._emitted
        if previous is not None and blank_flag(previous):
            previous = None
        before = None  # the magnitude of ``previous``, worked out once, when first needed
        for k, copy in enumerate(changes):
            data = copy.data
            if blank_flag(data):
                previous = before = None
                continue
            if previous is not None:
                if before is None:
                    before = _norm(previous)
                norm = _norm(data)
                if abs(norm - before) > MAGNITUDE_STEP * before:
                    return self._reset_at(changes, k, now_ns)
                before = norm
            previous = data
        return None

    def _reset_behind_hang(self, changes: list[Copy], now_ns: int) -> PollResult | None:
        """The first change after a status read proved the chip idle in this run of
        unchanged copies (``_hung_ns``: RDY clear when a measuring chip would have set it):
        a chip whose engine hung and measures again, or one that lost power or reset (an
        unplugged chip plugged back in), whose registers came back at their defaults
        (single mode, RDY clear until its one measurement at the power-on gain and
        averaging). At the default range (1.3 Ga) that measurement has the configured gain,
        so neither its magnitude (``_reset_behind_jump``) nor its bytes tell it; nor do zeros
        when the master delivered none while the chip's registers held them. So the
        configuration is read back before it is handed out (``_reset_at``: once per proved
        hang). None: as configured, nothing to do."""
        if self._hung_ns is None:
            return None
        return self._reset_at(changes, 0, now_ns)

    def _reset_at(self, changes: list[Copy], k: int, now_ns: int) -> PollResult | None:
        """When the configuration reads back off the plan: the copies before ``changes[k]``
        handed out, a STALE sample for the reset chip's measurement, and the chip
        reconfigured; None when it reads back as written. With copies handed out, the chip
        is reconfigured at the next poll, at once: the frame ledger counts a reconfiguration
        before the samples of the poll that made it, and these fields, measured before the
        reset, end the segment of the chip's cadence they belong to."""
        if not self._off_plan():
            return None
        samples, _ = self._measurements(changes[:k], now_ns, late=True)
        samples.append(MagSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                                 mag_ut=NAN3, flags=SampleFlag.STALE))
        if len(samples) > 1:
            self._restart_due = True
            return PollResult(samples, self.clock.now_ns())
        return PollResult(samples, self.restart(reset_detected=True))

    def _reset_behind_blank(self, changes: list[Copy], now_ns: int) -> PollResult | None:
        """A copy of all-zero bytes followed by a measurement in one poll's copies: the
        HMC5883L's data registers read 0 after power-on (datasheet tables 13-15) and a reset
        chip then measures once at its power-on gain and averaging, in single mode, which
        the six bytes the master copies cannot show (Mode is not among them). So before that
        measurement is handed out the configuration is read back: off the plan, the copies
        before the zeros are handed out, the measurement after them is STALE (counted, no
        value) and the chip reconfigured. A blank alone in a poll is checked by
        ``_no_measurement``; zeros from a master reset (the MAX21100 clears its copy) find
        the HMC5883L as configured, and the copies go on as usual. Zeros that end a poll
        whose earlier copies were handed out (no blank poll reads the configuration back
        then) have the first copy of the next poll checked the same way. None: nothing to
        do."""
        ended_zeros, self._ended_zeros = self._ended_zeros, False
        if ended_zeros and any(changes[0].data):
            return self._reset_at(changes, 0, now_ns)
        if len(changes) < 2:  # (the usual poll) a blank alone or last: nothing to do
            return None
        last = max((k for k, copy in enumerate(changes) if not any(copy.data)), default=None)
        if last is None or last == len(changes) - 1:
            return None
        return self._reset_at(changes, last, now_ns)

    def _measurements(self, changes: list[Copy], now_ns: int, *,
                      late: bool) -> tuple[list[Sample], Sample | None]:
        """The samples of the master's copies that changed since the previous poll
        (``changes``: delivery time, bytes, oldest first; more than one when its reads
        brought two measurements between two polls, as FIFO reads at the IMU's own
        instants can), and the last blank one when none is a measurement. The newest is
        stamped with this poll, as one alone is; an older one with its delivery (its
        measurement at most the feed's latency before it, or on the driver's grid when the
        master paused before it: ``_after_pause``, ``stamp_on_cadence``), kept in order. So
        is the newest when this poll looks again for a copy that was not there on time (``late``): a
        failed slave read or IMU burst delayed it, and the poll a delivery latency after the
        planned one would stamp it up to 7 ms late at the seed's rates, past half the
        field's period, where the frame ledger counts a field the chip never skipped; and
        when it came more than a latency and a guard before this poll (a poll put off a
        period after the master's late deliveries, which reads the copy before the one it
        aimed at)."""
        samples: list[Sample] = []
        blank: Sample | None = None
        assert self._feed is not None
        pause_ns = self._feed.latency_ns * 4 // 3
        # an on-time poll comes at most a latency and a guard after the copy of the
        # measurement it reads; a copy older than that at this poll (one put off a period:
        # the master was late too, and the copy the put-off poll aimed at had not come)
        # would be stamped a period after its measurement
        stale_ns = now_ns - self._feed.latency_ns - self._grid.guard_ns
        for k, delivered in enumerate(changes):
            copy = self._unlocking(delivered)
            if copy is None:
                continue
            t_ns, data = copy.t_ns, copy.data
            if t_ns < self._settle_ns or data == self._emitted:
                continue
            left = len(changes) - 1 - k  # copies after this one: each needs a later stamp
            by_delivery = left or late or copy is not delivered or t_ns < stale_ns \
                or (self._ahead() and _after_a_pause(copy, pause_ns))
            if by_delivery:
                t_ns = self._by_delivery(copy, pause_ns,
                                         taken_late=not (left or late) and copy is delivered)
                if left and not blank_flag(changes[k + 1].data):
                    t_ns = self._before_next(t_ns, changes[k + 1].t_ns)
            stamp = min(max(t_ns, self._stamped_ns + 1), now_ns - left) \
                if by_delivery else now_ns
            sample = self._decoded(data, stamp, blank_flag(data))
            if sample.flags and sample.flags & SampleFlag.BLANK:  # (enum & is a call)
                blank = sample
                continue
            self._emitted = data
            self._stamped_ns = self._cadence_ns = stamp
            samples.append(sample)
        return samples, (None if samples else blank)

    def _by_delivery(self, copy: Copy, pause_ns: int, *, taken_late: bool) -> int:
        """The stamp of a copy not stamped with this poll (``_measurements``): after a
        pause on the grid (``_after_pause``), after failed reads on the cadence
        (``stamp_on_cadence``), else its delivery, or, the newest copy a late poll took
        (``taken_late``), the grid point a poll on time would have taken it at
        (``_on_time_point``)."""
        t_ns = self._after_pause(copy, pause_ns) or stamp_on_cadence(
            copy, self._cadence_ns, self._grid.period_ns, pause_ns=pause_ns)
        if taken_late and t_ns == copy.t_ns:
            return self._on_time_point(t_ns)
        return t_ns

    def _after_pause(self, copy: Copy, pause_ns: int) -> int | None:
        """The stamp of a copy the master delivered after a pause in its deliveries
        (longer than ``pause_ns``: the host's polls late or stalled, the master's reads
        failing): where a poll on time would have stamped its measurement, the latest
        point of the driver's grid (a latency and a guard after each of the chip's
        instants from the Mode write) at or before the delivery, or the first after the
        field before when none lies between. Stamped at the delivery, or on the cadence of
        a field stamped off the grid itself, it lay up to a period after its measurement
        where its neighbours lay a guard after theirs, and the frame ledger's gaps, rounded
        to whole periods, counted a field the chip never skipped (a 20 ms pause of
        ``jitter`` at 10 %: 1.93 periods after a field stamped 1.8 ms after its own). On a
        chip clock a few percent off its nominal period the grid follows the chip's
        instants as the polls do (``_steer``). None: no pause, or no field yet
        (``stamp_on_cadence``)."""
        last = self._cadence_ns
        if last is None or copy.after_ns is None or copy.t_ns - copy.after_ns <= pause_ns:
            return None
        grid = self._grid
        point = grid.point_at_or_before(copy.t_ns)
        if point <= last:
            point = grid.point_at_or_before(last) + grid.step_ns
        return point

    def _on_time_point(self, delivered_ns: int) -> int:
        """The stamp of the newest copy a poll took more than a latency and a guard after
        its delivery (the poll came late: ``_measurements``' ``stale_ns``): the point of
        the driver's grid a poll on time would have taken it at, the first at or after the
        delivery, when the copy came no sooner than the chip's instant that point stands
        for (a latency and a guard before it, less a quarter of a guard for a grid a little
        off the chip's instants: 0.2 ms at 10 % bus errors, seed 7); else its delivery (its
        measurement came before that instant: a copy a period late, or a grid off its
        chip's phase, as after the restarts of FIFO reads under 10 % bus errors, where a
        copy 6.7 ms before the point carried a measurement 13 ms before it).
        Stamped at its delivery, an on-time copy lay up to a latency before where its
        neighbours, taken on time, lay (a guard and a latency after their measurements),
        and next to a copy failed reads delayed (stamped at its delivery, up to 9 ms after
        its measurement) the frame ledger's gap rounded to a field the chip never skipped
        (10 % bus errors, seeds 4 and 7: 20.2 ms between fields 13.3 ms apart)."""
        assert self._feed is not None
        grid = self._grid
        point = grid.point_at_or_before(delivered_ns)
        if point < delivered_ns:
            point += grid.step_ns
        if point - delivered_ns > self._feed.latency_ns + grid.guard_ns + grid.guard_ns // 4:
            return delivered_ns
        return point

    def _before_next(self, t_ns: int, next_ns: int) -> int:
        """The stamp ``t_ns`` of a copy whose next change, a measurement, was delivered at
        ``next_ns``: the chip measures once a period, so this copy's measurement came a
        period before that one, and a poll on time for it came at most a latency and a
        guard after it. A stamp later than that (a copy after a host stall that
        ``stamp_on_cadence`` put two periods after the field before, where the chip made
        one) goes back to the latest point of the cadence before that bound; the frame
        ledger counts the gap from it."""
        assert self._feed is not None
        last, period = self._cadence_ns, self._grid.period_ns
        bound = next_ns - period + self._feed.latency_ns + self._grid.guard_ns
        if last is None or t_ns <= bound:
            return t_ns
        periods = int((bound - last) / period + 0.1)
        return min(t_ns, last + periods * period) if periods >= 1 else t_ns

    def _unlocking(self, copy: Copy) -> Copy | None:
        """``copy`` as the time its measurement was made allows. The master's first copy
        after the driver read Mode is the locked outputs: a measurement made before that
        read (its delivery taken as the read's time), or None when the read was
        configure()'s, whose locked bytes are from before the configuration. While the
        master copies, that copy repeats the one before and is no change; after the
        master's auto-read was off (its chip reset and reprogrammed, its copies blank
        meanwhile) it differs, and it is as old as the read or older. Delivered long after
        the read by a master that kept copying, it is a copy of its own
        (``_copied_since``)."""
        locked, blank_since = self._locked_ns, self._blank_since_ns
        if copy.t_ns < locked:  # delivered before the latest read of Mode (a check of a
            locked = self._locked_before_ns  # poll's copies reads it before they are taken)
        blank = bool(blank_flag(copy.data))
        self._blank_since_ns = (copy.t_ns if blank_since is None else blank_since) \
            if blank else None
        after = copy.after_ns
        # the delivery before it came before the read, or only blank copies did (the
        # master's registers reset: it read no slave), or only blank ones since
        # configure() (the master's copies restart with its auto-read reprogrammed, blank
        # until it reads the chip; a reset chip's old measurement is what it reads first)
        unread = self._unread_lock
        first = (after is not None and after < locked) or \
            (blank_since is not None and blank_since <= locked) or unread
        if not blank:
            self._unread_lock = False
        if blank or not first or copy.t_ns < locked:
            return copy
        if blank_since is None and not unread and self._copied_since(copy, locked):
            return copy
        if locked < self._settle_ns:
            return None
        return copy._replace(t_ns=locked)

    def _copied_since(self, copy: Copy, locked: int) -> bool:
        """``copy``, the master's first delivery after the read of Mode at ``locked``, came
        so late after it (more than a latency and a master period: the host's polls late or
        put off) that the copying master (no blank copies, no configure() since) made two
        copies or more since the read, unseen: the first released the lock, and this one
        holds a measurement of its own, no locked outputs. Dated at the read, it lay before
        its measurement (5 ms jitter from 0.30 s: the chip's field after the locked one
        stamped at the read, the ledger one field above the chip's count)."""
        feed = self._feed
        assert feed is not None
        return bool(feed.period_ns) and copy.t_ns - locked > feed.latency_ns + feed.period_ns

    def _no_measurement(self, sample: Sample, now_ns: int) -> PollResult:
        """No usable measurement (``sample`` says why): check the configuration at once, and
        restart the chip when it keeps producing nothing (rewriting the mode restarts
        continuous measuring)."""
        if self._watch.check_due(now_ns, overdue=True) and self._off_plan():
            return PollResult([sample], self.restart(reset_detected=True))
        if self._watch.stale_poll():
            return PollResult([sample], self.restart(reset_detected=False))
        return PollResult([sample], self._grid.next_after(now_ns))

    def _sample(self, now_ns: int) -> tuple[Sample, bool]:
        """Read Mode and the six data bytes (X, Z, Y) in one transaction and decode the
        data, flagging a blank or frozen frame (values NaN) and out-of-range or overflowed
        counts; and whether the chip still measures in the planned mode. A chip that does
        not: its sample is STALE (values NaN)."""
        assert self.gain_lsb_per_gauss is not None and self.plan is not None
        raw = self._read(Reg.MODE, MODE_AND_DATA)
        data = raw[Reg.X_MSB - Reg.MODE:]
        blank = blank_flag(data)
        if not blank and self.plan.mismatches({Reg.MODE: raw[0]}):
            return MagSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                             mag_ut=NAN3, flags=SampleFlag.STALE), False
        return self._decoded(data, now_ns, blank or self._frozen_flag(data)), True

    def _decoded(self, raw: bytes, now_ns: int, bad: SampleFlag) -> Sample:
        """The sample of the six data bytes ``raw`` (registers 0x03..0x08), NaN when ``bad``
        says it is no measurement."""
        assert self.gain_lsb_per_gauss is not None
        if bad:
            return MagSample(t_ns=now_ns, device=self.device, frame=Frame.SENSOR,
                             mag_ut=NAN3, flags=bad)
        counts = decode.data_counts_xyz(raw)
        flags = decode.counts_flags(counts)
        settling = self._memory.flag(Quantity.MAG, now_ns, flags)
        if settling:  # (an enum operation costs a Python call)
            flags |= settling
        return MagSample.build(now_ns, self.device, flags, Frame.SENSOR,
                               decode.counts_to_ut(counts, self.gain_lsb_per_gauss))

    def filter_memory_outputs(self) -> int:
        """Outputs after an overflowed or out-of-range one that the averaging (Config A
        MA1..MA0, 1 to 8 measurements per output) can still carry it. The datasheet does
        not say whether the average restarts at each output or runs over the last
        measurements; taken as the running one (the worse case): ``averaging - 1``."""
        return self.settings.averaging - 1

    def _frozen_flag(self, raw: bytes) -> SampleFlag:
        return self._frozen.observe(Quantity.MAG, raw)

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """One field per continuous-mode output period (Config A's data output rate)."""
        return Quantity.MAG, self._grid.period_ns

    def resume(self, now_ns: int) -> int | None:
        """One transfer of a poll failed: when Config A/B and Mode still read back as
        written (the read-back also releases the data lock a partial data read may have
        set), the chip kept measuring, so poll again at once instead of the full recovery
        (which rewrites the configuration and drops the first measurement after it).

        After a configure() the failure broke (a restart's) that wrote its plan in full,
        its Mode write restarted the chip's measurements with a new phase: when the plan
        reads back as written, the rest of configure() is done (the grid anchored at that
        write by start(), a reconfiguration counted: the frame ledger's segment ends).
        Resumed as a glitch, the driver polled on the old grid and the ledger counted
        across the restart (the fault matrix's ``bus_errors+os_error+all_ones`` at 10 %);
        the full recovery probes the chip again first, whose one-shot reads through an
        auto-read master fail on such a wire for seconds. Broken within its writes: the
        full recovery."""
        if self._configuring:
            return self._resume_configure(now_ns)
        if self._feed is None:
            self._idle_from = None  # a failed read breaks the run of reads a hang's proof needs
        if self.settings.mode == "single" and self.gain_lsb_per_gauss is not None:
            # a failed Mode write is made again, a failed read read again (the chip keeps a
            # single measurement until the next Mode write); the next read carries Config A/B
            return max(now_ns, self.clock.now_ns())
        if self.gain_lsb_per_gauss is None or self._off_plan():
            return None
        return max(now_ns, self.clock.now_ns())

    def _resume_configure(self, now_ns: int) -> int | None:
        """``resume`` after a broken configure(): see there."""
        plan = self._written
        if plan is None:
            return None
        got = plan.read(self.regs)
        if plan.mismatches(got):
            return None
        self._configured_as(plan, got)
        self.health.reconfigurations += 1
        return self.start(max(now_ns, self.clock.now_ns()))

    @property
    def host_paced(self) -> bool:
        """mode: single: the chip measures when the driver's Mode write tells it to."""
        return self.settings.mode == "single"

    def _poll_single(self, now_ns: int) -> PollResult:
        """``mode: single``: start a measurement at each point of the driver's cadence
        (``odr_hz`` on the host's clock: a Mode write of single), read it SINGLE_WAIT_NS
        later (Config A through the data in one read: as many transactions per field as
        continuous mode's status and data reads) and stamp it at its end. The chip makes
        exactly the measurements the driver starts, so on any chip clock no field is handed
        out twice and none is lost unseen. A start more than half a period late (a stalled
        host) slides the cadence, a measurement not done by the next start is one the chip
        never made (hung: Mode still reads single): both are slots the chip did not
        measure (``DeviceHealth.not_converted_ns``, as the MS5611's). Config A/B off the
        plan, or Mode continuous, is a silent reset (STALE, reconfigured)."""
        assert self.plan is not None
        period = self._grid.period_ns
        if self._single_ns is None:
            if now_ns < self._due_ns:
                return PollResult([], self._due_ns)
            if 2 * (now_ns - self._due_ns) > period:
                self.health.not_converted_ns += now_ns - self._due_ns
                self._due_ns = now_ns
            self.regs.write(Reg.MODE, MODE_SINGLE)
            self._single_ns = max(now_ns, self.clock.now_ns())
            self._due_ns += period
            return PollResult([], self._single_ns + SINGLE_WAIT_NS)
        raw = self._read(Reg.CONFIG_A, CONFIG_TO_DATA)
        stamp_ns = self._single_ns + SINGLE_MEASUREMENT_NS
        data = raw[Reg.X_MSB - Reg.CONFIG_A:]
        md = raw[Reg.MODE - Reg.CONFIG_A] & MODE_MD_MASK
        blank = blank_flag(raw)
        if not blank and (md == MODE_CONTINUOUS or self.plan.mismatches(
                {Reg.CONFIG_A: raw[0], Reg.CONFIG_B: raw[1]})):
            return PollResult([self._decoded(data, stamp_ns, SampleFlag.STALE)],
                              self.restart(reset_detected=True))
        if not blank and md == MODE_SINGLE:
            if now_ns + NOT_READY_RETRY_NS < self._due_ns:
                return PollResult([], now_ns + NOT_READY_RETRY_NS)
            self.health.not_converted_ns += period  # its slot passed unmeasured
            blank = SampleFlag.STALE
        self._single_ns = None
        if blank:
            sample = self._decoded(data, stamp_ns, blank)
            if self._watch.stale_poll():
                return PollResult([sample], self.restart(reset_detected=False))
            return PollResult([sample], max(now_ns, self._due_ns))
        self._watch.fresh_poll()
        if self._skip_next:  # measured at the old gain (see poll)
            self._skip_next = False
            self._memory.forget()
            return PollResult([], max(now_ns, self._due_ns))
        return PollResult([self._decoded(data, stamp_ns, self._frozen_flag(data))],
                          max(now_ns, self._due_ns))

    def _off_plan(self) -> bool:
        """The plan's check (Config A/B and Mode: a mismatch is a silent reset, defaults
        0x10, 0x20, single mode, or nothing answering), then the data lock that reading Mode
        set released (with read: auto, the master's next read of the six bytes does)."""
        assert self.plan is not None
        wrong = self.plan.check_next(self.regs)
        if self._feed is None:
            self._read(Reg.X_MSB, 6)
        else:
            self._locked_before_ns, self._locked_ns = self._locked_ns, self.clock.now_ns()
        return wrong is not None


def _after_a_pause(copy: Copy, pause_ns: int) -> bool:
    """The master delivered nothing for longer than ``pause_ns`` before ``copy`` (a host
    stall, polls put off): its measurement may have waited up to a field period in the
    chip. Taken by a poll of a grid that ``_steer`` moved (a chip clock off its nominal
    period: a slow chip's grid runs up to a latency early of its instants, as its looks
    again show), the poll's time says nothing of when it was made: 20 ms stalls at -2 %
    stamped such a copy 14.4 ms after its measurement, a gap of two periods from the
    field before where the chip made one. It is stamped as an older copy of a poll is
    (``Hmc5883lDriver._by_delivery``: on the grid, or the cadence of the field before)."""
    after = copy.after_ns
    return after is not None and copy.t_ns - after > pause_ns


def _norm(data: bytes) -> float:
    """The magnitude of six data bytes' field, in counts."""
    return math.hypot(*decode.data_counts_xyz(data))


def _partly_unanswered(found: bytes) -> bool:
    """Some ID bytes read 0xFF (unanswered) and every other one is the HMC5883L's."""
    unanswered = [b == 0xFF for b in found]
    return (any(unanswered) and not all(unanswered) and len(found) == len(IDENTITY)
            and all(u or b == e for b, e, u in zip(found, IDENTITY, unanswered, strict=True)))


def _show(found: bytes) -> str:
    text = found.decode("ascii", "replace") if all(32 <= b < 127 for b in found) else ""
    return f"ID bytes {found.hex(' ')}" + (f" ('{text}')" if text else "")


def _identity_hint(found: bytes) -> str:
    if found == b"\xff\xff\xff":
        return ("nothing drives the bus (all 0xFF): check SDA/SCL wiring and pull-ups, or "
                "the I2C master the magnetometer sits behind")
    if found == b"\x00\x00\x00":
        return "ID reads as zeros: a clone or another chip at 0x1E; this driver needs 'H43'"
    return ("another chip (or an HMC5883L clone with a different register map) answers at "
            "this address; QMC5883L clones live at 0x0D and need their own driver")
