"""The MPU-9250 emulator driven the way public drivers drive the chip, not the way imuhal's
driver does: the AK8963 configured through I2C-master slave-0 *writes*, then read through the
slave-0 auto-read into EXT_SENS_DATA (the sequence of the common Arduino/embedded MPU-9250
libraries: I2C_SLV0_ADDR without the read bit, I2C_SLV0_REG, I2C_SLV0_DO, I2C_SLV0_CTRL =
EN | 1, wait; then I2C_SLV0_ADDR with the read bit and LENG bytes).

Register numbers and conversions are written here from the MPU-9250 register map (rev 1.4),
section 4 (MPU registers) and section 5 (AK8963), not imported from imuhal's driver.
"""

from __future__ import annotations

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

MPU, AK = 0x68, 0x0C
PWR_MGMT_1, USER_CTRL, I2C_MST_CTRL = 0x6B, 0x6A, 0x24
I2C_SLV0_ADDR, I2C_SLV0_REG, I2C_SLV0_CTRL, I2C_SLV0_DO = 0x25, 0x26, 0x27, 0x63
EXT_SENS_DATA_00 = 0x49
AK_WIA, AK_HXL, AK_CNTL1, AK_CNTL2, AK_ASAX = 0x00, 0x03, 0x0A, 0x0B, 0x10
FIELD_UT = (23.4, -17.9, 41.2)


class PublicStyleDriver:
    """The register sequence of a typical public MPU-9250 + AK8963 driver."""

    def __init__(self, link: Link, clock: SimulatedClock) -> None:
        self.link, self.clock = link, clock

    def write(self, reg: int, value: int) -> None:
        self.link.transfer(bytes([reg, value]))

    def read(self, reg: int, n: int) -> bytes:
        return self.link.transfer(bytes([reg]), n)

    def ak_write(self, reg: int, value: int) -> None:
        self.write(I2C_SLV0_ADDR, AK)  # read bit clear: a write transaction
        self.write(I2C_SLV0_REG, reg)
        self.write(I2C_SLV0_DO, value)
        self.write(I2C_SLV0_CTRL, 0x80 | 1)  # enable, one byte
        self.clock.sleep(0.010)

    def ak_read(self, reg: int, n: int) -> bytes:
        self.write(I2C_SLV0_ADDR, AK | 0x80)
        self.write(I2C_SLV0_REG, reg)
        self.write(I2C_SLV0_CTRL, 0x80 | n)
        self.clock.sleep(0.010)
        return self.read(EXT_SENS_DATA_00, n)

    def begin(self) -> tuple[int, tuple[int, int, int]]:
        """(WIA, ASA bytes) after configuring continuous 100 Hz 16-bit measurement."""
        self.write(PWR_MGMT_1, 0x01)  # PLL clock, awake
        self.write(USER_CTRL, 0x20)  # I2C_MST_EN
        self.write(I2C_MST_CTRL, 0x0D)  # 400 kHz
        self.ak_write(AK_CNTL2, 0x01)  # soft reset
        wia = self.ak_read(AK_WIA, 1)[0]
        self.ak_write(AK_CNTL1, 0x00)  # power down
        self.ak_write(AK_CNTL1, 0x0F)  # fuse ROM access
        asa = self.ak_read(AK_ASAX, 3)
        self.ak_write(AK_CNTL1, 0x00)
        self.ak_write(AK_CNTL1, 0x16)  # continuous mode 2 (100 Hz), 16-bit output
        self.ak_read(AK_HXL, 7)  # from now on slave 0 reads HXL..ST2 at every sample
        return wia, (asa[0], asa[1], asa[2])

    def field_ut(self, asa: tuple[int, int, int]) -> tuple[float, ...]:
        data = self.read(EXT_SENS_DATA_00, 7)
        counts = [int.from_bytes(data[i:i + 2], "little", signed=True) for i in (0, 2, 4)]
        assert data[6] & 0x10, "ST2.BITM: 16-bit output"
        # Hadj = H * ((ASA - 128) * 0.5 / 128 + 1), 0.15 uT per LSB at 16 bit.
        return tuple(c * 0.15 * ((a - 128) * 0.5 / 128 + 1) for c, a in zip(counts, asa,
                                                                             strict=True))


def board() -> tuple[SimulatedClock, MPU9250Emulator, AK8963Emulator, PublicStyleDriver]:
    clock = SimulatedClock()
    bus = EmulatedBus("host", BusKind.I2C)
    mpu = bus.attach(MPU, MPU9250Emulator(clock))
    ak = mpu.aux_bus.attach(AK, AK8963Emulator(clock))
    return clock, mpu, ak, PublicStyleDriver(bus.link(MPU), clock)


def test_slave0_writes_configure_the_ak8963() -> None:
    _clock, _mpu, ak, drv = board()
    wia, asa = drv.begin()
    assert wia == 0x48
    assert asa == ak.asa  # read in fuse-ROM mode, which only a slave-0 write can enter
    assert ak.bus_transfer(BusKind.I2C, bytes([AK_CNTL1]), 1) == bytes([0x16])


def test_slave0_auto_read_delivers_the_true_field() -> None:
    clock, _mpu, ak, drv = board()
    _, asa = drv.begin()
    ak.set_physics(PhysicalInputs(magnetic_field_ut=FIELD_UT))
    clock.sleep(0.025)  # two 100 Hz measurements, each copied by the next MPU sample
    got = drv.field_ut(asa)
    for axis in range(3):
        # One 16-bit step (0.15 uT) times the largest adjustment the part can have (1.5).
        assert abs(got[axis] - FIELD_UT[axis]) <= 0.15 * 1.5, (axis, got)


def test_without_slave0_writes_the_magnetometer_stays_powered_down() -> None:
    clock, _mpu, ak, drv = board()
    drv.write(PWR_MGMT_1, 0x01)
    drv.write(USER_CTRL, 0x20)
    ak.set_physics(PhysicalInputs(magnetic_field_ut=FIELD_UT))
    drv.ak_read(AK_HXL, 7)
    clock.sleep(0.025)
    assert drv.read(EXT_SENS_DATA_00, 6) == bytes(6)  # never measured: the test has teeth
