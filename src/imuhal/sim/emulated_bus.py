"""An emulated bus: routes transactions to chip emulators by address or chip select."""

from __future__ import annotations

from typing import Protocol, TypeVar

from imuhal.bus.base import Bus, BusKind
from imuhal.core.errors import BusError, NackError


class BusTarget(Protocol):
    """What answers at one address or chip select: a ChipEmulator, or a line in front of
    one (imuhal.emulation.faults.FaultLine, the MPU-9250's bypass gate)."""

    @property
    def absent(self) -> bool: ...

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes: ...

    def idle_answer(self, kind: BusKind, write: bytes, read_len: int) -> bytes | None: ...


_T = TypeVar("_T", bound=BusTarget)


class _TimedChip(Protocol):
    master_instant_ns: int | None


def _chip_behind(target: object) -> _TimedChip | None:
    """The chip emulator answering at a bus target: the target itself, or the emulator
    behind a line in front of it (``.emulator``); None when it keeps no time of its own."""
    chip = getattr(target, "emulator", target)
    return chip if hasattr(chip, "master_instant_ns") else None


class EmulatedBus(Bus):
    """A bus whose far end is register-level chip emulators.

    Fault injection on a whole board goes through imuhal.emulation.faults (per device, in
    simulated time). For driver unit tests without a board, ``fail_transfers({n, ...})``
    makes the n-th transfer from now (1-based) raise a bus error.
    """

    def __init__(self, name: str, kind: BusKind) -> None:
        super().__init__(name)
        self.kind = kind
        self.targets: dict[int, BusTarget] = {}
        self._chips: dict[int, _TimedChip | None] = {}
        """``_chip_behind`` of each target, worked out when it is attached."""
        self._fail_at: set[int] = set()
        self._count = 0

    def attach(self, target: int, emulator: _T) -> _T:
        if target in self.targets:
            raise ValueError(f"{self.name}: target 0x{target:02X} already has an emulator")
        self.targets[target] = emulator
        self._chips[target] = _chip_behind(emulator)
        return emulator

    def fail_transfers(self, which: set[int]) -> None:
        """Make the given future transfers (1 = the next one) fail with a BusError."""
        self._fail_at |= {self._count + n for n in which}

    def transfer(self, target: int, write: bytes = b"", read_len: int = 0) -> bytes:
        """:meth:`Bus.transfer` and :meth:`_transfer` in one call (the same checks in the
        same order): every register access of an emulated board comes through here, about
        500 times per simulated second on the seed board. :meth:`_transfer` keeps the
        base class's path for the bus's other operations."""
        if type(write) is not bytes:  # a bytearray or memoryview: the callee gets a copy
            write = bytes(write)
        with self.lock:
            self.transfers += 1
            self._count += 1
            if self._fail_at and self._count in self._fail_at:
                self._fail_at.discard(self._count)
                raise BusError("injected transfer failure", bus=self.name, target=target)
            emulator = self.targets.get(target)
            if emulator is None or emulator.absent:
                what = "address" if self.kind is BusKind.I2C else "chip select"
                raise NackError(f"no device answered at {what} 0x{target:02X}",
                                bus=self.name, target=target)
            data = emulator.bus_transfer(self.kind, write, read_len)
        if len(data) != read_len:
            raise BusError(f"short read: {len(data)} of {read_len} bytes", bus=self.name,
                           target=target)
        return data

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        self._count += 1
        if self._fail_at and self._count in self._fail_at:
            self._fail_at.discard(self._count)
            raise BusError("injected transfer failure", bus=self.name, target=target)
        emulator = self.targets.get(target)
        if emulator is None or emulator.absent:
            what = "address" if self.kind is BusKind.I2C else "chip select"
            raise NackError(f"no device answered at {what} 0x{target:02X}", bus=self.name,
                            target=target)
        return emulator.bus_transfer(self.kind, write, read_len)

    def transfer_at(self, t_ns: int, target: int, write: bytes = b"",
                    read_len: int = 0) -> bytes:
        """:meth:`transfer` as a bus master on the board times it: the chip at ``target``
        (behind its fault line, if any) answers as at ``t_ns`` (``ChipEmulator.now_ns``),
        which may lie before the host's clock. For an emulated master (the MPU-9250's
        slave 0) catching up on samples measured while the host did not look."""
        line = self.targets.get(target)
        chip = self._chips.get(target)
        if chip is None:
            return self.transfer(target, write, read_len)
        chip.master_instant_ns = t_ns
        try:
            if read_len and not self._fail_at and not line.absent:  # type: ignore[union-attr]  # a chip answers there (_chip_behind)
                # A read that changes nothing in the chip (``ChipEmulator.idle_answer``,
                # through its line's faults): answered without the layers, counted.
                answer = line.idle_answer(self.kind, write, read_len)  # type: ignore[union-attr]  # as above
                if answer is not None:
                    with self.lock:
                        self.transfers += 1
                        self._count += 1
                    return answer
            return self.transfer(target, write, read_len)
        finally:
            chip.master_instant_ns = None

    def _receive(self, target: int, max_len: int) -> bytes:
        emulator = self.targets.get(target)
        if emulator is None or emulator.absent:
            return b""  # a silent UART: nothing arrives
        return emulator.bus_receive(self.kind, max_len)  # type: ignore[attr-defined]  # a serial bus's targets are chip emulators (ChipEmulator.bus_receive); BusTarget is the register-bus protocol

    def set_baudrate(self, baudrate: int) -> None:
        """The host UART's line speed: an emulated serial chip garbles what it sends when it
        differs from its own (as a real UART at the wrong speed reads noise)."""
        for emulator in self.targets.values():
            emulator.host_baudrate = baudrate  # type: ignore[attr-defined]  # a serial bus's targets are chip emulators (ChipEmulator.host_baudrate); BusTarget is the register-bus protocol
