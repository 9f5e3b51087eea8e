"""Fault injection for emulated boards: the documented interface (docs/reliability.md).

Faults are typed specs (imuhal.profile.faults, re-exported here), each naming a device, a
start and an end time in simulated seconds. A profile lists them under ``emulation: faults``;
Python code passes them to ``imuhal.emulation.open_emulated(..., faults=[...])`` or adds
them to a running board with ``pipeline.board.faults.add(spec)``.

Three places act on them, each at the level where the fault happens on real hardware:

- the **bus line** of the device (``FaultLine``, standing between the bus and the chip
  emulator): transient bus errors, OSError, all-0xFF / all-0x00 reads, an unplugged chip;
- the **chip** (the ChipEmulator fault hook): reset, stuck data-ready, frozen data,
  corrupted PROM/trimming, a navigation receiver's stale solution;
- the **world** the chip measures and the **host's timing** (``BoardFaults.physics`` and
  ``BoardFaults.before_poll``, called by the emulated board before each poll): a wild value,
  a wrong but in-range pressure, late polls and jitter.

Every random draw comes from a generator seeded by the run seed, the fault's index and its
device, so a run is reproducible and adding a fault does not change the others' draws.
"""

from __future__ import annotations

import errno
import random
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, NackError
from imuhal.profile.faults import (
    CHIP_FAULT_KINDS,
    AllOnes,
    AllZeros,
    BusErrors,
    BusOSError,
    ChipAbsent,
    ChipReset,
    CorruptByte,
    CorruptTrim,
    FaultSpec,
    FrozenData,
    HostStall,
    LatePolls,
    StaleNavigation,
    StuckDataReady,
    TimingJitter,
    WildValue,
    WrongPressure,
)
from imuhal.sim.chip import ChipEmulator
from imuhal.sim.inputs import PhysicalInputs

if TYPE_CHECKING:
    from imuhal.sim.emulated_bus import EmulatedBus

__all__ = [
    "AllOnes", "AllZeros", "BoardFaults", "BusErrors", "BusOSError", "ChipAbsent", "ChipReset",
    "CorruptByte", "CorruptTrim", "FaultLine", "FaultSpec", "FrozenData", "HostStall",
    "LatePolls", "StaleNavigation",
    "StuckDataReady", "TimingJitter", "WildValue", "WrongPressure",
]

_LINE_KINDS = (BusErrors, BusOSError, AllOnes, AllZeros, ChipAbsent)
_TIMING_KINDS = (LatePolls, TimingJitter)
_VALUE_KINDS = (WildValue, WrongPressure)
_PHYSICS_FIELD = {
    "accel": "specific_force_m_s2",
    "gyro": "angular_rate_rad_s",
    "mag": "magnetic_field_ut",
    "pressure": "pressure_pa",
    "temperature": "temperature_degc",
}


@dataclass
class _Active:
    """One fault of a board and its progress."""

    spec: FaultSpec
    rng: random.Random
    started: bool = False
    ended: bool = False
    uses: int = 0
    """Value faults: polls whose physics carried the wrong value."""
    first_s: float | None = None
    """Value faults without end_s: the first poll at or after start_s."""
    bytes_seen: int = 0
    """corrupt_byte: bytes received since start_s."""
    next_s: float | None = None
    """host_stall: when the next stall is due."""


@dataclass
class FaultLog:
    """What the injected faults did, for tests and the soak report."""

    events: list[str] = field(default_factory=list)
    injected: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per device and fault kind: transfers failed or altered, polls delayed, values
    replaced, chip events."""

    def count(self, device: str, kind: str) -> None:
        per_device = self.injected.setdefault(device, {})
        per_device[kind] = per_device.get(kind, 0) + 1

    def total(self, kind: str) -> int:
        return sum(d.get(kind, 0) for d in self.injected.values())


class BoardFaults:
    """The faults of one emulated board, on the board's simulated clock."""

    def __init__(self, clock: Clock, emulators: dict[str, ChipEmulator], *,
                 seed: int = 0, faults: Iterable[FaultSpec] = ()) -> None:
        self.clock = clock
        self.emulators = emulators
        self.seed = seed
        self.log = FaultLog()
        self._faults: list[_Active] = []
        self._by_device: dict[str, list[_Active]] = {}
        for spec in faults:
            self.add(spec)

    @property
    def specs(self) -> list[FaultSpec]:
        return [a.spec for a in self._faults]

    def add(self, spec: FaultSpec) -> None:
        """Schedule one more fault (times are absolute simulated seconds)."""
        index = len(self._faults)
        where = f"fault {index} ({spec.kind} on {spec.device!r})"
        emulator = self.emulators.get(spec.device)
        if emulator is None:
            raise ConfigurationError(f"{where}: no emulated device {spec.device!r}; devices: "
                                     f"{', '.join(self.emulators) or 'none'}")
        if spec.kind in CHIP_FAULT_KINDS and spec.kind not in emulator.chip_faults():
            raise ConfigurationError(
                f"{where}: the {emulator.chip or type(emulator).__name__} emulator does not "
                f"model it; it models: {', '.join(sorted(emulator.chip_faults()))}")
        if isinstance(spec, CorruptByte) and \
                type(emulator).bus_receive is ChipEmulator.bus_receive:
            raise ConfigurationError(f"{where}: corrupt_byte acts on a serial line; the "
                                     f"{emulator.chip or type(emulator).__name__} emulator is "
                                     "not a byte-stream chip (use bus_errors)")
        active = _Active(spec, random.Random(f"{self.seed}/{index}/{spec.device}"))
        self._faults.append(active)
        self._by_device.setdefault(spec.device, []).append(active)

    def has_faults(self, device: str) -> bool:
        """Whether any fault is scheduled on ``device`` (past, in force or to come)."""
        return bool(self._by_device.get(device))

    def line(self, device: str, emulator: ChipEmulator, bus: EmulatedBus,
             target: int) -> FaultLine:
        """The bus line to ``device``: what its bus attaches instead of the bare emulator."""
        return FaultLine(self, device, emulator, bus, target)

    # -- the chip: events at start_s / end_s --------------------------------------------

    def sync(self, now_ns: int | None = None) -> None:
        """Start and end the chip-level faults that are due by ``now_ns`` (default: now)."""
        t_s = (self.clock.now_ns() if now_ns is None else now_ns) / 1e9
        for a in self._faults:
            if a.ended:
                continue
            spec = a.spec
            if not a.started and t_s >= spec.start_s:
                a.started = True
                self._start(a)
            if a.started and spec.end_s is not None and t_s >= spec.end_s:
                a.ended = True
                self._end(a)
            elif a.started and spec.instantaneous:
                a.ended = True

    def _start(self, a: _Active) -> None:
        spec, emu = a.spec, self.emulators[a.spec.device]
        if isinstance(spec, ChipReset):
            emu.silent_reset()
            self._note(spec, "chip reset")
        elif isinstance(spec, StuckDataReady):
            _hang_from(emu, spec.start_s)
            self._note(spec, "data-ready stuck")
        elif isinstance(spec, FrozenData):
            emu.frozen = True
            self._note(spec, "conversions frozen")
        elif isinstance(spec, CorruptTrim):
            self._note(spec, f"corrupted {emu.corrupt_trim(a.rng, spec.bits)}")
        elif isinstance(spec, StaleNavigation):
            emu.stale_solution(spec.time)
            self._note(spec, f"stale navigation ({spec.time} time)")
        elif isinstance(spec, ChipAbsent):
            self._note(spec, "unplugged")

    def _end(self, a: _Active) -> None:
        spec, emu = a.spec, self.emulators[a.spec.device]
        if isinstance(spec, StuckDataReady):
            # it ends at the chip's next access (a chip wedged until the host touches it):
            # ended at end_s, a chip that resumed unread overwrote several measurements,
            # which its one overrun bit (the AK8963's DOR) cannot count
            emu.stuck_data_ready = False
        elif isinstance(spec, FrozenData):
            emu.frozen = False
        elif isinstance(spec, StaleNavigation):
            emu.stale_solution(None)
        elif isinstance(spec, ChipAbsent):
            # Plugged back in: the chip powers up in its reset state.
            if "reset" in emu.chip_faults():
                emu.silent_reset()
            self._note(spec, "plugged back in")

    def _note(self, spec: FaultSpec, what: str) -> None:
        self.log.events.append(f"t={self.clock.now_ns() / 1e9:.3f} s {spec.device}: {what}")
        self.log.count(spec.device, spec.kind)

    # -- the host's timing and the world, before each poll ------------------------------

    def before_poll(self, device: str, t_ns: int) -> int:
        """Called when ``device`` is due at ``t_ns``: start/end due faults, then delay the
        poll as late-poll and jitter faults say. Returns the time the poll happens."""
        if not self._faults:  # a board without faults: nothing to start, nothing delays
            return t_ns
        self.sync(t_ns)
        delay_s = 0.0
        t_s = t_ns / 1e9
        for a in self._by_device.get(device, ()):
            spec = a.spec
            if isinstance(spec, _TIMING_KINDS) and spec.active(t_s):
                delay_s += spec.delay_s if isinstance(spec, LatePolls) \
                    else a.rng.uniform(0.0, spec.max_delay_s)
                self.log.count(spec.device, spec.kind)
            elif isinstance(spec, HostStall) and spec.active(t_s):
                delay_s += self._stalls_due(a, spec, t_s)
        if not delay_s:
            return t_ns
        late_ns = t_ns + round(delay_s * 1e9)
        self.clock.sleep_until(late_ns)
        self.sync()
        return late_ns

    def _stalls_due(self, a: _Active, spec: HostStall, t_s: float) -> float:
        """host_stall: the stall time (s) due by ``t_s``; one stall per poll at most (a
        stall that falls due during another starts when the host resumes)."""
        if a.next_s is None:
            a.next_s = spec.start_s if spec.every_s is not None else \
                spec.start_s + a.rng.expovariate(spec.rate_hz or 1.0)
        if t_s < a.next_s:
            return 0.0
        gap = spec.every_s if spec.every_s is not None else \
            a.rng.expovariate(spec.rate_hz or 1.0)
        a.next_s = max(a.next_s + gap, t_s + spec.stall_s)
        self.log.count(spec.device, spec.kind)
        return spec.stall_s

    def physics(self, device: str, t_ns: int, inputs: PhysicalInputs) -> PhysicalInputs:
        """What ``device`` measures at ``t_ns``: the truth, unless a value fault replaces it.
        A value fault without ``end_s`` holds for its ``hold_s`` from the first poll at or
        after ``start_s`` (about one measurement of the chip)."""
        faults = self._by_device.get(device)
        if not faults:
            return inputs
        t_s = t_ns / 1e9
        for a in faults:
            spec = a.spec
            if not isinstance(spec, _VALUE_KINDS) or t_s < spec.start_s:
                continue
            if spec.end_s is None:
                if a.first_s is None:
                    a.first_s = t_s
                    self._note(spec, spec.kind)
                if t_s >= a.first_s + spec.hold_s:
                    continue
            elif t_s >= spec.end_s:
                continue
            inputs = _replace_value(inputs, spec)
            a.uses += 1
        return inputs

    # -- the bus line ---------------------------------------------------------------------

    def line_faults(self, device: str, t_s: float) -> Sequence[_Active]:
        return [a for a in self._by_device.get(device, ())
                if isinstance(a.spec, _LINE_KINDS) and a.spec.active(t_s)]


def _replace_value(inputs: PhysicalInputs, spec: WildValue | WrongPressure) -> PhysicalInputs:
    if isinstance(spec, WrongPressure):
        true = inputs.pressure_pa if inputs.pressure_pa is not None else 101325.0
        return replace(inputs, pressure_pa=true + spec.offset_pa)
    name = _PHYSICS_FIELD[spec.channel]
    current = getattr(inputs, name)
    if spec.channel in ("pressure", "temperature"):
        return replace(inputs, **{name: spec.value})  # type: ignore[arg-type]  # name is the PhysicalInputs field of the channel (_PHYSICS_FIELD)
    vector = list(current) if current is not None else [0.0, 0.0, 0.0]
    vector[spec.axis] = spec.value
    return replace(inputs, **{name: (vector[0], vector[1], vector[2])})  # type: ignore[arg-type]  # name is the PhysicalInputs field of the channel (_PHYSICS_FIELD)


class FaultLine:
    """The wire between a bus and one chip emulator, where bus-level faults happen.

    Attached to the EmulatedBus in place of the emulator; with no fault in force it hands
    every transaction straight through.
    """

    def __init__(self, faults: BoardFaults, device: str, emulator: ChipEmulator,
                 bus: EmulatedBus, target: int) -> None:
        self.faults = faults
        self.device = device
        self.emulator = emulator
        self.bus = bus
        self.target = target
        self._last_receive_ns: int | None = None
        """When the host last read a byte stream from this line (for a break's bytes)."""
        self.writes = 0
        """Write-only transactions (``read_len`` 0) sent down this line, failed ones
        included: a chip's configuration changes only through them, so the emulated board
        keeps what it asked the emulator about its configuration until this count moves."""

    @property
    def absent(self) -> bool:
        return self.emulator.absent

    @property
    def host_baudrate(self) -> int:
        return self.emulator.host_baudrate

    @host_baudrate.setter
    def host_baudrate(self, baudrate: int) -> None:
        self.emulator.host_baudrate = baudrate

    def bus_receive(self, kind: BusKind, max_len: int) -> bytes:
        """What a byte-stream chip (a UART) sent that reaches the host, through the line's
        faults: ``absent`` and ``all_ones`` (RX idle high) deliver nothing, ``all_zeros`` (RX
        held low: a break) delivers 0x00 bytes at the host's line rate, ``os_error`` raises
        ``OSError`` from the port, and ``bus_errors`` corrupts (one bit flipped) or loses each
        byte with probability ``rate``, as noise on a serial line does: a UART reports
        nothing, the sentence or frame checksums must catch it. What the chip sent while
        nothing reached the host is lost, as on a real line."""
        faults = self.faults
        if not faults._by_device.get(self.device):
            return self.emulator.bus_receive(kind, max_len)
        faults.sync()
        now_ns = faults.clock.now_ns()
        since_ns, self._last_receive_ns = self._last_receive_ns, now_ns
        active = faults.line_faults(self.device, now_ns / 1e9)
        for a in active:
            spec = a.spec
            if isinstance(spec, BusOSError) and a.rng.random() < spec.rate:
                faults.log.count(self.device, spec.kind)
                raise OSError(errno.EIO, f"{self.bus.name}: injected I/O error")
        data = self.emulator.bus_receive(kind, max_len)
        for a in active:
            spec = a.spec
            if isinstance(spec, ChipAbsent | AllOnes):
                faults.log.count(self.device, spec.kind)
                return b""
            if isinstance(spec, AllZeros):
                faults.log.count(self.device, spec.kind)
                baud = self.emulator.host_baudrate
                n = (now_ns - since_ns) * baud // 10_000_000_000 if since_ns is not None else 0
                return bytes(min(max(n, 0), max_len))
        for a in active:
            if isinstance(a.spec, BusErrors) and data:
                data = self._noisy(data, a)
        for a in faults._by_device[self.device]:
            if isinstance(a.spec, CorruptByte) and data and a.started:
                data = self._upset(data, a)
        return data

    def _upset(self, data: bytes, a: _Active) -> bytes:
        """``corrupt_byte``: flip the mask's bits in its byte, when it is in ``data``."""
        assert isinstance(a.spec, CorruptByte)
        at = a.spec.byte - a.bytes_seen
        a.bytes_seen += len(data)
        if not 0 <= at < len(data):
            return data
        self.faults.log.count(self.device, a.spec.kind)
        out = bytearray(data)
        out[at] ^= a.spec.mask
        return bytes(out)

    def _noisy(self, data: bytes, a: _Active) -> bytes:
        """Each byte, with probability ``rate``: one bit flipped or (as often) lost."""
        assert isinstance(a.spec, BusErrors)
        rate, rng = a.spec.rate, a.rng
        out = bytearray()
        for byte in data:
            if rng.random() >= rate:
                out.append(byte)
                continue
            self.faults.log.count(self.device, a.spec.kind)
            if rng.random() < 0.5:
                out.append(byte ^ (1 << rng.randrange(8)))
        return bytes(out)

    def idle_answer(self, kind: BusKind, write: bytes, read_len: int) -> bytes | None:
        """The chip's ``idle_answer`` while no fault is scheduled on the line (a fault in
        force may act on any transaction, and draws its odds per transaction: those are
        carried out); never for a write (``writes`` counts them)."""
        if not read_len or self.faults._by_device.get(self.device):  # has_faults, inline
            return None
        return self.emulator.idle_answer(kind, write, read_len)

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if not read_len:
            self.writes += 1
        faults = self.faults
        if not faults._by_device.get(self.device):
            return self.emulator.bus_transfer(kind, write, read_len)
        faults.sync()
        active = faults.line_faults(self.device, faults.clock.now_ns() / 1e9)
        fill: int | None = None
        target = self.target
        for a in active:
            spec = a.spec
            if isinstance(spec, ChipAbsent) and kind is BusKind.SERIAL:
                # A UART has no acknowledge: what is written to an unplugged chip is lost.
                faults.log.count(self.device, spec.kind)
                return bytes(read_len)
            if isinstance(spec, ChipAbsent):
                faults.log.count(self.device, spec.kind)
                what = "address" if kind is BusKind.I2C else "chip select"
                raise NackError(f"no device answered at {what} 0x{target:02X} (unplugged)",
                                bus=self.bus.name, target=target)
            if isinstance(spec, BusErrors) and a.rng.random() < spec.rate:
                faults.log.count(self.device, spec.kind)
                raise BusError("injected transient bus error", bus=self.bus.name,
                               target=target)
            if isinstance(spec, BusOSError) and a.rng.random() < spec.rate:
                faults.log.count(self.device, spec.kind)
                raise OSError(errno.EIO, f"{self.bus.name} 0x{target:02X}: injected I/O error")
            if isinstance(spec, AllOnes):
                fill = 0xFF
            elif isinstance(spec, AllZeros):
                fill = 0x00
        data = self.emulator.bus_transfer(kind, write, read_len)
        if fill is not None and read_len:
            faults.log.count(self.device, "all_ones" if fill else "all_zeros")
            return bytes([fill]) * read_len
        return data


def _hang_from(emu: ChipEmulator, start_s: float) -> None:
    """``stuck_data_ready`` set as at ``start_s``, not at the chip's next access, where
    ``FaultSet.sync`` notices it: an emulator that brings its measurements up to date when
    it hangs (``HangsBetweenTransfers``: the AK8963, HMC5883L, BMP280) completes what fell
    due before the hang began and nothing after. Noticed at a poll 2.7 ms after its
    measurement was due and 0.3 ms after the hang began, the gy91 BMP280 had skipped that
    measurement, and the poll handed out the one before again as new (the fault matrix's
    ``reset + stuck_data_ready + frozen`` at 0.1 %: 498 frames for the chip's 497)."""
    saved = emu.master_instant_ns
    start_ns = round(start_s * 1e9)
    emu.master_instant_ns = start_ns if saved is None else min(saved, start_ns)
    try:
        emu.stuck_data_ready = True
    finally:
        emu.master_instant_ns = saved
