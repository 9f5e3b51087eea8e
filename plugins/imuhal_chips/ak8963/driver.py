"""AK8963 (AKM) 3-axis magnetometer driver, standalone or behind an MPU-9250.

Source of the register facts: MPU-9250 Register Map RM-MPU-9250A-00 rev 1.4 section 5 and
Linux ``inv_mpu_magn.c`` (imuhal shared chip facts, section 4).

The driver speaks plain I2C to address 0x0C. Inside an MPU-9250 (GY-91, MPU-9250 modules)
the AK8963 is reached through the MPU's ``aux`` child bus: its bypass (host I2C) or its
internal I2C master (also when the MPU is on SPI); this driver does not know which.

configure(): soft reset, fuse-ROM mode to read the sensitivity adjustment ASAX..ASAZ,
power-down, then continuous mode at ``odr_hz`` and ``resolution_bits``, read back and verified.
poll(): one burst ST1..ST2 (0x02..0x09): ST1.DRDY says whether it is new, and reading ST2 last
releases the data for the next measurement. HOFL -> SampleFlag.OVERFLOW (never valid);
a count at the data range limit -> SATURATED, beyond it -> OUT_OF_RANGE; a burst of all
0x00/0xFF -> BLANK, a repeated frame -> FROZEN. The shared polling toolkit
(imuhal.drivers.polling) decides staleness, re-reads CNTL1 every ``reset_check_s`` to catch a
silent reset, and restarts a magnetometer that keeps its mode but stops converting.
``read: auto`` (behind a master that can auto-read, imuhal.bus.auto_read: the MPU-9250's
``imu/aux`` in master mode): the MPU's slave 0 reads ST1..ST2 (8 bytes) at each MPU sample
into EXT_SENS_DATA and the driver takes them from the MPU's burst, with no transaction of its
own; identity, the fuse-ROM ASA read at configure and the periodic CNTL1 read-back still use
the master's one-shot path (slave 4). Because ST1 is in the bytes, a measurement is new when
DRDY is set (the master's read of ST2 released it and cleared DRDY, so a copy with DRDY comes
from one measurement) and the bytes differ from the copy delivered before it: the copy a
failed (NACKed) master read leaves in EXT_SENS_DATA repeats the one before and is not new,
while two equal measurements in a row have a copy without DRDY between them and both count.
The feed queues every new copy (``AutoReadFeed.keep_ready_only``, ``take``), so polling at
the AK8963's rate while the MPU reads faster, or reads its FIFO in bursts, loses nothing.
No new measurement for STALE_AFTER_PERIODS -> a STALE sample (a chip repeating its bytes
gives no new copy, so STALE too); HOFL -> OVERFLOW;
never valid.
Each new copy is a sample stamped with the time the master copied it (the MPU's poll, or
its FIFO frame's chip-clock stamp): at most one MPU sample period after the measurement;
several copies read from the FIFO in one burst are several samples. A copy that follows
slave-0 reads the MPU-9250 reported failed (I2C_MST_STATUS.SLV0_NACK, read with every
burst) or a pause in the master's deliveries (its recovery, blank reads) is stamped on the
chip's own cadence instead (``imuhal.bus.auto_read.stamp_on_cadence``), so the frame ledger
counts what the chip measured (issue 25); a copy after master reads that all found DRDY
clear for 1.5 field periods proves the chip hung, as direct reads do (``health.idle``).
Staleness is judged on
the master's deliveries, so a master delivering late (a FIFO after a host stall) is not a
stale magnetometer.
Output: uT in the AK8963's own axes
(mag X = MPU accel Y, mag Y = MPU accel X, mag Z = -MPU accel Z); the profile's mount
rotation takes it to the body frame.
"""

from __future__ import annotations

from functools import partial
from typing import ClassVar, Literal

from imuhal.bus.auto_read import (
    AutoReadBus,
    AutoReadFeed,
    Copy,
    require_auto_read,
    stamp_on_cadence,
)
from imuhal.bus.base import BusKind, Link
from imuhal.bus.register_plan import IN_PLACE_ATTEMPTS, RegisterPlan, RegisterSetting, retried
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.poll_plan import CHIP_CLOCK_PLAN
from imuhal.core.samples import Frame, MagSample, Quantity, SampleFlag
from imuhal.core.streams import StreamSpec
from imuhal.drivers.base import (
    DeviceIdentity,
    Driver,
    DriverSettings,
    PollResult,
    SettingsInput,
)
from imuhal.drivers.polling import DataReady, PollGrid, ResetWatch, reset_check_field
from imuhal.drivers.settings import SlaveRead
from imuhal.drivers.validity import NAN3, FrozenWatch, blank_flag
from imuhal_chips.ak8963 import registers as r
from imuhal_chips.ak8963.decode import Measurement, decode_burst

EARLY_FRACTION = 64
"""Read directly (bypass), the poll grid steps 1/64 period short of the period until it has
learnt the chip's own (``PollGrid(track=True)``) and a poll that finds no DRDY retries a
guard later, so the polls sit within a guard after the chip's measurements. Anchored at
whichever poll last found data, a poll after a blank read (``all_zeros``) or a late one
(``jitter``) moved the grid up to a period after the chip's instants, and a poll late by
less than half a period then read the next field: the frame ledger counted one off
(issue 25). Behind a master the copies come at the master's samples, whose grid this is
not (a grid one delivery latency after the measurement instants, re-anchored at each)."""

BEHIND_MPU_HINT = (
    "inside an MPU-9250 the AK8963 answers only when the MPU's bypass is enabled or through "
    "its I2C master: put this device on the mpu9250's 'aux' bus"
)


def _plausible_asa(asa: bytes) -> bool:
    """No fuse-ROM byte at an end of the adjustment's range (0x00, 0xFF): what a line held
    low or left floating reads."""
    return 0x00 not in asa and 0xFF not in asa


class AK8963Settings(DriverSettings):
    """AK8963 settings: continuous measurement rate and output resolution."""

    odr_hz: Literal[8, 100] = 100
    """Continuous mode 1 (8 Hz) or 2 (100 Hz)."""
    resolution_bits: Literal[14, 16] = 16
    """14-bit (0.6 uT/LSB) or 16-bit (0.15 uT/LSB) output."""
    reset_check_s: float = reset_check_field()
    """How often (s) CNTL1 is read back to catch a silent chip reset."""
    read: SlaveRead = "one-shot"
    """How the data are read: ``one-shot``, by the driver at each poll (ST1..ST2 in one
    transfer) on any I2C bus (the host bus, the MPU-9250's bypass or its slave-4 master);
    ``auto``, by the MPU-9250's slave 0 at every MPU sample, handed over in the MPU's burst
    (its ``aux`` bus in master mode)."""


class AK8963Driver(Driver):
    """AKM AK8963 magnetometer (the magnetometer die of the MPU-9250)."""

    name = "ak8963"
    description = "AKM AK8963 magnetometer, I2C 0x0C (inside the MPU-9250: use its aux bus)"
    Settings = AK8963Settings
    channels: ClassVar[tuple[Quantity, ...]] = (Quantity.MAG,)
    bus_kinds: ClassVar[frozenset[BusKind]] = frozenset({BusKind.I2C})
    resumes_in_a_row = IN_PLACE_ATTEMPTS
    """Each ``resume()`` reads CNTL1 back (a soft reset or power-on clears it)."""

    FROZEN_AFTER_FRAMES = 30
    """Identical data frames in a row that mean the chip stopped measuring. The quietest
    setting (14 bits, 0.6 uT/LSB, about 0.3 uT noise: 0.5 LSB per axis) repeats a three-axis
    frame with probability about 0.2; 30 in a row (0.3 s at 100 Hz), about 1e-21 per sample."""

    def __init__(self, link: Link, settings: SettingsInput, *, device: str,
                 clock: Clock) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.settings: AK8963Settings
        self.regs = RegisterView(link)
        self.asa: tuple[int, int, int] = (128, 128, 128)
        self._cntl1 = r.cntl1_value(self.settings.odr_hz, self.settings.resolution_bits)
        # The one register that holds the configuration: continuous mode and resolution,
        # entered through power-down (the datasheet's mode-change rule, in configure()).
        self.plan = RegisterPlan(self.describe(), [
            RegisterSetting(r.REG_CNTL1, self._cntl1, name="CNTL1", wait_s=r.MODE_CHANGE_S)])
        self._period_ns = round(1e9 / self.settings.odr_hz)
        self._grid = self._poll_grid()
        self._search_ns: int | None = None
        """Read directly, the retry asked for after a poll that found no new field: a new
        field at it (not a late poll) locates the chip's instant."""
        self._idle_since: int | None = None
        """The stamp of the latest valid field while every read since found DRDY clear
        (None: a read since failed, was blank or frozen, or the chip was reconfigured): the
        chip made nothing since (``health.idle``). read: auto: the latest field's, its
        master's reads since counted by the feed (``Copy.quiet_ns``)."""
        self._ready = DataReady({Quantity.MAG: self._period_ns})
        self._watch = ResetWatch(self.settings.reset_check_s)
        self._frozen = FrozenWatch(self.FROZEN_AFTER_FRAMES)
        self.last: Measurement | None = None
        if self.settings.read == "auto":
            require_auto_read(link.bus, who=self.describe(), bus_name=link.bus.name,
                              example="the MPU-9250's imu/aux with aux: master",
                              fix="use read: one-shot or set the MPU's aux: master")
        self._feed: AutoReadFeed | None = None
        self._stamped_ns: int | None = None
        """read: auto: the stamp of the latest field from a copy (None after configure)."""
        self._on_delivery = False
        """read: auto: the latest field was stamped with its own copy's delivery (not placed
        on the chip's cadence, ``stamp_on_cadence``, which dates it as another slot's)."""
        self._asa_read: bytes | None = None
        """The fuse-ROM bytes as last taken (``_read_asa``)."""
        self._cntl1_written_ns = 0
        self._streams: tuple[StreamSpec, ...] = ()

    def _not_found(self, found: str, hint: str) -> DeviceNotFoundError:
        return DeviceNotFoundError(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            expected=f"WIA 0x{r.WIA:02X} at register 0x{r.REG_WIA:02X}", found=found, hint=hint)

    def probe(self) -> DeviceIdentity:
        try:
            wia = retried(partial(self.regs.read_u8, r.REG_WIA))
        except NackError as exc:
            raise self._not_found("no answer (NACK)", BEHIND_MPU_HINT) from exc
        if wia != r.WIA:
            hint = (BEHIND_MPU_HINT if wia in (0x00, 0xFF)
                    else "another chip or an AK8963 clone answers at this address")
            raise self._not_found(f"0x{wia:02X}", hint)
        self.identity = DeviceIdentity(self.name, self.link.bus.name, self.link.target,
                                       f"WIA=0x{wia:02X}")
        return self.identity

    def _set_mode(self, value: int) -> None:
        retried(partial(self.regs.write, r.REG_CNTL1, value))
        self.clock.sleep(r.MODE_CHANGE_S)

    def _read_asa(self) -> tuple[int, int, int]:
        """ASAX..ASAZ (fuse-ROM mode), checked: the adjustment scales every field the driver
        reports (ASA 0xFF: x1.5) and the bytes carry no check of their own, so a transfer a
        glitch garbled (through the MPU-9250's slave 4 a failed read hands back whatever DI
        holds; a floating line reads 0xFF, one held low 0x00) would give valid fields off
        by up to half their size until the next reconfiguration. A read is taken when no
        byte is 0x00 or 0xFF (the ends of the formula's range, x0.5 and x1.5; factory
        values lie near its middle) and it equals the part's earlier reads (a fuse does
        not change); otherwise it is read again, and taken only when both reads agree and
        are plausible, else a BusError (the recovery tries again). One read when all is
        well, so recordings replay with the transactions they hold."""
        asa = retried(partial(self.regs.read, r.REG_ASAX, 3))
        if _plausible_asa(asa) and asa == (self._asa_read or asa):
            self._asa_read = asa
            return asa[0], asa[1], asa[2]
        again = retried(partial(self.regs.read, r.REG_ASAX, 3))
        if again != asa or not _plausible_asa(asa):
            raise BusError(f"{self.describe()}: the fuse-ROM sensitivity adjustment read "
                           f"{asa.hex(' ')} then {again.hex(' ')}: a garbled transfer, "
                           "not taken")
        self._asa_read = asa
        return asa[0], asa[1], asa[2]

    def configure(self) -> None:
        self._idle_since = None
        # every transfer that fails is repeated in place (RegisterPlan.retried), so a
        # glitch does not start the soft reset and the fuse-ROM read over (issue 26)
        retried(partial(self.regs.write, r.REG_CNTL2, r.CNTL2_SRST))
        self.clock.sleep(r.RESET_S)
        # ASA is readable only in fuse-ROM mode; modes change only through power-down.
        self._set_mode(r.MODE_FUSE_ROM)
        self.asa = self._read_asa()
        self._set_mode(r.MODE_POWER_DOWN)
        self.plan.apply(self.regs, self.clock, attempts=IN_PLACE_ATTEMPTS)
        if self.settings.read == "auto":
            # measurements start here (read only when needed: a clock read is part of a
            # recording, and one-shot recordings must replay as they were made)
            self._cntl1_written_ns = self.clock.now_ns()
        back = self.plan.verify(self.regs, attempts=IN_PLACE_ATTEMPTS,
                                clock=self.clock)[r.REG_CNTL1]
        if self.settings.read == "auto":
            assert isinstance(self.link.bus, AutoReadBus)
            feed = self._feed = self.link.bus.auto_read(
                self.link.target, r.DATA_BURST_START, r.DATA_BURST_LENGTH)
            feed.keep_ready_only(0, r.ST1_DRDY)
            self._stamped_ns = None  # the stream restarts with a new phase
            # A copy from before this configuration is no measurement of it: writing CNTL1
            # cleared DRDY, so the next copy with DRDY differs from this one or is new.
            feed.take()
        # the rate read back sets the poll grid and the stale policy
        spec = self._spec(back)
        self._streams = (spec,)
        self._period_ns = spec.period_ns
        self._grid = self._poll_grid()
        self._search_ns = None
        self._ready = DataReady({Quantity.MAG: self._period_ns})

    def _poll_grid(self) -> PollGrid:
        if self.settings.read == "auto":
            return PollGrid(self._period_ns)
        return PollGrid(self._period_ns, early_fraction=EARLY_FRACTION, track=True,
                        catch_up=True, bounded=self.poll_plan >= CHIP_CLOCK_PLAN)

    def start(self, now_ns: int) -> int:
        # recover() passes the time from before configure() waited; never start in the past.
        now_ns = max(now_ns, self.clock.now_ns())
        self._ready.start(now_ns)
        self._watch.start(now_ns)
        if self._feed is not None:
            # Poll one delivery latency after each measurement instant (counted from the
            # CNTL1 write), when the master's copy has reached the host.
            self._grid.anchor(self._cntl1_written_ns + self._feed.latency_ns)
            return self._grid.next_after(now_ns)
        self._grid.anchor(now_ns)
        return now_ns + round(r.MEASUREMENT_S * 1e9)

    def _spec(self, cntl1: int) -> StreamSpec:
        """The field's spec from CNTL1 as read from the chip: MODE[3:0] (continuous mode 1
        or 2) gives the rate, BIT the resolution. Full scale: the measurement range,
        +-4912 uT per axis; scale: uT per count before the fuse-ROM adjustment (ASA, within
        0.5..1.5 of it per axis)."""
        period_s = r.MODE_PERIOD_S.get(cntl1 & r.MODE_MASK)
        if period_s is None:
            raise ConfigurationError(f"{self.describe()}: CNTL1 reads back 0x{cntl1:02X}, "
                                     "not a continuous mode; check the bus")
        bits = 16 if cntl1 & r.CNTL1_BIT else 14
        latency_s = (self._feed.latency_ns * 1e-9 if self._feed is not None
                     else r.MEASUREMENT_S)
        return StreamSpec(self.device, Quantity.MAG, Frame.SENSOR, 1.0 / period_s,
                          scale=r.RESOLUTIONS[bits].ut_per_lsb,
                          full_scale=r.OVERFLOW_SUM_UT, latency_s=latency_s)

    def streams(self) -> tuple[StreamSpec, ...]:
        """The magnetic field (uT, the AK8963's sensor frame) as read back at configure()."""
        return self._streams

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        self._streams = (self._spec(self.regs.read_u8(r.REG_CNTL1)),)
        return self._streams
    def resume(self, now_ns: int) -> int | None:
        """One transfer of a poll failed: when CNTL1 still reads back as written (a soft
        reset or power-on clears it), the chip kept measuring, so poll again at once instead
        of the full recovery (soft reset, fuse-ROM read and three mode changes: about 30 ms
        on the clock every device shares). A retry after a read that reached the chip finds
        DRDY clear (ST2 ended that read) and waits for the next measurement: one lost,
        none repeated."""
        self._idle_since = None  # a failed read may have cleared DRDY: no proof across it
        if self.asa is None or retried(partial(self.plan.lost, self.regs)):
            return None
        return max(now_ns, self.clock.now_ns())

    @property
    def polls_after_instants(self) -> bool:
        """Polled, its grid searches the chip's instants (EARLY_FRACTION)."""
        return self.settings.read != "auto"

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """One field per continuous-mode period (8 or 100 Hz)."""
        return Quantity.MAG, self._period_ns

    def full_scale(self, channel: Quantity) -> float | None:
        """The measurement range, +-4912 uT per axis."""
        return r.OVERFLOW_SUM_UT if channel is Quantity.MAG else None

    def _frozen_flag(self, frame: bytes) -> SampleFlag:
        return self._frozen.observe(Quantity.MAG, frame)

    def poll(self, now_ns: int) -> PollResult:
        # read: auto judges staleness on the master's time line (its latest delivery): a
        # master that delivers late (a FIFO read after a host stall) makes no stale field
        seen_ns = now_ns if self._feed is None else self._feed.t_ns
        overdue = self._ready.overdue(Quantity.MAG, seen_ns)
        if self._watch.check_due(now_ns, overdue=overdue) and self.plan.check_next(self.regs):
            return PollResult([], self.restart(reset_detected=True))
        if self._feed is not None:
            return self._poll_feed(now_ns, overdue)
        data = self.regs.read(r.DATA_BURST_START, r.DATA_BURST_LENGTH)
        # every read since the latest valid field was good and found DRDY clear, or this
        # is the read after it (``_idle_since``): a field with DOR clear is the next one
        sample, bad, ready = self._measurement(data, now_ns, now_ns, unbroken=True)
        if sample is None:
            self._saw_no_field(now_ns, ready or bool(bad))
            return self._no_measurement(now_ns, overdue or ready, bad, stale=not ready)
        self._idle_since = now_ns if sample.valid else None
        if self._search_ns is not None and now_ns - self._search_ns < self._grid.guard_ns:
            # new data appeared within a guard before now (EARLY_FRACTION): the chip's instant
            self._grid.locate(now_ns)
        self._search_ns = None
        return PollResult([sample], self._grid.next_after(now_ns))

    def _saw_no_field(self, now_ns: int, broken: bool) -> None:
        """Read directly, a good read brought no valid field: with DRDY clear (not
        ``broken``: not blank, frozen or flagged) and every read since the latest valid
        field alike, the chip has measured nothing since that field (``health.idle``, for
        the frame ledger's count of a hung chip's slots)."""
        if broken:
            self._idle_since = None
        elif self._idle_since is not None:
            self.health.idle = (self._idle_since, now_ns)

    def _poll_feed(self, now_ns: int, overdue: bool) -> PollResult:
        """read: auto: every new copy the master delivered since the last poll (several
        when it read them from its FIFO), each stamped with its copy's time."""
        assert self._feed is not None
        samples: list[MagSample] = []
        bad = SampleFlag.OK
        for copy in self._feed.take():
            if not copy.data[0] & r.ST1_DRDY:
                self._idle_since = None
                continue
            if not samples:
                self._copies_found_nothing(copy)
            t_ns = self._copy_stamp(copy)
            on_delivery = t_ns == copy.t_ns
            sample, flag, _ = self._measurement(
                copy.data, t_ns, t_ns,
                unbroken=on_delivery and self._on_delivery and self._unbroken(copy))
            if sample is not None:
                samples.append(sample)
                self._stamped_ns = t_ns
                self._on_delivery = on_delivery
            self._idle_since = t_ns if sample is not None and sample.valid else None
            bad |= flag
        if not samples:
            return self._no_measurement(now_ns, overdue or bool(bad), bad, stale=not bad)
        self._grid.anchor(now_ns)
        return PollResult(list(samples), self._grid.next_after(now_ns))

    def _copies_found_nothing(self, copy: Copy) -> None:
        """read: auto: slave 0's reads between the latest valid field's copy and ``copy``
        were good and found ST1.DRDY clear up to ``copy.quiet_ns`` (``Copy.quiet_ns``):
        the chip made nothing since that field, up to the earliest such a read can have
        been made (a delivery comes at most the feed's latency after the master's read),
        for the frame ledger's count of a hung chip's slots (``health.idle``). Only the
        first copy of a poll can report it: the ledger takes it before the poll's fields."""
        if self._idle_since is not None and copy.quiet_ns is not None:
            assert self._feed is not None
            until_ns = copy.quiet_ns - self._feed.latency_ns
            if until_ns > self._idle_since:
                self.health.idle = (self._idle_since, until_ns)

    def _unbroken(self, copy: Copy) -> bool:
        """read: auto: every read slave 0 made since the copy before ``copy`` was delivered,
        good and found ST1.DRDY clear, the latest of them the delivery just before it
        (``Copy.quiet_ns``: no pause, no failed read), so ``copy``'s ST1 follows the
        master's read before it as a direct read follows the read before. Only between
        fields stamped at their own copies (``_on_delivery``): a field placed on the cadence
        after failed reads stands for the slot before its copy, and the slots between its
        stamp and the next field's are not between the two reads."""
        assert self._feed is not None
        after = copy.after_ns
        return (copy.quiet_ns is not None and copy.quiet_ns == after and not copy.failed_ns
                and after is not None and copy.t_ns - after <= self._feed.latency_ns)

    def _copy_stamp(self, copy: Copy) -> int:
        """The time the master copied this measurement: its delivery, or on the chip's own
        cadence after failed master reads (SLV0_NACK) or a pause in the master's deliveries
        (``stamp_on_cadence``). A failed read moves the copy one MPU sample (5 ms at the
        boards' 200 Hz: half the 100 Hz field period) later, and a paused master (its
        recovery, blank reads) delivers a copy up to a field period old; stamped at the
        delivery, the frame ledger rounds the gap before it up to a field the chip never
        skipped and the one after down to none. The pause: a third more than the feed's
        latency (one MPU period and its poll guard) between two deliveries, one and a half
        MPU periods: more than the poll grid's search for a sample ever adds."""
        assert self._feed is not None
        # ST1.DOR: the chip measured twice since slave 0's last good read of it
        return stamp_on_cadence(copy, self._stamped_ns, self._period_ns,
                                pause_ns=self._feed.latency_ns * 4 // 3,
                                at_least=2 if copy.data[0] & r.ST1_DOR else 1)

    def _measurement(self, data: bytes, t_ns: int, poll_ns: int, *,
                     unbroken: bool = False) -> tuple[MagSample | None, SampleFlag, bool]:
        """An ST1..ST2 burst stamped ``t_ns``, found at the poll at ``poll_ns``: (the
        sample, or None; the flag of a bad frame; DRDY). ``unbroken``: the read before this
        one read the chip too, and was good (with ``_idle_since``: every read since the
        latest valid field was, each finding DRDY clear), so a valid field with DOR clear is
        the chip's next measurement after that field (``health.adjacent``): DOR is set by a
        measurement that overwrites one unread and cleared by every data read."""
        m = decode_burst(data, self.asa)
        bad = blank_flag(data)
        if m.data_ready and not bad:
            bad = self._frozen_flag(data[1:7])
        if not m.data_ready or bad:
            return None, bad, m.data_ready
        self._ready.fresh(Quantity.MAG, poll_ns)
        self._watch.fresh_poll()
        if m.data_overrun:  # a measurement overwritten unread: the ledger's proof of one
            self.health.overrun_ns = t_ns
            if self._feed is not None:
                # behind slave 0 too: a field lies between this one and the field before,
                # whatever the stamps say (a copy after failed slave reads stamped at its
                # delivery, 1.5 periods after a field whose copy lagged it by 6.8 ms)
                self.health.skipped_ns = t_ns
        flags = SampleFlag.OK
        if m.overflow:
            flags |= SampleFlag.OVERFLOW
        if m.saturated:
            flags |= SampleFlag.SATURATED
        if any(abs(c) > r.RESOLUTIONS[m.bits].max_count for c in m.counts):
            flags |= SampleFlag.OUT_OF_RANGE
        if flags == SampleFlag.OK:
            self.last = m
            if unbroken and self._idle_since is not None and not m.data_overrun:
                self.health.adjacent = (self._idle_since, t_ns)
        return MagSample(t_ns=t_ns, device=self.device, flags=flags, mag_ut=m.field_ut), \
            flags, True

    def _no_measurement(self, now_ns: int, overdue: bool, bad: SampleFlag, *,
                        stale: bool = True) -> PollResult:
        """No usable measurement: look again soon while one is not yet overdue, else a
        flagged NaN sample (STALE when nothing new came, ``bad`` when a frame was bad), and
        restart a chip that keeps producing nothing."""
        if not overdue:
            if self._feed is not None:
                # the copy may come one MPU burst late; look again when it can have come
                return PollResult([], now_ns + self._feed.latency_ns // 2)
            if bad:  # a blank read: the grid keeps the chip's phase for when data come back
                self._search_ns = None
                return PollResult([], self._grid.next_after(now_ns))
            self._search_ns = now_ns + self._grid.guard_ns
            return PollResult([], self._search_ns)
        flags = SampleFlag.STALE | bad if stale else bad
        sample = MagSample(t_ns=now_ns, device=self.device, flags=flags, mag_ut=NAN3)
        if self._watch.stale_poll():
            # CNTL1 intact but no new data: a reset and reconfiguration restarts measuring
            return PollResult([sample], self.restart(reset_detected=False))
        return PollResult([sample], self._grid.next_after(now_ns))
