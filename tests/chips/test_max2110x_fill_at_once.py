"""The MAX2110x emulator's fast paths (``Max2110xEmulator.fast_paths``) leave every
register, status bit, FIFO byte, slave transaction, pull and recorded instant as its general
paths do: a FIFO fill latched at once (the inputs of a fill's instants taken from the
board's plan in one step, the counts encoded for the plan, the frames packed by one numpy
call), and both channels on one clock caught up as a pair when the host reads the data
registers. Two chips are driven alike by a planning board of their own (what
``EmulatedBoard`` does for a chip with its own clock: the inputs of the announced instants
computed ahead, handed out while the pulls come as announced), one on the fast paths, one
on the general ones, and read alike over the bus."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest
from tests.chips.test_max2110x_emulator import rd, spi, wr
from tests.chips.test_max2110x_emulator_auto_read import SLAVE, RegisterFile

from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs, PlannedInputs
from imuhal_chips.max2110x.emulator import Max21100Emulator, Max21105Emulator

PERIOD_S = 0.004  # 250 Hz both channels: GYRO_CFG2 code 5, ACC_CFG1 code 3


class PlanningBoard:
    """The three hooks an emulated board gives a chip with its own clock, on a plan of
    random inputs per announced instant (``huge_at``: one value whose counts do not encode
    with the plan's others); a pull elsewhere drops the plan. The inputs stay inside the
    narrowest range the tests set (250 deg/s, 4 g) by over four sigma: a plan with a word at
    the rail is latched row by row (its cut runs through the low-pass, imuhal.sim.lowpass)."""

    def __init__(self, chip: Max21100Emulator, seed: int, huge_at: int | None = None) -> None:
        self.chip = chip
        self.rng = np.random.default_rng(seed)
        self.huge_at = huge_at
        self.times: list[int] = []
        self.plan: PlannedInputs | None = None
        self.next = 0
        self.pulls: list[int] = []
        """Every instant the chip pulled, in order (one by one or taken at once)."""
        chip.physics_source = self.pull
        chip.physics_ahead = self.ahead
        chip.physics_rows = self.rows

    def ahead(self, times: Sequence[int]) -> None:
        n = len(times)
        rng = self.rng
        force = rng.normal(0.0, 8.0, (n, 3))
        if self.huge_at is not None and self.huge_at < n:
            force[self.huge_at, 1] = 1e308  # a finite value whose quotient overflows
            self.huge_at = None
        self.plan = PlannedInputs(force, rng.normal(0.0, 0.8, (n, 3)),
                                  rng.normal(0.0, 50.0, (n, 3)), rng.normal(9e4, 50.0, n),
                                  rng.normal(30.0, 10.0, n), np.zeros((n, 3)), np.zeros((n, 3)))
        self.times = list(times)
        self.next = 0

    def pull(self, t_ns: int) -> None:
        self.pulls.append(t_ns)
        if self.plan is not None and self.next < len(self.times) \
                and self.times[self.next] == t_ns:
            self.chip.set_planned(self.plan, self.next)
            self.next += 1
            return
        # a pull not as announced (a measurement skipped): the plan is dropped and the
        # instant's inputs computed alone, as the board does
        self.plan = None
        rng = np.random.default_rng(t_ns)
        self.chip.set_physics(PhysicalInputs(
            specific_force_m_s2=tuple(rng.normal(0.0, 8.0, 3).tolist()),
            angular_rate_rad_s=tuple(rng.normal(0.0, 0.8, 3).tolist()),
            temperature_degc=float(rng.normal(30.0, 10.0))))

    def rows(self, times: Sequence[int]) -> tuple[PlannedInputs, int] | None:
        if self.plan is None or self.times[self.next:self.next + len(times)] != list(times):
            return None
        first = self.next
        self.pulls.extend(times)
        self.next += len(times)
        self.chip.set_planned(self.plan, self.next - 1)
        return self.plan, first


def _measuring(cls: type[Max21100Emulator], at_once: bool, seed: int, *, temperature: bool,
               little_endian: bool, huge_at: int | None = None
               ) -> tuple[SimulatedClock, EmulatedBus, Max21100Emulator, PlanningBoard]:
    clock, bus, emu = spi(cls)
    emu.fast_paths = at_once
    board = PlanningBoard(emu, seed, huge_at)
    wr(bus, 0x01, 0x02)  # +-500 dps
    wr(bus, 0x02, 0x05)  # gyro 250 Hz
    wr(bus, 0x04, 0x87)  # +-4 g, X/Y/Z on
    wr(bus, 0x05, 0x03)  # accel 250 Hz
    wr(bus, 0x13, 0x01 if temperature else 0x00)  # DR_CFG: the temperature word
    wr(bus, 0x16, 0x02 if little_endian else 0x00)  # I2C_CFG: the data words' byte order
    if cls is Max21105Emulator:
        wr(bus, 0x17, 0x03)  # FIFO_STORE: gyro and accelerometer
        wr(bus, 0x19, 0x08)  # FIFO_CFG: normal mode
    else:
        wr(bus, 0x18, 0x43)  # FIFO_CFG: normal mode, gyro and accelerometer stored
    wr(bus, 0x00, 0x7F)  # accel + gyro normal, all axes: measuring from here
    return clock, bus, emu, board


def _read_out(bus: EmulatedBus) -> tuple[bytes, ...]:
    """What a host sees, in the order a FIFO driver reads it: the count, the status, the
    data words from SYSTEM_STATUS on (temperature included), then the FIFO's bytes."""
    count = rd(bus, 0x3C)[0]
    status = rd(bus, 0x3D)
    words = rd(bus, 0x23, 0x3C - 0x23)
    return bytes((count,)), status, words, rd(bus, 0x3E, 2 * count, no_inc=True)


def _fly(cls: type[Max21100Emulator], at_once: bool, fills: Sequence[int], seed: int,
         writes: dict[int, tuple[int, int]] | None = None, **options: object
         ) -> tuple[list[tuple[bytes, ...]], list[int], int, int, int]:
    """(what the host read after each fill, the pulls, the instants recorded, the frames
    written and dropped); the last fly's chip in ``FLOWN``. ``writes``: a register written
    (register, value) after the read of the fill of that index."""
    clock, bus, emu, board = _measuring(cls, at_once, seed, **options)  # type: ignore[arg-type]
    FLOWN[:] = [emu]
    seen = []
    for k, frames in enumerate(fills):
        clock.sleep(frames * PERIOD_S)
        seen.append(_read_out(bus))
        if writes and k in writes:
            wr(bus, *writes[k])
    return (seen, board.pulls, emu.measured_ns.count_until(clock.now_ns()),
            emu.fifo.frames_written, emu.fifo.frames_dropped)


FLOWN: list[Max21100Emulator] = []


FILLS = (1, 2, 3, 8, 7, 9, 10, 11, 30, 2, 8, 16, 5)
"""Fills of one to thirty frames: the FIFO (ten frames of six words) overflows in some."""


@pytest.mark.parametrize("cls", [Max21100Emulator, Max21105Emulator])
@pytest.mark.parametrize(("temperature", "little_endian"), [(True, False), (False, True)])
def test_a_fill_latched_at_once_reads_as_one_latched_measurement_by_measurement(
        cls: type[Max21100Emulator], temperature: bool, little_endian: bool) -> None:
    at_once = _fly(cls, True, FILLS, 5, temperature=temperature, little_endian=little_endian)
    one_by_one = _fly(cls, False, FILLS, 5, temperature=temperature,
                      little_endian=little_endian)
    assert at_once == one_by_one
    assert at_once[4] > 0  # some fills overflowed


def test_a_fill_after_a_change_of_range_packs_its_frames_at_the_new_sensitivity() -> None:
    # the frames packed once per plan are the counts at the sensitivity they are latched at:
    # +-500 dps and +-4 g, then +-250 dps (GYRO_CFG1) from the fourth fill and +-8 g
    # (PWR_ACC_CFG) from the seventh (each write restarts the timing: a new plan)
    writes = {3: (0x01, 0x03), 6: (0x04, 0x47)}
    options = {"temperature": True, "little_endian": False}
    at_once = _fly(Max21100Emulator, True, FILLS, 5, writes, **options)
    latched = FLOWN[0].fills_latched_at_once
    assert at_once == _fly(Max21100Emulator, False, FILLS, 5, writes, **options)
    assert latched >= sum(1 for n in FILLS[7:] if n > 1)  # fills after both changes too


def test_fills_are_latched_at_once_when_the_board_planned_their_instants() -> None:
    clock, bus, emu, _ = _measuring(Max21100Emulator, True, 5, temperature=True,
                                    little_endian=False)
    for frames in FILLS:
        clock.sleep(frames * PERIOD_S)
        _read_out(bus)
    # fills of more than one instant: all but each one's last latched at once
    assert emu.fills_latched_at_once == sum(1 for n in FILLS if n > 1)


def test_a_plan_whose_values_do_not_encode_at_once_latches_its_rows_one_by_one() -> None:
    # a plan with one value whose quotient overflows (round() would raise on it) cannot be
    # encoded at once; the fills before that value's instant take their rows at once and
    # latch them from their inputs one at a time
    options = {"temperature": True, "little_endian": False, "huge_at": 900}
    at_once = _fly(Max21100Emulator, True, FILLS, 9, **options)
    assert FLOWN[0].fills_latched_at_once == 0
    one_by_one = _fly(Max21100Emulator, False, FILLS, 9, **options)
    assert at_once == one_by_one
    assert sum(FILLS) < 900


def test_instants_the_board_did_not_plan_are_pulled_one_by_one() -> None:
    clock, bus, emu, board = _measuring(Max21100Emulator, True, 5, temperature=False,
                                        little_endian=False)
    clock.sleep(8 * PERIOD_S)
    _read_out(bus)
    latched = emu.fills_latched_at_once
    emu.physics_ahead = None  # the board plans no more: each pull asks for its instant
    board.plan = None
    emu.physics_source = lambda t_ns: emu.set_physics(PhysicalInputs(
        angular_rate_rad_s=(0.1, 0.2, 0.3), specific_force_m_s2=(0.0, 0.0, -9.8)))
    clock.sleep(8 * PERIOD_S)
    assert len(_read_out(bus)[3]) == 8 * 12
    assert emu.fills_latched_at_once == latched


def _polled(fast: bool, gaps: Sequence[float], *, temperature: bool = True,
            little_endian: bool = False, power_cfg: int = 0x7F, huge_at: int | None = None,
            frozen_after: int | None = None) -> tuple[list[bytes], list, list[int], int]:
    """A MAX21100 read by register bursts (no FIFO) after each of ``gaps`` (periods), its
    slave auto-read on at every accelerometer measurement, a one-shot read of the slave
    triggered after each burst (the chip wakes for its end, before the next measurement):
    (the bursts, the slave's transactions, the pulls, the instants recorded); the chip in
    ``FLOWN``. ``power_cfg``: POWER_CFG as written (0x7F: every gyro axis on);
    ``frozen_after``: the chip freezes after that many bursts."""
    clock, bus, emu = spi(Max21100Emulator)
    FLOWN[:] = [emu]
    emu.fast_paths = fast
    board = PlanningBoard(emu, 3, huge_at)
    slave = emu.child_buses()["aux"].attach(SLAVE, RegisterFile())
    dr_cfg = 0x01 if temperature else 0x00
    for reg, value in ((0x01, 0x02), (0x02, 0x05), (0x04, 0x87), (0x05, 0x03), (0x08, SLAVE),
                       (0x09, 0x03), (0x07, 0x86), (0x13, dr_cfg),
                       (0x16, 0x02 if little_endian else 0x00), (0x00, power_cfg)):
        wr(bus, reg, value)
    bursts = []
    for k, gap in enumerate(gaps):
        emu.frozen = frozen_after is not None and k >= frozen_after
        clock.sleep(gap * PERIOD_S)
        bursts.append(rd(bus, 0x23, 0x3C - 0x23))
        wr(bus, 0x0B, 0x05)  # I2C_MST_ADD: the slave's register 5
        wr(bus, 0x13, 0x30 | dr_cfg)  # DR_CFG: a one-shot read (the temperature bit kept)
        clock.sleep(0.2 * PERIOD_S)
        bursts.append(rd(bus, 0x0C))  # I2C_MST_DATA, once the one-shot is done
    return bursts, slave.log, board.pulls, emu.measured_ns.count_until(clock.now_ns())


GAPS = (1.0, 1.0, 0.25, 0.5, 2.5, 3.0, 1.0, 0.3, 7.0, 1.0, 1.0)
"""Polls each period, several a period and a few periods apart (overruns)."""


def test_both_channels_caught_up_as_a_pair_read_as_on_the_general_path() -> None:
    fast = _polled(True, GAPS)
    general = _polled(False, GAPS)
    assert fast == general
    assert len(fast[1]) > len(GAPS)  # the auto-reads and the one-shots reached the slave


def test_both_channels_of_an_instant_are_latched_together_from_the_plan() -> None:
    # a burst and a one-shot each period: every measurement is latched as it comes, each
    # instant's two pulls taken from the plan at once (an overrun, a pull the board did not
    # plan, drops the plan: then they go one by one)
    *_, measured = _polled(True, (0.8,) * 12)
    assert measured >= 11
    assert FLOWN[0].pairs_latched_at_once == measured
    _polled(False, (0.8,) * 12)
    assert FLOWN[0].pairs_latched_at_once == 0


@pytest.mark.parametrize(("temperature", "little_endian"), [(False, False), (True, True)])
def test_a_pair_latched_together_reads_as_on_the_general_path_in_either_byte_order(
        temperature: bool, little_endian: bool) -> None:
    options = {"temperature": temperature, "little_endian": little_endian}
    fast = _polled(True, GAPS, **options)  # type: ignore[arg-type]
    assert FLOWN[0].pairs_latched_at_once > 0
    assert fast == _polled(False, GAPS, **options)  # type: ignore[arg-type]


@pytest.mark.parametrize("options", [
    {"power_cfg": 0x7D},  # the gyro's Y axis off: its word reads 0
    {"huge_at": 6},  # a plan value whose counts do not encode: latched from the row's inputs
    {"frozen_after": 4},  # a frozen chip keeps the inputs it had: no rows taken
], ids=["axis-off", "plan-not-encoded", "frozen"])
def test_a_pair_the_plan_cannot_latch_together_is_latched_channel_by_channel(
        options: dict[str, int]) -> None:
    fast = _polled(True, GAPS, **options)  # type: ignore[arg-type]
    assert fast == _polled(False, GAPS, **options)  # type: ignore[arg-type]
