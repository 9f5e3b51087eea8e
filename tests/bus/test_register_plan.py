"""The checked register plan (imuhal.bus.register_plan): applied in order, verified with one
located error, checked continuously one step per check."""

from __future__ import annotations

import pytest

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.register_plan import IN_PLACE_ATTEMPTS, RegisterPlan, RegisterSetting
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, ConfigurationError
from imuhal.drivers.polling import ResetWatch

CHIP = "xyz0 on i2c0 @0x19"


class RegisterFile(Bus):
    """An I2C chip as a plain register file with an auto-incrementing pointer; every
    transfer is logged as (register, bytes written, bytes read)."""

    kind = BusKind.I2C

    def __init__(self) -> None:
        super().__init__("regfile")
        self.regs = bytearray(256)
        self.log: list[tuple[int, bytes, int]] = []

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        register, data = write[0], write[1:]
        self.log.append((register, bytes(data), read_len))
        for offset, value in enumerate(data):
            self.regs[register + offset] = value
        return bytes(self.regs[register:register + read_len])


class GlitchyRegisterFile(RegisterFile):
    """A register file whose transfers numbered in ``failing`` (counted from 0, every
    attempt counted) raise BusError before reaching the chip, and whose ``deaf`` registers
    ignore the first write they get (a write the chip did not take)."""

    def __init__(self, failing: set[int], deaf: set[int] | None = None) -> None:
        super().__init__()
        self.failing = failing
        self.deaf = set(deaf or ())
        self.attempts = 0
        self.failed: list[int] = []
        """The register of each transfer that failed, in order."""

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        n, self.attempts = self.attempts, self.attempts + 1
        if n in self.failing:
            self.failed.append(write[0])
            raise BusError("regfile: injected")
        if len(write) > 1 and write[0] in self.deaf:
            self.deaf.discard(write[0])
            self.log.append((write[0], b"(ignored)", 0))
            return b""
        return super()._transfer(target, write, read_len)


class StuckByte(bytearray):
    """Register memory one of whose registers always reads ``value`` (a stuck line)."""

    def __init__(self, register: int, value: int) -> None:
        super().__init__(256)
        self.stuck = (register, value)

    def __getitem__(self, index):  # type: ignore[no-untyped-def]
        out = super().__getitem__(index)
        if isinstance(index, slice):
            return bytes(self.stuck[1] if i == self.stuck[0] else b
                         for i, b in zip(range(*index.indices(len(self))), out, strict=True))
        return out


def _plan(*, checks: list[tuple[int, ...]] | None = None, gap: int = 0, burst: bool = True,
          burst_write: bool = False, hint: str = "") -> RegisterPlan:
    return RegisterPlan(CHIP, [
        RegisterSetting(0x20, 0x07, name="CTRL1"),
        RegisterSetting(0x21, 0x40, name="CTRL2"),
        RegisterSetting(0x23, 0x88, mask=0xF0, name="CTRL4"),
        RegisterSetting(0x10, 0x01, name="MODE"),
    ], checks=checks, gap=gap, burst=burst, burst_write=burst_write, hint=hint)


def _rig() -> tuple[RegisterFile, RegisterView]:
    chip = RegisterFile()
    return chip, RegisterView(chip.link(0x19))


def test_apply_writes_every_setting_in_plan_order() -> None:
    chip, regs = _rig()
    _plan().apply(regs)
    assert chip.log == [(0x20, b"\x07", 0), (0x21, b"\x40", 0), (0x23, b"\x88", 0),
                        (0x10, b"\x01", 0)]


def test_consecutive_settings_go_in_one_transfer_when_the_plan_says_so() -> None:
    chip, regs = _rig()
    _plan(burst_write=True).apply(regs)
    assert chip.log[0] == (0x20, b"\x07\x40", 0)
    assert len(chip.log) == 3


def test_a_setting_waits_its_time_after_the_write() -> None:
    _, regs = _rig()
    clock = SimulatedClock(0)
    RegisterPlan(CHIP, [RegisterSetting(0x0A, 0x16, wait_s=0.002)]).apply(regs, clock)
    assert clock.now_ns() == 2_000_000


def test_verify_returns_what_the_chip_holds() -> None:
    _, regs = _rig()
    plan = _plan()
    plan.apply(regs)
    assert plan.verify(regs) == {0x20: 0x07, 0x21: 0x40, 0x23: 0x88, 0x10: 0x01}


def test_verify_raises_one_located_error_naming_chip_register_expected_and_read() -> None:
    chip, regs = _rig()
    plan = _plan(hint="check the wiring")
    plan.apply(regs)
    chip.regs[0x21] = 0x00
    chip.regs[0x10] = 0x03
    with pytest.raises(ConfigurationError) as err:
        plan.verify(regs)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{CHIP}: configuration did not read back: ")
    assert "CTRL2 (0x21) reads 0x00, expected 0x40" in message
    assert "MODE (0x10) reads 0x03, expected 0x01" in message
    assert "CTRL1" not in message and message.endswith("; check the wiring")


def test_bits_outside_a_settings_mask_are_not_checked() -> None:
    chip, regs = _rig()
    plan = _plan()
    plan.apply(regs)
    chip.regs[0x23] = 0x8F  # low nibble: the chip's own
    plan.verify(regs)
    chip.regs[0x23] = 0x98
    with pytest.raises(ConfigurationError, match=r"CTRL4 \(0x23\) reads 0x98, expected 0x88 "
                                                 r"in bits 0xF0"):
        plan.verify(regs)


def test_read_back_is_one_burst_per_run_of_nearby_registers() -> None:
    chip, regs = _rig()
    plan = _plan(gap=1)
    plan.apply(regs)
    chip.log.clear()
    plan.verify(regs)
    assert chip.log == [(0x10, b"", 1), (0x20, b"", 4)]  # 0x22 read over and ignored


def test_read_back_one_register_at_a_time_in_plan_order_without_bursts() -> None:
    chip, regs = _rig()
    plan = _plan(burst=False)
    plan.apply(regs)
    chip.log.clear()
    plan.verify(regs)
    assert chip.log == [(0x20, b"", 1), (0x21, b"", 1), (0x23, b"", 1), (0x10, b"", 1)]


def test_the_continuous_check_reads_one_register_per_check_and_cycles_through_the_plan(
        ) -> None:
    chip, regs = _rig()
    plan = _plan()
    plan.apply(regs)
    chip.log.clear()
    assert [plan.check_next(regs) for _ in range(5)] == [None] * 5
    assert chip.log == [(0x20, b"", 1), (0x21, b"", 1), (0x23, b"", 1), (0x10, b"", 1),
                        (0x20, b"", 1)]


def test_the_continuous_check_finds_a_lost_register_within_one_round() -> None:
    chip, regs = _rig()
    plan = _plan()
    plan.apply(regs)
    chip.regs[0x10] = 0x00  # a silent reset of MODE
    found = [plan.check_next(regs) for _ in range(len(plan))]
    assert found[:3] == [None, None, None]
    assert found[3] is not None
    assert found[3].describe() == "MODE (0x10) reads 0x00, expected 0x01"


def test_a_grouped_check_step_reads_its_registers_in_one_transfer() -> None:
    chip, regs = _rig()
    plan = _plan(checks=[(0x20, 0x21)])
    plan.apply(regs)
    chip.log.clear()
    plan.check_next(regs)
    plan.check_next(regs)
    assert chip.log == [(0x20, b"", 2), (0x20, b"", 2)]


def test_lost_reads_every_checked_register_at_once_and_names_the_first_that_differs() -> None:
    chip, regs = _rig()
    plan = _plan()
    plan.apply(regs)
    assert plan.lost(regs) is None
    chip.regs[0x21] = 0x41
    wrong = plan.lost(regs)
    assert wrong is not None and wrong.setting.register == 0x21 and wrong.read == 0x41


def test_check_steps_must_name_planned_registers() -> None:
    with pytest.raises(ValueError, match="outside the plan"):
        _plan(checks=[(0x20, 0x30)])


def test_a_watch_spread_over_the_steps_still_reads_the_whole_plan_every_check_interval(
        ) -> None:
    watch = ResetWatch(0.4)
    watch.spread_over(4)
    watch.start(0)
    due = [t for t in range(0, 400_000_001, 10_000_000) if watch.check_due(t)]
    assert due == [100_000_000, 200_000_000, 300_000_000, 400_000_000]


def test_establish_repeats_a_failed_transfer_in_place_and_goes_on() -> None:
    chip = GlitchyRegisterFile(failing={1, 2, 6})  # CTRL2's write twice, the first read
    regs = RegisterView(chip.link(0x19))
    got = _plan(burst=False).establish(regs)
    assert got == {0x20: 0x07, 0x21: 0x40, 0x23: 0x88, 0x10: 0x01}
    assert chip.failed == [0x21, 0x21, 0x20]
    # each failed transfer was repeated at once; nothing was written twice that succeeded
    assert chip.log == [(0x20, b"\x07", 0), (0x21, b"\x40", 0), (0x23, b"\x88", 0),
                        (0x10, b"\x01", 0), (0x20, b"", 1), (0x21, b"", 1), (0x23, b"", 1),
                        (0x10, b"", 1)]


def test_establish_gives_up_on_a_transfer_that_fails_every_attempt() -> None:
    chip = GlitchyRegisterFile(failing=set(range(1, 1 + IN_PLACE_ATTEMPTS)))
    with pytest.raises(BusError):
        _plan().establish(RegisterView(chip.link(0x19)))
    assert chip.failed == [0x21] * IN_PLACE_ATTEMPTS
    assert [entry[0] for entry in chip.log] == [0x20]  # nothing after the failing write


def test_establish_writes_a_register_that_reads_back_wrong_again_and_reads_it_back() -> None:
    chip = GlitchyRegisterFile(failing=set(), deaf={0x23})
    regs = RegisterView(chip.link(0x19))
    assert _plan(burst=False).establish(regs)[0x23] == 0x88
    assert chip.log[-2:] == [(0x23, b"\x88", 0), (0x23, b"", 1)]  # written again, re-read


def test_establish_raises_the_located_error_when_a_register_keeps_reading_wrong() -> None:
    chip = RegisterFile()
    chip.regs = StuckByte(0x21, 0xFF)
    with pytest.raises(ConfigurationError, match=r"CTRL2 \(0x21\) reads 0xFF, expected 0x40"):
        _plan(burst=False).establish(RegisterView(chip.link(0x19)))
    writes = [entry for entry in chip.log if entry[0] == 0x21 and entry[1]]
    assert len(writes) == IN_PLACE_ATTEMPTS  # the plan's write and three more


def test_verify_without_attempts_neither_repeats_nor_rewrites() -> None:
    chip = GlitchyRegisterFile(failing={4})
    regs = RegisterView(chip.link(0x19))
    plan = _plan(burst=False)
    plan.apply(regs)
    with pytest.raises(BusError):
        plan.verify(regs)
    assert chip.attempts == 5
