"""The MPU-9250 emulator's INT pin, from the register map's side (RM-MPU-9250A-00 rev 1.4:
INT_PIN_CFG 0x37 ACTL [7], LATCH_INT_EN [5]; INT_ENABLE 0x38 FIFO_OFLOW_EN [4], RAW_RDY_EN
[0]; a 50 us pulse unless latched), and the emulated line it drives."""

from __future__ import annotations

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus
from imuhal.emulation.lines import KERNEL_QUEUE, EmulatedLine
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

MPU = 0x68
SMPLRT_DIV, CONFIG, FIFO_EN, INT_PIN_CFG, INT_ENABLE, INT_STATUS = \
    0x19, 0x1A, 0x23, 0x37, 0x38, 0x3A
USER_CTRL, PWR_MGMT_1 = 0x6A, 0x6B
MS = 1_000_000
PERIOD_NS = 5 * MS  # 1 kHz / (1 + 4)


class Rig:
    def __init__(self, int_enable: int = 0x01, pin_cfg: int = 0x00) -> None:
        self.clock = SimulatedClock()
        self.bus = EmulatedBus("host", BusKind.I2C)
        self.mpu = self.bus.attach(MPU, MPU9250Emulator(self.clock))
        self.write(PWR_MGMT_1, 0x01)
        self.write(CONFIG, 0x03)  # DLPF 41 Hz: 1 kHz internal
        self.write(SMPLRT_DIV, 4)  # 200 Hz, sampling restarts at t = 0
        self.write(INT_PIN_CFG, pin_cfg)
        self.write(INT_ENABLE, int_enable)

    def write(self, reg: int, value: int) -> None:
        self.bus.transfer(MPU, bytes([reg, value]), 0)

    def read(self, reg: int, n: int = 1) -> bytes:
        return self.bus.transfer(MPU, bytes([reg]), n)


def test_data_ready_asserts_the_pin_at_every_sample_instant() -> None:
    rig = Rig()
    assert rig.mpu.interrupt_after(0) == PERIOD_NS
    assert rig.mpu.interrupt_after(PERIOD_NS) == 2 * PERIOD_NS
    assert rig.mpu.interrupt_after(PERIOD_NS + 1) == 2 * PERIOD_NS


def test_without_an_enabled_interrupt_or_asleep_the_pin_stays_quiet() -> None:
    assert Rig(int_enable=0x00).mpu.interrupt_after(0) is None
    rig = Rig()
    rig.write(PWR_MGMT_1, 0x40)  # SLEEP
    assert rig.mpu.interrupt_after(0) is None


def test_a_stuck_measurement_engine_raises_no_data_ready() -> None:
    rig = Rig()
    rig.mpu.stuck_data_ready = True
    assert rig.mpu.interrupt_after(0) is None


def test_the_pin_is_an_active_high_50_us_pulse_unless_configured_otherwise() -> None:
    assert Rig().mpu.interrupt_pin() == (True, 50_000)
    assert Rig(pin_cfg=0x80).mpu.interrupt_pin() == (False, 50_000)  # ACTL: active low
    assert Rig(pin_cfg=0x20).mpu.interrupt_pin() == (True, 0)  # LATCH_INT_EN


def test_a_latched_pin_asserts_again_only_after_the_status_is_read() -> None:
    rig = Rig(pin_cfg=0x20)
    rig.clock.sleep_until(PERIOD_NS)  # the first sample: the pin goes active and stays
    assert rig.mpu.interrupt_after(PERIOD_NS) is None
    rig.read(INT_STATUS)  # read to clear
    assert rig.mpu.interrupt_after(PERIOD_NS) == 2 * PERIOD_NS


def test_fifo_overflow_alone_asserts_at_the_sample_that_finds_the_fifo_full() -> None:
    rig = Rig(int_enable=0x10)  # FIFO_OFLOW_EN only
    rig.write(FIFO_EN, 0x78)  # gyro and accel: 12 bytes a sample, 42 fit in 512
    rig.write(USER_CTRL, 0x44)  # FIFO on, reset
    assert rig.mpu.interrupt_after(0) == 43 * PERIOD_NS


def test_an_emulated_line_reports_the_rising_edges_of_an_active_high_pulse() -> None:
    rig = Rig()
    line = EmulatedLine("int", rig.mpu, rig.clock, "rising")
    rig.clock.sleep_until(3 * PERIOD_NS)
    assert [(e.t_ns, e.seqno) for e in line.take_edges()] == \
        [(PERIOD_NS, 1), (2 * PERIOD_NS, 2), (3 * PERIOD_NS, 3)]
    assert line.next_edge_ns() == 4 * PERIOD_NS


def test_an_active_low_pulse_rises_at_its_end() -> None:
    rig = Rig(pin_cfg=0x80)
    rising = EmulatedLine("int", rig.mpu, rig.clock, "rising")
    both = EmulatedLine("int", rig.mpu, rig.clock, "both")
    assert rising.next_edge_ns() == PERIOD_NS + 50_000
    rig.clock.sleep_until(PERIOD_NS + 50_000)
    assert [e.t_ns for e in both.take_edges()] == [PERIOD_NS, PERIOD_NS + 50_000]


def test_an_unread_line_keeps_the_newest_edges_and_numbers_every_one() -> None:
    rig = Rig()
    line = EmulatedLine("int", rig.mpu, rig.clock, "rising")
    rig.clock.sleep_until(40 * PERIOD_NS)
    edges = line.take_edges()
    assert len(edges) == KERNEL_QUEUE
    assert [e.seqno for e in edges] == list(range(41 - KERNEL_QUEUE, 41))
