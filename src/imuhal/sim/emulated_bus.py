"""An emulated bus: routes transactions to chip emulators by address or chip select."""

from __future__ import annotations

from imuhal.bus.base import Bus, BusKind
from imuhal.core.errors import BusError, NackError
from imuhal.sim.chip import ChipEmulator


class EmulatedBus(Bus):
    """A bus whose far end is register-level chip emulators.

    Fault injection: ``fail_transfers({n, ...})`` makes the n-th transfer from now (1-based)
    raise a bus error, as a glitch on real wiring would.
    """

    def __init__(self, name: str, kind: BusKind) -> None:
        super().__init__(name)
        self.kind = kind
        self.targets: dict[int, ChipEmulator] = {}
        self._fail_at: set[int] = set()
        self._count = 0

    def attach(self, target: int, emulator: ChipEmulator) -> ChipEmulator:
        if target in self.targets:
            raise ValueError(f"{self.name}: target 0x{target:02X} already has an emulator")
        self.targets[target] = emulator
        return emulator

    def fail_transfers(self, which: set[int]) -> None:
        """Make the given future transfers (1 = the next one) fail with a BusError."""
        self._fail_at |= {self._count + n for n in which}

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        self._count += 1
        if self._count in self._fail_at:
            self._fail_at.discard(self._count)
            raise BusError("injected transfer failure", bus=self.name, target=target)
        emulator = self.targets.get(target)
        if emulator is None or emulator.absent:
            what = "address" if self.kind is BusKind.I2C else "chip select"
            raise NackError(f"no device answered at {what} 0x{target:02X}", bus=self.name,
                            target=target)
        return emulator.bus_transfer(self.kind, write, read_len)
