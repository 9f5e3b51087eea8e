"""The MAX21100 emulator's FIFO, byte by byte from the bus (its facts and assumptions:
imuhal_chips/max2110x/emulator_fifo.py). Written against the register values the sources
give (Kris Winer's FIFO_CFG 0x41 / 0x42 / 0x00, FIFO_COUNT in words, 64 words), not
against the driver's tables."""

from __future__ import annotations

import struct

from tests.chips.test_max2110x_emulator import rd, spi, wr

from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.max2110x.emulator import Max21100Emulator

PERIOD_S = 0.004  # 250 Hz: GYRO_CFG2 code 5, ACC_CFG1 code 3
RATE_RAD_S = (0.5, -1.0, 2.0)
FORCE_M_S2 = (1.0, -9.0, 3.5)
# +-500 dps (GYRO_CFG1 [1:0] = 10): 60 LSB/dps; +-4 g (PWR_ACC_CFG [7:6] = 10): 7500 LSB/g
GYRO_COUNTS = tuple(round(w * 57.29577951308232 * 60) for w in RATE_RAD_S)
ACCEL_COUNTS = tuple(round(f / 9.80665 * 7500) for f in FORCE_M_S2)


def _measuring(fifo_cfg: int) -> tuple[SimulatedClock, EmulatedBus, Max21100Emulator]:
    clock, bus, emu = spi()
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=RATE_RAD_S,
                                   specific_force_m_s2=FORCE_M_S2, temperature_degc=25.0))
    wr(bus, 0x01, 0x02)  # +-500 dps
    wr(bus, 0x02, 0x05)  # gyro 250 Hz
    wr(bus, 0x04, 0x87)  # +-4 g, X/Y/Z on
    wr(bus, 0x05, 0x03)  # accel 250 Hz
    wr(bus, 0x18, fifo_cfg)
    wr(bus, 0x00, 0x7F)  # accel + gyro normal, all axes: measuring from here
    return clock, bus, emu


def _count(bus: EmulatedBus) -> int:
    return rd(bus, 0x3C)[0]


def test_the_fifo_off_stores_nothing() -> None:
    clock, bus, _ = _measuring(0x00)
    clock.sleep(10 * PERIOD_S + 0.001)
    assert _count(bus) == 0
    assert rd(bus, 0x3D)[0] & 0x01  # empty


def test_normal_mode_stores_a_frame_of_gyro_then_accel_words_per_measurement() -> None:
    clock, bus, _ = _measuring(0x43)
    clock.sleep(3 * PERIOD_S + 0.001)
    assert _count(bus) == 3 * 6  # three frames of six words
    frame = struct.unpack(">6h", rd(bus, 0x3E, 12, no_inc=True))
    assert frame == GYRO_COUNTS + ACCEL_COUNTS
    assert _count(bus) == 2 * 6


def test_gyro_only_frames_are_three_words() -> None:
    clock, bus, _ = _measuring(0x41)  # Winer's "normal mode, accumulate gyro data"
    clock.sleep(4 * PERIOD_S + 0.001)
    assert _count(bus) == 4 * 3
    assert struct.unpack(">3h", rd(bus, 0x3E, 6, no_inc=True)) == GYRO_COUNTS


def test_every_measurement_of_a_host_pause_is_kept_until_the_fifo_is_full() -> None:
    clock, bus, emu = _measuring(0x43)
    clock.sleep(9 * PERIOD_S + 0.001)
    assert _count(bus) == 54 and not rd(bus, 0x3D)[0] & 0x10
    clock.sleep(1 * PERIOD_S)
    status = rd(bus, 0x3D)[0]
    assert _count(bus) == 60 and status & 0x02 and not status & 0x10  # full, nothing lost
    clock.sleep(3 * PERIOD_S)
    assert _count(bus) == 60  # a frame that does not fit whole is not written
    assert rd(bus, 0x3D)[0] & 0x10  # data_lost
    assert not rd(bus, 0x3D)[0] & 0x10  # reading the status clears it
    assert emu.fifo is not None and emu.fifo.frames_dropped == 3


def test_the_threshold_in_words_sets_ovthold() -> None:
    clock, bus, _ = _measuring(0x43)
    wr(bus, 0x17, 12)  # two frames
    clock.sleep(1 * PERIOD_S + 0.001)
    assert not rd(bus, 0x3D)[0] & 0x04
    clock.sleep(1 * PERIOD_S)
    assert rd(bus, 0x3D)[0] & 0x04


def test_turning_the_fifo_off_empties_it() -> None:
    clock, bus, _ = _measuring(0x43)
    clock.sleep(5 * PERIOD_S + 0.001)
    wr(bus, 0x18, 0x00)
    wr(bus, 0x18, 0x43)
    assert _count(bus) == 0


def test_reading_an_empty_fifo_is_flagged_read_empty() -> None:
    _, bus, _ = _measuring(0x43)
    assert rd(bus, 0x3E, 2, no_inc=True) == b"\x00\x00"
    assert rd(bus, 0x3D)[0] & 0x08


def test_a_soft_reset_empties_the_fifo() -> None:
    clock, bus, emu = _measuring(0x43)
    clock.sleep(5 * PERIOD_S + 0.001)
    wr(bus, 0x3F, 0x08)
    assert _count(bus) == 0 and emu.fifo is not None and emu.fifo.cfg == 0


# --- INT1 (emulator_int.py: the MAX21105's DATA_READY example taken for the MAX21100) ---


def _int1(clock: SimulatedClock, bus: EmulatedBus, *, enable: int = 0x20) -> None:
    wr(bus, 0x22, 0x01)  # bank 1
    for reg, value in ((0x17, 0x20), (0x0F, 0x80), (0x0C, 0x00), (0x0B, enable)):
        wr(bus, reg, value)
    wr(bus, 0x22, 0x00)


def test_int1_pulses_at_each_gyro_measurement_when_bank_1_selects_it() -> None:
    clock, bus, emu = _measuring(0x43)
    start = clock.now_ns()
    _int1(clock, bus)
    period = round(PERIOD_S * 1e9)
    assert emu.interrupt_pin() == (True, 50_000)
    assert emu.interrupt_after(start) == start + period
    assert emu.interrupt_after(start + period) == start + 2 * period
    clock.sleep(3.5 * PERIOD_S)
    assert emu.interrupt_after(start + 2 * period + 1) == start + 3 * period
    assert emu.interrupt_after(clock.now_ns()) == start + 4 * period


def test_int1_stays_quiet_without_its_enable_bit() -> None:
    clock, bus, emu = _measuring(0x43)
    _int1(clock, bus, enable=0x00)
    assert emu.interrupt_after(clock.now_ns()) is None
