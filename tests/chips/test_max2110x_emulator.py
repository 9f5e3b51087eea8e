"""MAX2110x emulator bus face, byte by byte (what the real chip does, per the facts)."""

from __future__ import annotations

import math

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import NackError
from imuhal.core.samples import Quantity
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.max2110x.emulator import Max21100Emulator, Max21105Emulator

ADDR = 0x58


def spi(emulator_cls: type = Max21100Emulator) -> tuple[SimulatedClock, EmulatedBus,
                                                        Max21100Emulator]:
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    emu = bus.attach(0, emulator_cls(clock))
    return clock, bus, emu


def rd(bus: EmulatedBus, reg: int, n: int = 1, *, no_inc: bool = False) -> bytes:
    return bus.transfer(0, bytes([0x80 | (0x40 if no_inc else 0) | reg]), n)


def wr(bus: EmulatedBus, reg: int, *data: int) -> None:
    bus.transfer(0, bytes([reg, *data]), 0)


def test_identity_registers_differ_between_parts_and_are_read_only() -> None:
    _, bus, _ = spi(Max21100Emulator)
    assert rd(bus, 0x20) == b"\xb2"
    wr(bus, 0x20, 0x00)
    assert rd(bus, 0x20) == b"\xb2"
    _, bus5, _ = spi(Max21105Emulator)
    assert rd(bus5, 0x20) == b"\xb4"
    assert rd(bus5, 0x21) == b"\x05"  # SILICON_REV_OTP default


def test_power_on_defaults_of_the_max21105_user_guide() -> None:
    _, bus, _ = spi(Max21105Emulator)
    assert rd(bus, 0x01) == b"\x28"  # 100 Hz bandwidth, 2000 dps
    assert rd(bus, 0x02) == b"\x04"  # 400 Hz
    assert rd(bus, 0x04)[0] >> 6 == 0b11  # 2 g


def test_bit6_stops_auto_increment_and_plain_burst_increments() -> None:
    _, bus, _ = spi()
    assert rd(bus, 0x20, 3) == bytes([0xB2, 0x01, 0x00])
    assert rd(bus, 0x20, 3, no_inc=True) == bytes([0xB2] * 3)


def test_bank_select_switches_the_low_half_but_not_the_common_bank() -> None:
    _, bus, _ = spi()
    wr(bus, 0x22, 0x01)
    wr(bus, 0x0F, 0x80)  # bank 1 INT_MSK
    assert rd(bus, 0x0F) == b"\x80"
    assert rd(bus, 0x20) == b"\xb2"
    wr(bus, 0x22, 0x00)
    assert rd(bus, 0x0F) == b"\x00"
    assert rd(bus, 0x22) == b"\x00"


def test_soft_reset_restores_power_on_defaults_and_bank_0() -> None:
    _, bus, _ = spi()
    wr(bus, 0x01, 0x16)
    wr(bus, 0x22, 0x02)
    wr(bus, 0x3F, 0x08)
    assert rd(bus, 0x22) == b"\x00"
    assert rd(bus, 0x01) == b"\x28"


def test_measurement_sets_data_ready_after_one_period_and_full_read_clears_it() -> None:
    clock, bus, emu = spi()
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.0, 0.0, 0.0)))
    wr(bus, 0x02, 0x05)  # gyro 250 Hz
    wr(bus, 0x00, 0x7F)  # accel + gyro normal
    assert rd(bus, 0x23)[0] & 0x01 == 0
    clock.sleep(0.004)
    assert rd(bus, 0x23)[0] & 0x01 == 0x01
    rd(bus, 0x24, 5)  # mode 00: five of six gyro bytes do not clear it
    assert rd(bus, 0x23)[0] & 0x01 == 0x01
    rd(bus, 0x24, 6)
    assert rd(bus, 0x23)[0] & 0x01 == 0


def test_unread_sample_overwritten_sets_the_error_bit_until_status_read() -> None:
    clock, bus, _ = spi()
    wr(bus, 0x02, 0x05)
    wr(bus, 0x00, 0x7F)
    clock.sleep(0.0085)  # two gyro periods, nothing read
    status = rd(bus, 0x23)[0]
    assert status & 0x03 == 0x03  # gyro_dr and gyro_err
    assert rd(bus, 0x23)[0] & 0x02 == 0


def test_data_ready_clear_mode_on_status_read() -> None:
    clock, bus, _ = spi()
    wr(bus, 0x13, 0x09)  # DR_CFG: clear on status read (10), temperature on
    wr(bus, 0x02, 0x05)
    wr(bus, 0x00, 0x7F)
    clock.sleep(0.004)
    assert rd(bus, 0x23)[0] & 0x01
    assert rd(bus, 0x23)[0] & 0x01 == 0


def test_words_are_big_endian_by_default_and_little_endian_on_request() -> None:
    clock, bus, emu = spi()
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.0, 0.0, 0.0),
                                   temperature_degc=25.0))
    wr(bus, 0x00, 0x7F)
    clock.sleep(0.002)
    assert rd(bus, 0x36, 2) == (6400).to_bytes(2, "big")
    wr(bus, 0x16, 0x03)  # SPI, little-endian
    assert rd(bus, 0x36, 2) == (6400).to_bytes(2, "little")


def test_encoding_saturates_at_30000_counts() -> None:
    clock, bus, emu = spi()
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=(100.0, -100.0, 0.0)))
    wr(bus, 0x00, 0x7F)
    clock.sleep(0.002)
    raw = rd(bus, 0x24, 6)
    assert int.from_bytes(raw[0:2], "big", signed=True) == 30000
    assert int.from_bytes(raw[2:4], "big", signed=True) == -30000


def test_i2c_slave_disable_makes_the_chip_ignore_i2c() -> None:
    clock = SimulatedClock()
    i2c = EmulatedBus("i2c", BusKind.I2C)
    emu = i2c.attach(ADDR, Max21105Emulator(clock))
    assert i2c.transfer(ADDR, b"\x20", 1) == b"\xb4"
    i2c.transfer(ADDR, b"\x16\x01", 0)
    with pytest.raises(NackError):
        i2c.transfer(ADDR, b"\x20", 1)
    emu.silent_reset()
    assert i2c.transfer(ADDR, b"\x20", 1) == b"\xb4"


def test_har_in_air_master_sequence_configures_an_hmc5883l_behind_the_max21100() -> None:
    import json
    from pathlib import Path

    from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator

    seq = json.loads((Path(__file__).parent.parent / "data/chips/max2110x_vectors.json")
                     .read_text())["max21100"]["hmc5883l_master_config_har_in_air"]
    clock, bus, emu = spi()
    mag = emu.child_buses()["aux"].attach(0x1E, Hmc5883lEmulator(clock))
    for reg, value in seq:
        wr(bus, reg, value)
        clock.sleep(0.001)
    assert (mag.regs[0x00], mag.regs[0x01], mag.regs[0x02]) == (0x78, 0x80, 0x00)
    # one-shot read of ID A: I2C_MST_ADD <- 0x0A, trigger 0x35, 0x05, wait, read 0x0C
    for reg, value in ((0x0B, 0x0A), (0x13, 0x35), (0x13, 0x05)):
        wr(bus, reg, value)
    clock.sleep(0.0002)
    assert rd(bus, 0x0C) == b"H"


@pytest.mark.parametrize("start,length", [(0x23, 15), (0x00, 64), (0x38, 12), (0x0B, 3),
                                          (0x3E, 4)])
def test_a_burst_read_returns_what_reading_each_register_alone_returns(start, length) -> None:
    # Bursts are served from a register image; bank 0 (with the aux master's data register),
    # the identity and status bytes, both byte orders of the data words and the wrap past
    # 0x3F must read as they do one register at a time.
    clock, bus, emu = spi(Max21100Emulator)
    wr(bus, 0x00, 0x7F)  # gyro and accel on
    wr(bus, 0x04, 0x07)
    emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.5, -1.0, 2.0),
                                   specific_force_m_s2=(1.0, -9.0, 3.5),
                                   temperature_degc=31.0))
    for little_endian in (False, True):
        wr(bus, 0x16, 0x02 if little_endian else 0x00)
        clock.sleep(0.05)
        emu._advance()
        single = bytes(emu._read((start + k) & 0x3F) for k in range(length))
        assert emu.words, "no measurement was latched"
        assert rd(bus, start, length) == single


def test_an_honest_rate_beyond_the_range_is_cut_before_the_low_pass_and_its_trace_fades() -> None:
    """The digital low-pass runs on the ADC's words (cut at 30000 counts), so a rotation
    that passes the range and comes back leaves outputs in range that read low by what the
    filter still carries of the cut, as a first-order filter of the datasheet bandwidth on
    the cut input does (within the world's own lag through the filter, which the emulator
    leaves out: tau times the rate's fastest change, 6 % of the full scale at 0.5 Hz). After
    the cut the outputs in range read up to 2.5 % of the full scale low (an emulator that cut
    each word alone would read them exactly); a rate in range with no cut before it reads
    as it is."""
    clock, bus, emu = spi()
    wr(bus, 0x01, 0x10)  # GYRO_CFG1: 10 Hz bandwidth, 2000 dps (15 LSB/dps)
    wr(bus, 0x02, 0x05)
    wr(bus, 0x00, 0x7F)
    bandwidth = emu.noise_bandwidth_hz(Quantity.GYRO)
    period = emu.noise_period_s(Quantity.GYRO)
    assert bandwidth == 10.0 and period is not None
    a = math.exp(-2 * math.pi * bandwidth * period)
    reference = 0.0
    off_in_range = []
    for k in range(int(2.0 / period)):
        t = (k + 1) * period
        world = 2500.0 * 15 * math.sin(2 * math.pi * 0.5 * t)  # counts, up to 1.25 x range
        emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.0, 0.0, math.radians(world / 15))))
        clock.sleep(period)
        word = int.from_bytes(rd(bus, 0x24, 6)[4:6], "big", signed=True)
        reference = a * reference + (1 - a) * max(-30000.0, min(30000.0, world))
        lag = 2500.0 * 15 * 2 * math.pi * 0.5 / (2 * math.pi * bandwidth)  # tau x max rate
        assert abs(word - reference) <= lag + 1.0
        if abs(world) < 30000:
            off_in_range.append(abs(word - world))
    assert max(off_in_range) > 0.01 * 30000  # the cut's trace, where the rate is in range
    assert min(off_in_range) <= 1.0  # before the first cut: the rate as it is
