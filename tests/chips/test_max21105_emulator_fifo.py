"""The MAX21105 emulator's FIFO, byte by byte from the bus, at the MAX21105's own addresses
(user guide rev 1.4: FIFO_STORE 0x17, FIFO_THS 0x18 in samples, FIFO_CFG 0x19 with the mode
in [4:3], double size [2] and overrun [0]; its assumptions: imuhal_chips/max2110x/
emulator_fifo.py). Written against the user guide's register values, not the driver's."""

from __future__ import annotations

import struct

from tests.chips.test_max2110x_emulator import rd, spi, wr

from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.max2110x.emulator import Max21105Emulator

PERIOD_S = 0.005  # 200 Hz: SNS_CFG_2 code 5, ACC_CFG_1 code 3
RATE_RAD_S = (0.5, -1.0, 2.0)
FORCE_M_S2 = (1.0, -9.0, 3.5)
# +-500 dps (SNS_CFG_1 [1:0] = 10): 60 LSB/dps; +-4 g (SET_ACC_PWR [7:6] = 10): 7500 LSB/g
GYRO_COUNTS = tuple(round(w * 57.29577951308232 * 60) for w in RATE_RAD_S)
ACCEL_COUNTS = tuple(round(f / 9.80665 * 7500) for f in FORCE_M_S2)
NORMAL = 0x08  # FIFO_CFG [4:3] = 01
OVERRUN = 0x01
DOUBLE_SIZE = 0x04


def _measuring(fifo_cfg: int, store: int = 0x03) -> tuple[SimulatedClock, EmulatedBus,
                                                           Max21105Emulator]:
    clock, bus, emu = spi(Max21105Emulator)
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=RATE_RAD_S,
                                   specific_force_m_s2=FORCE_M_S2, temperature_degc=25.0))
    wr(bus, 0x01, 0x02)  # +-500 dps
    wr(bus, 0x02, 0x05)  # gyro 200 Hz
    wr(bus, 0x04, 0x80)  # +-4 g
    wr(bus, 0x05, 0x03)  # accel 200 Hz
    wr(bus, 0x17, store)  # FIFO_STORE: [1] accel, [0] gyro
    wr(bus, 0x19, fifo_cfg)
    wr(bus, 0x00, 0x78)  # acc LN + gyro LN: measuring from here
    return clock, bus, emu


def _count(bus: EmulatedBus) -> int:
    return rd(bus, 0x3C)[0]


def _x_rate_counts_per_frame(clock: SimulatedClock, emu: Max21105Emulator, n: int) -> None:
    """``n`` measurements, the k-th of an X rate of k counts (60 LSB/dps)."""
    for k in range(n):
        emu.set_physics(PhysicalInputs(angular_rate_rad_s=(k / 60 / 57.29577951308232, 0, 0),
                                       specific_force_m_s2=FORCE_M_S2))
        clock.sleep(PERIOD_S)
    clock.sleep(0.001)


def test_normal_mode_stores_a_frame_of_gyro_then_accel_words_per_measurement() -> None:
    clock, bus, _ = _measuring(NORMAL)
    clock.sleep(3 * PERIOD_S + 0.001)
    assert _count(bus) == 3 * 6
    frame = struct.unpack(">6h", rd(bus, 0x3E, 12, no_inc=True))
    assert frame == GYRO_COUNTS + ACCEL_COUNTS
    assert _count(bus) == 2 * 6


def test_fifo_store_selects_the_channels_stored() -> None:
    clock, bus, _ = _measuring(NORMAL, store=0x02)  # the accelerometer alone
    clock.sleep(2 * PERIOD_S + 0.001)
    assert _count(bus) == 2 * 3
    assert struct.unpack(">3h", rd(bus, 0x3E, 6, no_inc=True)) == ACCEL_COUNTS


def test_the_max21100s_fifo_cfg_value_at_0x18_is_only_the_max21105s_threshold() -> None:
    clock, bus, _ = _measuring(0x00)
    wr(bus, 0x18, 0x43)  # the MAX21100's "normal, gyro + accel" at its FIFO_CFG address
    clock.sleep(3 * PERIOD_S + 0.001)
    assert _count(bus) == 0


def test_the_threshold_counts_samples_of_three_words() -> None:
    clock, bus, _ = _measuring(NORMAL)
    wr(bus, 0x18, 4)  # four 3-axis samples: two frames
    clock.sleep(1 * PERIOD_S + 0.001)
    assert not rd(bus, 0x3D)[0] & 0x04
    clock.sleep(1 * PERIOD_S)
    assert rd(bus, 0x3D)[0] & 0x04  # ovthold


def test_a_full_fifo_keeps_its_oldest_frames_and_flags_data_lost() -> None:
    clock, bus, emu = _measuring(NORMAL)
    _x_rate_counts_per_frame(clock, emu, 13)
    assert _count(bus) == 60
    assert rd(bus, 0x3D)[0] & 0x12 == 0x12  # data_lost, full
    assert struct.unpack(">6h", rd(bus, 0x3E, 12, no_inc=True))[0] == 0
    assert emu.fifo.frames_dropped == 3


def test_with_overrun_a_full_fifo_writes_over_its_oldest_frames() -> None:
    clock, bus, emu = _measuring(NORMAL | OVERRUN)
    _x_rate_counts_per_frame(clock, emu, 13)
    assert _count(bus) == 60
    assert rd(bus, 0x3D)[0] & 0x10
    assert struct.unpack(">6h", rd(bus, 0x3E, 12, no_inc=True))[0] == 3


def test_double_size_holds_twice_the_words() -> None:
    clock, bus, _ = _measuring(NORMAL | DOUBLE_SIZE)
    clock.sleep(21 * PERIOD_S + 0.001)
    assert _count(bus) == 126 and not rd(bus, 0x3D)[0] & 0x10  # 21 frames in 128 words
    clock.sleep(PERIOD_S)
    assert _count(bus) == 126 and rd(bus, 0x3D)[0] & 0x10


def test_turning_the_fifo_off_empties_it() -> None:
    clock, bus, _ = _measuring(NORMAL)
    clock.sleep(5 * PERIOD_S + 0.001)
    wr(bus, 0x19, 0x00)
    wr(bus, 0x19, NORMAL)
    assert _count(bus) == 0


def test_int1_pulses_at_each_gyro_measurement_as_the_user_guides_example_sets_it() -> None:
    clock, bus, emu = _measuring(NORMAL)
    start = clock.now_ns()
    wr(bus, 0x22, 0x01)  # bank 1: the user guide's DATA_READY interrupt example
    for reg, value in ((0x17, 0x20), (0x0F, 0x80), (0x0C, 0x00), (0x0B, 0x20)):
        wr(bus, reg, value)
    wr(bus, 0x22, 0x00)
    period = round(PERIOD_S * 1e9)
    assert emu.interrupt_after(start) == start + period
    assert emu.interrupt_after(start + period) == start + 2 * period
