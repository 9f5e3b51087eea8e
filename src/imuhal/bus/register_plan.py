"""A chip's configuration as a declared, checked register plan.

A driver declares once what its chip's registers must hold (:class:`RegisterSetting`:
register, value, the bits that are checked) and the plan does the rest, as PX4's drivers do
with ``_register_cfg[]`` and ``RegisterCheck()`` and ArduPilot's with
``setup_checked_registers()`` and ``check_next_register()``:

- :meth:`RegisterPlan.apply` writes every setting, in the declared order (the order matters:
  a chip may ignore some writes once it measures, so the plan says what goes last);
- :meth:`RegisterPlan.verify` reads them all back and raises one located error, naming the
  chip, each register that differs, what was expected and what was read;
- :meth:`RegisterPlan.check_next` reads the next check step only (one register unless the
  driver grouped some) and moves on, so a running driver re-checks its whole configuration
  continuously, one cheap transfer at a time, and catches a silent reset, a brown-out or a
  corrupted register;
- :meth:`RegisterPlan.lost` reads every check step at once, for the moments a driver must
  know now (its data are overdue, or a transfer failed and it wants to resume);
- :meth:`RegisterPlan.establish` is apply and verify for a recovery on a noisy bus: a
  transfer that fails is repeated in place (:func:`retried`) and a register that reads back
  wrong is written again, rather than the whole sequence starting over. PX4's InvenSense
  drivers do the same in their CONFIGURE state: every register is checked, only those that
  differ are set again, and the reset is not repeated for it.

Bits outside a setting's ``mask`` are written as given but never checked: bits the chip
changes by itself (a forced-mode barometer's mode bits fall back to sleep after each
measurement) or that read back as something else.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError

T = TypeVar("T")

IN_PLACE_ATTEMPTS = 4
"""Tries of one configuration transfer before a sequence gives up on it. At 10 % of
transfers failing, one fails four times in a row once in 10,000: an MPU-9250 recovery (about
30 transfers) then completes 997 times in 1,000, where starting the sequence over after any
failure completed it about once in 20 (0.9^30)."""


def retried(transfer: Callable[[], T], attempts: int = IN_PLACE_ATTEMPTS) -> T:
    """``transfer()``, called again at once when it raises :class:`BusError` (a NACK
    included), ``attempts`` times at most; the last error is raised. Only for transfers the
    chip may see twice: a configuration write (the same value again) or a read without side
    effects (identity and configuration registers), never a data, status or FIFO read that
    the chip clears when it is read."""
    for _ in range(attempts - 1):
        try:
            return transfer()
        except BusError:
            continue
    return transfer()


@dataclass(frozen=True)
class RegisterSetting:
    """What one register must hold: ``value`` is written whole; the bits of ``mask`` are
    checked (set where ``value`` has a 1, clear where it has a 0)."""

    register: int
    value: int
    mask: int = 0xFF
    name: str = ""
    """The datasheet's name of the register, for messages (default: its address)."""
    wait_s: float = 0.0
    """Time the chip needs after this write before the next access (a mode change), s."""

    @property
    def set_bits(self) -> int:
        return self.value & self.mask

    @property
    def clear_bits(self) -> int:
        return ~self.value & self.mask

    def holds(self, read: int) -> bool:
        """Whether the value ``read`` from the chip has every checked bit as planned."""
        return (read ^ self.value) & self.mask == 0

    @property
    def label(self) -> str:
        address = f"0x{self.register:02X}"
        return f"{self.name} ({address})" if self.name else address


@dataclass(frozen=True)
class RegisterMismatch:
    """A register whose checked bits differ from the plan."""

    setting: RegisterSetting
    read: int

    def describe(self) -> str:
        s = self.setting
        mask = "" if s.mask == 0xFF else f" in bits 0x{s.mask:02X}"
        return f"{s.label} reads 0x{self.read:02X}, expected 0x{s.value:02X}{mask}"


class RegisterPlan:
    """The registers a chip must hold, in write order; applied, verified and checked."""

    def __init__(self, chip: str, settings: Iterable[RegisterSetting], *,
                 checks: Sequence[Sequence[int]] | None = None, gap: int = 0,
                 burst: bool = True, burst_write: bool = False, hint: str = "") -> None:
        """``chip``: how messages name the chip (its driver's ``describe()``).
        ``checks``: the continuous check's steps, each a group of registers read in one
        transfer (default: every register of the plan, one per step). ``gap``: registers
        read back in one burst when at most this many unplanned registers lie between them
        (those are read and ignored; 0: only adjacent ones). ``burst=False``: :meth:`verify`
        reads every register on its own, in plan order (a chip whose burst reads do not
        cover its configuration registers). ``burst_write``: settings of consecutive
        registers, in plan order, are written in one transfer (a chip that takes a
        configuration block at once). ``hint``: what to do when verification fails,
        appended to the error."""
        self.chip = chip
        self.settings: tuple[RegisterSetting, ...] = tuple(settings)
        self._by_register = {s.register: s for s in self.settings}
        if len(self._by_register) != len(self.settings):
            raise ValueError(f"{chip}: a register appears twice in its plan")
        steps = checks if checks is not None else [(s.register,) for s in self.settings]
        unknown = [reg for step in steps for reg in step if reg not in self._by_register]
        if unknown or not all(steps):
            raise ValueError(f"{chip}: check steps name registers outside the plan: {unknown}")
        self.steps: tuple[tuple[int, ...], ...] = tuple(tuple(step) for step in steps)
        self.gap = gap
        self.burst = burst
        self.burst_write = burst_write
        self.hint = hint
        self._next = 0

    @classmethod
    def of(cls, chip: str, values: Mapping[int, int], *,
           names: Mapping[int, str] | None = None,
           checks: Sequence[Sequence[int]] | None = None, gap: int = 0, burst: bool = True,
           burst_write: bool = False, hint: str = "") -> RegisterPlan:
        """A plan of whole-register values (register -> value, in write order); ``names``:
        register -> datasheet name, for messages."""
        names = names or {}
        return cls(chip, (RegisterSetting(reg, value, name=names.get(reg, ""))
                          for reg, value in values.items()),
                   checks=checks, gap=gap, burst=burst, burst_write=burst_write, hint=hint)

    # -- what the plan says -----------------------------------------------------------------

    @property
    def registers(self) -> tuple[int, ...]:
        return tuple(s.register for s in self.settings)

    def __getitem__(self, register: int) -> int:
        """The value planned for ``register``."""
        return self._by_register[register].value

    def get(self, register: int, default: int) -> int:
        s = self._by_register.get(register)
        return s.value if s is not None else default

    def __len__(self) -> int:
        return len(self.settings)

    def mismatches(self, values: Mapping[int, int]) -> list[RegisterMismatch]:
        """The planned registers among ``values`` (register -> value read) that differ."""
        return [RegisterMismatch(s, values[s.register]) for s in self.settings
                if s.register in values and not s.holds(values[s.register])]

    # -- talking to the chip ------------------------------------------------------------------

    def apply(self, regs: RegisterView, clock: Clock | None = None, *,
              attempts: int = 1) -> None:
        """Write every setting, in plan order, waiting a setting's ``wait_s`` on ``clock``
        after writing it; a write that raises :class:`BusError` is repeated in place up to
        ``attempts`` times in all (:func:`retried`; 1: not repeated)."""
        for block in self._write_blocks():
            retried(partial(self._write, regs, block), attempts)
            if block[-1].wait_s and clock is not None:
                clock.sleep(block[-1].wait_s)

    def establish(self, regs: RegisterView, clock: Clock | None = None, *,
                  attempts: int = IN_PLACE_ATTEMPTS) -> dict[int, int]:
        """:meth:`apply` and :meth:`verify` for a bus that fails now and then (a recovery):
        each transfer that fails is repeated in place and a setting that reads back wrong
        is written again, ``attempts`` times at most, rather than the whole sequence
        starting over. Returns the values read back."""
        self.apply(regs, clock, attempts=attempts)
        return self.verify(regs, attempts=attempts, clock=clock)

    @staticmethod
    def _write(regs: RegisterView, block: Sequence[RegisterSetting]) -> None:
        """One write transfer of consecutive settings (a block of :meth:`_write_blocks`)."""
        first = block[0]
        if len(block) == 1:
            regs.write(first.register, first.value)
        else:
            regs.write(first.register, bytes(s.value for s in block))

    def _read_groups(self, registers: Iterable[int], burst: bool) -> list[list[int]]:
        """``registers`` grouped as :meth:`read` reads them, one transfer per group."""
        wanted = list(registers)
        if not burst:
            return [[reg] for reg in wanted]
        return [[reg for reg in wanted if first <= reg <= last]
                for first, last in _runs(sorted(set(wanted)), self.gap)]

    def _write_blocks(self) -> list[list[RegisterSetting]]:
        """The settings grouped into the transfers that write them."""
        blocks: list[list[RegisterSetting]] = []
        for s in self.settings:
            last = blocks[-1][-1] if blocks else None
            if (self.burst_write and last is not None and not last.wait_s
                    and s.register == last.register + 1):
                blocks[-1].append(s)
            else:
                blocks.append([s])
        return blocks

    def read(self, regs: RegisterView, registers: Iterable[int] | None = None,
             *, burst: bool | None = None) -> dict[int, int]:
        """The chip's current values of ``registers`` (default: the whole plan). In bursts
        over runs of nearby registers (``gap``), or one by one in the given order when
        ``burst`` (default: the plan's) is False."""
        wanted = list(self.registers if registers is None else registers)
        if not (self.burst if burst is None else burst):
            return {reg: regs.read(reg, 1)[0] for reg in wanted}
        got: dict[int, int] = {}
        for first, last in _runs(sorted(set(wanted)), self.gap):
            block = regs.read(first, last - first + 1)
            for reg in wanted:
                if first <= reg <= last:
                    got[reg] = block[reg - first]
        return got

    def verify(self, regs: RegisterView, *, attempts: int = 1,
               clock: Clock | None = None) -> dict[int, int]:
        """Read every planned register back; one :class:`ConfigurationError` naming the chip
        and each register that differs (expected and read) when any does. Returns the
        values read (what the chip really runs with).

        ``attempts`` above 1: a read that raises :class:`BusError` is repeated in place, and
        a setting that reads back wrong is written again (waiting its ``wait_s`` on
        ``clock``) and read again, up to ``attempts`` times in all, before the error. The
        values returned are still all read from the chip after their last write: a
        configuration is never taken as set on the strength of a write."""
        got: dict[int, int] = {}
        for group in self._read_groups(self.registers, self.burst):
            got.update(retried(partial(self.read, regs, group), attempts))
        for _ in range(attempts - 1):
            wrong = self.mismatches(got)
            if not wrong:
                break
            for m in wrong:
                s = m.setting
                retried(partial(regs.write, s.register, s.value), attempts)
                if s.wait_s and clock is not None:
                    clock.sleep(s.wait_s)
                got[s.register] = retried(partial(regs.read_u8, s.register), attempts)
        return self.confirm(got)

    def confirm(self, got: dict[int, int]) -> dict[int, int]:
        """:meth:`verify` of values already read (register -> value); returns ``got``."""
        wrong = self.mismatches(got)
        if wrong:
            detail = "; ".join(m.describe() for m in wrong)
            hint = f"; {self.hint}" if self.hint else ""
            raise ConfigurationError(
                f"{self.chip}: configuration did not read back: {detail}{hint}")
        return got

    def check_next(self, regs: RegisterView) -> RegisterMismatch | None:
        """Read the next check step (one transfer) and move on to the following one; the
        first register of it that differs, or None."""
        step = self.steps[self._next]
        self._next = (self._next + 1) % len(self.steps)
        wrong = self.mismatches(self.read(regs, step, burst=True))
        return wrong[0] if wrong else None

    def lost(self, regs: RegisterView) -> RegisterMismatch | None:
        """Read every register the check steps cover now (in bursts over runs, as
        :meth:`read`); the first that differs, or None."""
        watched = dict.fromkeys(reg for step in self.steps for reg in step)
        wrong = self.mismatches(self.read(regs, watched, burst=True))
        return wrong[0] if wrong else None

    def restart_checks(self) -> None:
        """Start the continuous check over from the first step (after a reconfiguration)."""
        self._next = 0


def _runs(registers: Sequence[int], gap: int) -> list[tuple[int, int]]:
    """(first, last) of each run of sorted ``registers`` at most ``gap`` apart."""
    runs: list[tuple[int, int]] = []
    for reg in registers:
        if runs and reg - runs[-1][1] <= gap + 1:
            runs[-1] = (runs[-1][0], reg)
        else:
            runs.append((reg, reg))
    return runs
