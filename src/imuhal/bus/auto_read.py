"""Slave auto-read: a bus master that reads a slave's data registers on its own.

Some chips with an I2C master copy a slave's data registers into their own at every
measurement (the MAX21100's MAG_SLV_* registers, the MPU-9250's I2C_SLV0 into EXT_SENS_DATA),
so the host gets the slave's bytes in the burst it reads from the master anyway, without one
transaction per slave byte. The parts:

- the **master's bus** (``child_buses()`` of the master's driver) offers
  :meth:`AutoReadBus.auto_read` (address, first register, length) and declares the feature
  ``AUTO_READ`` for that bus in ``Driver.child_bus_features``, so a profile is checked
  before anything is opened;
- the **master's driver** programs its chip and, after each burst, hands the slave's bytes
  to the :class:`AutoReadFeed` (``deliver``);
- the **slave's driver** reads ``feed.data`` at its own polls and converts the bytes as it
  would after reading them itself (its gain, byte and axis order, overflow values). Whether
  a measurement is new is its decision: a master copies the registers whether or not the
  slave measured again, and a slave whose transaction failed leaves the master's copy as it
  was (real I2C masters keep the last data), so the same bytes can arrive many times.

Nothing here knows a chip.
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple, Protocol, runtime_checkable

from imuhal.core.errors import ConfigurationError

FRESH_KEPT = 64
"""Changes a feed keeps for its slave's driver (more than a FIFO of copies holds)."""
AUTO_READ = "auto_read"
"""The feature name a driver lists in ``child_bus_features`` for a bus whose master can
auto-read a slave (see :class:`AutoReadBus`)."""


class Copy(NamedTuple):
    """One change of a feed's ``data``: a copy the master's read brought."""

    t_ns: int
    """When the master's driver delivered it (ns, the driver clock)."""
    data: bytes
    failed_ns: tuple[int, ...] = ()
    """The deliveries just before it whose master read of the slave failed, as the master
    reported (the MPU-9250's SLV0_NACK), oldest first: the slave's measurement may have
    been there to copy at any of them. Empty for a master that reports no failures."""
    after_ns: int | None = None
    """The delivery before it (None: the first). Longer than the master's period before
    it, the master's driver was not reading (its chip recovering, blank reads, a stalled
    host), and the copy may hold a measurement up to one slave period older than usual."""
    quiet_ns: int | None = None
    """The latest delivery before it of an unbroken run of good ones since the change
    before it, each with the slave's data-ready bit clear (``keep_ready_only``) and each
    within the feed's latency of the delivery before it (so no master read came between
    unseen): the slave had measured nothing new at any of the master's reads (None: no
    such run, a failed read or a longer pause broke it, or the feed knows no data-ready
    bit)."""


def stamp_on_cadence(copy: Copy, last_ns: int | None, period_ns: int, *,
                     pause_ns: int, at_least: int = 1) -> int:
    """When a slave's measurement in ``copy`` was copied, for a slave driver that stamps
    each copy with its master's delivery, its previous field stamped ``last_ns`` and its
    measurements ``period_ns`` apart. Usually the delivery (``copy.t_ns``); two cases put
    it earlier, on the slave's own cadence (whole periods after ``last_ns``), as a
    driver that knows its chip's period stamps a FIFO frame (Linux
    inv_sensors_timestamp):

    - the master did not deliver for longer than ``pause_ns`` (its period) before it
      (``after_ns``, a failed delivery included): the copy may have waited a slave period
      in the chip; the latest cadence point not after the delivery, when one lies after
      ``last_ns`` (within 0.9 period of it, ``last_ns`` was a late poll's stamp, a new
      measurement cannot be on that cadence, and the delivery dates it);
    - else, the master's reads just before it failed (``failed_ns``): a failed read moved
      the copy a master period later; the read nearest the cadence is where it was due.

    Either way the stamp stays after ``last_ns`` and the delivery before it, and never
    after the delivery. A slave clock that drifted more than a tenth of a period since
    ``last_ns`` is stamped a period off: the cadence is only good over short gaps.

    ``at_least``: the slave's own status proves the measurement ``at_least`` periods after
    the one stamped ``last_ns`` (the AK8963's ST1.DOR: a measurement overwritten unread
    since the master's last good read, so two); no cadence point nearer is taken. Taking
    the failed read one period on, nearest its cadence, put a copy with DOR 3 ms before
    its own measurement, where the chip had measured twice."""
    t_ns = copy.t_ns
    if last_ns is None:
        return t_ns
    after = copy.after_ns
    periods = int((t_ns - last_ns) / period_ns + 0.1)
    if after is not None and t_ns - after > pause_ns and periods:
        periods = max(periods, at_least)
        # a pause after the failed reads too: the copy may have waited in the chip since
        return min(t_ns, max(last_ns + periods * period_ns, after + 1, last_ns + 1))
    if copy.failed_ns:
        def off_cadence(t: int) -> int:
            periods = max(at_least, round((t - last_ns) / period_ns))
            return abs(t - last_ns - periods * period_ns)
        return min((*copy.failed_ns, t_ns), key=off_cadence)
    return t_ns


class AutoReadFeed:
    """The bytes a master last read from one slave on its own, as its driver delivered them.

    ``data`` is None until the first delivery. ``changed_ns`` is the delivery at which
    ``data`` last changed: the slave's measurement behind it was made at most ``latency_ns``
    before that (what the master's driver promises: its copy period plus how late after a
    copy its burst comes).
    """

    __slots__ = ("_failed", "_quiet", "_quiet_ns", "_raw", "changed_ns", "copied_ns", "data",
                 "deliveries", "failures", "fresh", "latency_ns", "length", "next_ns",
                 "period_ns", "ready_bit", "register", "t_ns",
                 "target")

    def __init__(self, target: int, register: int, length: int, *, latency_ns: int) -> None:
        self.target = target
        self.register = register
        self.length = length
        self.latency_ns = latency_ns
        self.data: bytes | None = None
        self.t_ns = 0
        """Time of the latest delivery (ns, the driver clock)."""
        self.copied_ns = 0
        """Time of the latest delivery whose master may have copied the slave since the
        delivery before (ns, the driver clock): ``t_ns`` but for deliveries whose master
        said its own chip measured nothing since its previous read (``deliver(
        master_fresh=False)``: the MAX21100's accelerometer data-ready clear), which
        brought the copy of before again and tell nothing of the slave's instants since."""
        self.changed_ns = 0
        self.next_ns = 0
        """When the master's driver means to deliver next (ns, the driver clock; 0: it does
        not say): a master that reads the slave's copy less often than every slave
        measurement (a FIFO read every n frames) says so, and a slave driver then looks
        no sooner (imuhal.core.poll_plan, plan 2)."""
        self.period_ns = 0
        """How far apart the master's driver delivers while it reads on its own grid (ns;
        0: it does not say): a slave driver that waits for the first copy made after a
        given time looks one delivery after it, not a whole latency."""
        self.deliveries = 0
        self._raw: bytes | None = None
        """The bytes of the previous delivery, as read."""
        self.fresh: deque[Copy] = deque(maxlen=FRESH_KEPT)
        """Each change of ``data`` not yet taken (:meth:`take`): every measurement of a
        slave whose master's copies came in a burst (a FIFO), each at its own copy's
        time."""
        self.failures = 0
        """Deliveries whose master read of the slave failed (``deliver(failed=True)``)."""
        self._failed: list[int] = []
        """The failed deliveries since the latest good one."""
        self.ready_bit: tuple[int, int] | None = None
        """(byte offset, mask) of the slave's own data-ready bit among the bytes, when its
        driver set one with :meth:`keep_ready_only`."""
        self._quiet = True
        """Every delivery since the latest change was good and had the data-ready bit
        clear (a failed read, or a copy with data-ready repeating the one before, ends
        it)."""
        self._quiet_ns: int | None = None
        """The latest of those deliveries (``Copy.quiet_ns``)."""

    def keep_ready_only(self, offset: int, mask: int) -> None:
        """The slave has a data-ready bit among the bytes (byte ``offset``, bit ``mask``),
        cleared when the master reads the data: a delivery without it says only "no new
        measurement since the last read" and leaves ``data`` as it was, so a slave driver
        polling slower than the master reads still finds the measurement."""
        if not 0 <= offset < self.length:
            raise ValueError(f"data-ready byte {offset} is outside the {self.length} bytes read")
        self.ready_bit = (offset, mask)

    def deliver(self, t_ns: int, data: bytes, *, failed: bool = False,
                nack_seen: bool = False, master_fresh: bool | None = None) -> None:
        """The master's driver read ``data`` (``length`` bytes, slave register order) at
        ``t_ns``: one delivery per read the master made of the slave (a master that may not
        have read it again since the last delivery is not delivered from). ``failed``: the
        master reported that its read of the slave for this copy failed (its registers keep
        the copy before): no change, and the next change may carry the measurement that
        read missed (``Copy.failed_ns``).

        ``nack_seen``: the master reported a failed slave read among several copies without
        saying which (the MPU-9250's SLV0_NACK over a FIFO read of many frames): a copy
        that repeats the one before byte for byte may be it (a failed read leaves the copy
        before) and is taken as ``failed``. One that is not (the slave had nothing new,
        its data-ready bit read clear twice) costs nothing: a slave driver places the next
        change at the failed delivery nearest its own cadence or at its own delivery
        (``stamp_on_cadence``), and a delivery on its cadence is nearest.

        ``master_fresh``: whether the master's own chip measured since the master's
        driver last read it whole, where its copies of the slave follow its measurements
        (the MAX21100 copies at each accelerometer measurement): False, the master made no
        copy since (a hung master whose driver still reads its registers), and the bytes
        are the copy of before, whatever the slave did meanwhile (``copied_ns`` stays);
        None, the master does not say (or cannot: a read between them failed and may have
        cleared its data-ready bits). Neither changes ``data``: a slave driver's proof
        that its chip measured the same bytes again needs a copy the master made after the
        chip's next instant (imuhal_chips.hmc5883l)."""
        if master_fresh is not False:
            self.copied_ns = t_ns
        after_ns = self.t_ns if self.deliveries else None
        if nack_seen and not failed and data == self._raw:
            failed = True
        if failed:
            self.failures += 1
            self._failed.append(t_ns)
            self._quiet, self._quiet_ns = False, None
            self.t_ns = t_ns
            self.deliveries += 1
            return
        failed_ns, self._failed = tuple(self._failed), []
        # the master may have read the slave since the last delivery unseen (a host stall,
        # a poll put off), and such a read may have found new data: no read found nothing
        # across this pause (a change after it still carries the run before it)
        paused = bool(self.deliveries) and t_ns - self.t_ns > self.latency_ns
        ready = self.ready_bit
        raw, self._raw = self._raw, data
        quiet = False
        if ready is not None:
            if not data[ready[0]] & ready[1]:
                quiet = self._quiet  # a good read that found nothing new
                data = self.data if self.data is not None else data
            elif data != raw:
                # a copy with data-ready that differs from the copy before it is a new
                # measurement even when its bytes equal the last one's (a copy without
                # data-ready came between); a failed master read repeats the copy before
                self.data = None
        if data != self.data:
            self.data = data
            self.changed_ns = t_ns
            self.fresh.append(Copy(t_ns, data, failed_ns, after_ns, self._quiet_ns))
            self._quiet, self._quiet_ns = True, None
        elif quiet and not paused:
            self._quiet_ns = t_ns
        else:
            self._quiet, self._quiet_ns = False, None
        self.t_ns = t_ns
        self.deliveries += 1

    def take(self) -> list[Copy]:
        """The changes of ``data`` since the last take, oldest first."""
        out = list(self.fresh)
        self.fresh.clear()
        return out


def same_feed(feed: AutoReadFeed | None, target: int, register: int, length: int, *,
              where: str) -> AutoReadFeed | None:
    """For a master that auto-reads one slave: ``feed`` when it is already this read, None
    when there is none yet, else a ConfigurationError (``where`` names the master and
    slave) that tells the user to read the other chip with one-shot transactions."""
    if feed is None:
        return None
    if (feed.target, feed.register, feed.length) == (target, register, length):
        return feed
    raise ConfigurationError(
        f"{where}: the master already auto-reads 0x{feed.target:02X} and reads one "
        "slave; put the other chip on one-shot reads (read: one-shot)")


@runtime_checkable
class AutoReadBus(Protocol):
    """A bus whose master can read a slave's registers on its own."""

    def auto_read(self, target: int, register: int, length: int) -> AutoReadFeed:
        """Have the master read ``length`` bytes from ``register`` of the slave at 7-bit
        address ``target`` at every measurement; returns the feed its driver fills. Asking
        again for the same read returns the same feed; a ConfigurationError names what the
        master cannot do (another slave already auto-read, a length it cannot hold)."""
        ...


def require_auto_read(bus: object, *, who: str, bus_name: str, example: str,
                      fix: str) -> None:
    """A slave driver set to ``read: auto``: a ConfigurationError unless ``bus`` is an
    :class:`AutoReadBus` (``who`` names the driver, ``example`` a bus that can, ``fix`` what
    the user does instead). Profiles are checked earlier through ``AUTO_READ``; this covers
    a driver built directly."""
    if not isinstance(bus, AutoReadBus):
        raise ConfigurationError(
            f"{who}: read: auto needs a bus whose master reads the chip on its own "
            f"({example}); {bus_name} cannot: {fix}")
