"""The MAX21100 emulator's slave auto-read, register by register, from the chip facts
(facts/chips.md section 6, "MAX21100 I2C master reading an HMC5883L", steps 4-5): MAG_SLV_CFG
0x07 (bit 7 enable, bit 6 byte-order swap, [2:0] byte count), MAG_SLV_ADD 0x08, MAG_SLV_REG
0x09, MAG_MAP_REG 0x0A (0x00 as read, 0x08 the HMC5883L's X, Z, Y to X, Y, Z), ACC_CFG2 0x06
[3:1] (the slave every 2^code accelerometer measurements) and MAG X/Y/Z at 0x30..0x35.

Register numbers and values are written here from the facts, not imported from the driver.
"""

from __future__ import annotations

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import ChipEmulator, EmulatedBus
from imuhal_chips.max2110x.emulator import Max21100Emulator

SLAVE = 0x1E
ACCEL_PERIOD_S = 0.004  # ACC_CFG1 code 3: 250 Hz
SLAVE_BYTES = bytes([0x01, 0x82, 0x03, 0x84, 0x05, 0x86])
"""What the slave holds at registers 3..8: three big-endian words 0x0182, 0x0384, 0x0586."""


class RegisterFile(ChipEmulator):
    """An I2C slave with 16 registers and an auto-incrementing pointer, logging each
    transaction."""

    chip = "register-file"

    def __init__(self) -> None:
        super().__init__()
        self.regs = bytearray(16)
        self.regs[3:9] = SLAVE_BYTES
        self.log: list[tuple[bytes, int]] = []

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self.log.append((write, read_len))
        start = write[0] if write else 0
        return bytes(self.regs[(start + k) % 16] for k in range(read_len))


def board(mag_slv_cfg: int = 0x86, mag_map: int = 0x00, acc_cfg2: int = 0x00
          ) -> tuple[SimulatedClock, EmulatedBus, Max21100Emulator, RegisterFile]:
    """A MAX21100 on SPI measuring at 250 Hz with the slave auto-read programmed as
    har-in-air does (step 1: 0x06; step 2: 0x08; step 4: 0x09, 0x0A, 0x07 last)."""
    clock = SimulatedClock()
    spi = EmulatedBus("spi0", BusKind.SPI)
    chip = spi.attach(0, Max21100Emulator(clock))
    slave = chip.child_buses()["aux"].attach(SLAVE, RegisterFile())
    for reg, value in ((0x05, 0x03), (0x06, acc_cfg2), (0x08, SLAVE), (0x09, 0x03),
                       (0x0A, mag_map), (0x07, mag_slv_cfg), (0x13, 0x01), (0x00, 0x7F)):
        spi.transfer(0, bytes([reg, value]))
    return clock, spi, chip, slave


def mag_registers(spi: EmulatedBus) -> bytes:
    return spi.transfer(0, bytes([0x80 | 0x30]), 6)


def test_an_enabled_auto_read_copies_the_slave_bytes_at_the_accelerometer_measurement() -> None:
    clock, spi, _, slave = board()
    assert mag_registers(spi) == bytes(6)  # nothing measured yet
    clock.sleep(ACCEL_PERIOD_S)
    assert mag_registers(spi) == SLAVE_BYTES
    assert slave.log == [(b"\x03", 6)]  # one transaction: register 3, six bytes read


def test_the_20_byte_burst_from_0x24_carries_the_slave_at_offsets_12_to_17() -> None:
    clock, spi, _, _ = board()
    clock.sleep(ACCEL_PERIOD_S)
    burst = spi.transfer(0, bytes([0x80 | 0x24]), 20)
    assert burst[12:18] == SLAVE_BYTES


def test_map_0x08_turns_the_hmc5883l_x_z_y_words_into_x_y_z() -> None:
    clock, spi, _, _ = board(mag_map=0x08)
    clock.sleep(ACCEL_PERIOD_S)
    x, z, y = SLAVE_BYTES[0:2], SLAVE_BYTES[2:4], SLAVE_BYTES[4:6]
    assert mag_registers(spi) == x + y + z


def test_a_map_written_between_copies_of_the_same_slave_bytes_applies_at_the_next() -> None:
    # the words are stored again when the map changes, though the slave's bytes repeat
    clock, spi, _, slave = board()
    clock.sleep(ACCEL_PERIOD_S)
    assert mag_registers(spi) == SLAVE_BYTES
    spi.transfer(0, bytes([0x0A, 0x08]))
    clock.sleep(ACCEL_PERIOD_S)
    x, z, y = SLAVE_BYTES[0:2], SLAVE_BYTES[2:4], SLAVE_BYTES[4:6]
    assert mag_registers(spi) == x + y + z
    assert len(slave.log) == 2


def test_the_swap_bit_takes_each_slave_word_lsb_first() -> None:
    clock, spi, _, _ = board(mag_slv_cfg=0xC6)  # Kris Winer's LIS3MDL value
    clock.sleep(ACCEL_PERIOD_S)
    assert mag_registers(spi) == bytes([0x82, 0x01, 0x84, 0x03, 0x86, 0x05])


def test_the_words_follow_the_configured_output_byte_order() -> None:
    clock, spi, _, _ = board()
    spi.transfer(0, bytes([0x16, 0x02]))  # I2C_CFG bit 1: little-endian data registers
    clock.sleep(ACCEL_PERIOD_S)
    assert mag_registers(spi) == bytes([0x82, 0x01, 0x84, 0x03, 0x86, 0x05])


def test_the_byte_count_is_what_the_master_reads() -> None:
    clock, spi, _, slave = board(mag_slv_cfg=0x84)
    clock.sleep(ACCEL_PERIOD_S)
    # [UNVERIFIED] behaviour for fewer than six: the first four bytes replaced, the rest kept
    assert mag_registers(spi) == SLAVE_BYTES[:4] + bytes(2)
    assert slave.log == [(b"\x03", 4)]


def test_acc_cfg2_code_sets_how_many_accelerometer_measurements_per_slave_read() -> None:
    for code, reads in ((0, 16), (1, 8), (2, 4)):
        clock, spi, _, slave = board(acc_cfg2=code << 1)
        for _ in range(16):
            clock.sleep(ACCEL_PERIOD_S)
            spi.transfer(0, bytes([0x80 | 0x23]), 1)  # an access carries the latch out
        assert len(slave.log) == reads, code


def test_without_the_enable_bit_the_slave_is_never_read() -> None:
    clock, spi, _, slave = board(mag_slv_cfg=0x06)
    clock.sleep(10 * ACCEL_PERIOD_S)
    assert mag_registers(spi) == bytes(6) and slave.log == []


def test_a_soft_reset_stops_the_auto_read() -> None:
    clock, spi, _, slave = board()
    clock.sleep(ACCEL_PERIOD_S)
    mag_registers(spi)
    spi.transfer(0, bytes([0x3F, 0x08]))  # RST_REG soft reset: MAG_SLV_CFG back to 0
    spi.transfer(0, bytes([0x00, 0x7F]))
    clock.sleep(10 * ACCEL_PERIOD_S)
    assert len(slave.log) == 1
    assert mag_registers(spi) == bytes(6)


def test_a_slave_that_does_not_answer_leaves_the_last_data_and_is_counted() -> None:
    clock, spi, chip, slave = board()
    clock.sleep(ACCEL_PERIOD_S)
    assert mag_registers(spi) == SLAVE_BYTES
    slave.absent = True  # NACK from now on
    slave.regs[3] = 0x7F
    clock.sleep(3 * ACCEL_PERIOD_S)
    spi.transfer(0, bytes([0x80 | 0x23]), 1)
    assert mag_registers(spi) == SLAVE_BYTES
    assert chip.slave_read_failures >= 1


def test_inversion_bit_0_negates_mag_x() -> None:
    """[SS]: MAG_MAP_REG [2:0] = INV_Z, INV_Y, INV_X (one code base names the fields)."""
    clock, spi, _, _ = board(mag_map=0x01)
    clock.sleep(ACCEL_PERIOD_S)
    x = (-0x0182) & 0xFFFF
    assert mag_registers(spi) == x.to_bytes(2, "big") + SLAVE_BYTES[2:]
