"""MPU-9250 (InvenSense) register map and setting tables: setting -> code -> sensitivity.

Source of the register facts: InvenSense MPU-9250 Register Map and Descriptions
RM-MPU-9250A-00 rev 1.4 (register table, DLPF tables, I2C master, INT_PIN_CFG bypass),
cross-checked with Linux ``drivers/iio/imu/inv_mpu6050`` (WHO_AM_I 0x71/0x73, scale tables,
temperature scale) and har-in-air ``mpu9250.cpp``; imuhal shared chip facts, section 4.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

I2C_ADDRESSES: Final = (0x68, 0x69)
"""AD0 low -> 0x68, AD0 high -> 0x69."""
SPI_READ: Final = 0x80

SMPLRT_DIV: Final = 0x19
CONFIG: Final = 0x1A
GYRO_CONFIG: Final = 0x1B
ACCEL_CONFIG: Final = 0x1C
ACCEL_CONFIG2: Final = 0x1D
I2C_MST_CTRL: Final = 0x24
I2C_SLV0_ADDR: Final = 0x25
I2C_SLV0_REG: Final = 0x26
I2C_SLV0_CTRL: Final = 0x27
I2C_SLV4_ADDR: Final = 0x31
I2C_SLV4_REG: Final = 0x32
I2C_SLV4_DO: Final = 0x33
I2C_SLV4_CTRL: Final = 0x34
I2C_SLV4_DI: Final = 0x35
I2C_MST_STATUS: Final = 0x36
I2C_SLV0_DO: Final = 0x63
I2C_MST_DELAY_CTRL: Final = 0x67
INT_PIN_CFG: Final = 0x37
INT_ENABLE: Final = 0x38
INT_STATUS: Final = 0x3A
ACCEL_XOUT_H: Final = 0x3B
TEMP_OUT_H: Final = 0x41
GYRO_XOUT_H: Final = 0x43
EXT_SENS_DATA_00: Final = 0x49
SIGNAL_PATH_RESET: Final = 0x68
USER_CTRL: Final = 0x6A
PWR_MGMT_1: Final = 0x6B
PWR_MGMT_2: Final = 0x6C
WHO_AM_I: Final = 0x75

WHO_AM_I_MPU9250: Final = 0x71
WHO_AM_I_MPU9255: Final = 0x73

# bits
PWR1_H_RESET: Final = 0x80
PWR1_SLEEP: Final = 0x40
PWR1_CLKSEL_AUTO: Final = 0x01
USER_I2C_MST_EN: Final = 0x20
USER_I2C_IF_DIS: Final = 0x10
INT_PIN_BYPASS_EN: Final = 0x02
INT_PIN_ANYRD_2CLEAR: Final = 0x10
INT_RAW_RDY: Final = 0x01
SLV_EN: Final = 0x80
SLV_READ: Final = 0x80
SLV_BYTE_SW: Final = 0x40
SLV_REG_DIS: Final = 0x20
SLV_GRP: Final = 0x10
SLV_LENG: Final = 0x0F
MST_SLV4_DONE: Final = 0x40
MST_SLV4_NACK: Final = 0x10
MST_SLV0_NACK: Final = 0x01
I2C_MST_CLK_400KHZ: Final = 0x0D
I2C_MST_WAIT_FOR_ES: Final = 0x40
"""I2C_MST_CTRL bit 6: the data-ready interrupt waits until the slaves' data are loaded
into EXT_SENS_DATA (Linux inv_mpu6050 sets it with slave-0 reads)."""
SLV0_DLY_EN: Final = 0x01
"""I2C_MST_DELAY_CTRL bit 0: slave 0 is accessed only every 1 + I2C_MST_DLY samples
(I2C_SLV4_CTRL[4:0]); clear (the default), at every sample."""
EXT_SENS_DATA_BYTES: Final = 24
"""EXT_SENS_DATA_00..23 (0x49..0x60)."""

DATA_BURST_START: Final = INT_STATUS
DATA_BURST_LENGTH: Final = 15
"""INT_STATUS, ACCEL_XOUT_H..GYRO_ZOUT_L: status and one coherent sample in one burst."""
MASTER_STATUS_BYTES: Final = DATA_BURST_START - I2C_MST_STATUS
"""With a slave auto-read the burst starts at I2C_MST_STATUS (0x36): it, INT_PIN_CFG,
INT_ENABLE and 0x39 (not in the register map; DMP_INT_STATUS on the InvenSense parts
that document it; unused here) come before INT_STATUS, so SLV0_NACK arrives with the
slave's copy it concerns."""

RESET_S: Final = 0.1
"""Wait after H_RESET (Linux waits 100 ms)."""
WAKE_S: Final = 0.01

TEMP_LSB_PER_DEGC: Final = 333.87
TEMP_OFFSET_DEGC: Final = 21.0
"""T = TEMP_OUT / 333.87 + 21 degC (RoomTemp_Offset 0 at 21 degC)."""

STANDARD_GRAVITY_M_S2: Final = 9.80665


@dataclass(frozen=True)
class Range:
    """One full-scale setting: FS_SEL code and its sensitivity (LSB per dps or per g)."""

    fs_sel: int
    lsb_per_unit: float

    @property
    def config_value(self) -> int:
        return self.fs_sel << 3


GYRO_RANGES: Final[dict[int, Range]] = {
    250: Range(0, 131.0), 500: Range(1, 65.5), 1000: Range(2, 32.8), 2000: Range(3, 16.4),
}
"""gyro_range_dps -> GYRO_CONFIG.GYRO_FS_SEL and LSB/(deg/s)."""

ACCEL_RANGES: Final[dict[int, Range]] = {
    2: Range(0, 16384.0), 4: Range(1, 8192.0), 8: Range(2, 4096.0), 16: Range(3, 2048.0),
}
"""accel_range_g -> ACCEL_CONFIG.ACCEL_FS_SEL and LSB/g."""


@dataclass(frozen=True)
class GyroFilter:
    """CONFIG.DLPF_CFG with GYRO_CONFIG.Fchoice_b = 00, and the internal sample rate."""

    dlpf_cfg: int
    internal_rate_hz: int

    @property
    def divider_applies(self) -> bool:
        """SMPLRT_DIV only acts when 0 < DLPF_CFG < 7 (1 kHz internal rate)."""
        return 0 < self.dlpf_cfg < 7


GYRO_DLPF: Final[dict[int, GyroFilter]] = {
    250: GyroFilter(0, 8000), 184: GyroFilter(1, 1000), 92: GyroFilter(2, 1000),
    41: GyroFilter(3, 1000), 20: GyroFilter(4, 1000), 10: GyroFilter(5, 1000),
    5: GyroFilter(6, 1000), 3600: GyroFilter(7, 8000),
}
"""gyro_dlpf_hz (gyro bandwidth) -> DLPF_CFG and internal rate."""

ACCEL_DLPF: Final[dict[int, int]] = {
    460: 0x00, 184: 0x01, 92: 0x02, 41: 0x03, 20: 0x04, 10: 0x05, 5: 0x06, 1130: 0x08,
}
"""accel_dlpf_hz -> ACCEL_CONFIG2 (accel_fchoice_b in bit 3, A_DLPFCFG in bits 2:0)."""


def sample_rate_hz(gyro_filter: GyroFilter, smplrt_div: int) -> float:
    """SAMPLE_RATE = internal rate / (1 + SMPLRT_DIV) where the divider applies."""
    if not gyro_filter.divider_applies:
        return float(gyro_filter.internal_rate_hz)
    return gyro_filter.internal_rate_hz / (1 + smplrt_div)


def gyro_filter_from_config(config: int, gyro_config: int) -> tuple[int, float]:
    """(internal rate Hz, divider applies) read back from CONFIG and GYRO_CONFIG codes."""
    if gyro_config & 0b11:
        return 32000, False
    dlpf = config & 0b111
    return (1000 if 0 < dlpf < 7 else 8000), 0 < dlpf < 7

# -- FIFO (register map rev 1.4; imuhal shared chip facts section 4, "FIFO") ----------------
FIFO_EN: Final = 0x23
"""[7] TEMP_OUT, [6] GYRO_XOUT, [5] GYRO_YOUT, [4] GYRO_ZOUT, [3] ACCEL (X, Y, Z), [2] SLV2,
[1] SLV1, [0] SLV0 (the slave's EXT_SENS_DATA bytes)."""
FIFO_TEMP: Final = 0x80
FIFO_GYRO_X: Final = 0x40
FIFO_GYRO_Y: Final = 0x20
FIFO_GYRO_Z: Final = 0x10
FIFO_ACCEL: Final = 0x08
FIFO_SLV0: Final = 0x01
FIFO_COUNTH: Final = 0x72
"""FIFO_COUNTH[4:0] and FIFO_COUNTL: the bytes in the FIFO (13 bits, big-endian)."""
FIFO_R_W: Final = 0x74
"""Each byte read pops one byte; a burst read of N bytes pops N (no auto-increment)."""
FIFO_SIZE_BYTES: Final = 512
USER_FIFO_EN: Final = 0x40
USER_FIFO_RST: Final = 0x04
CONFIG_FIFO_MODE: Final = 0x40
"""1: when the FIFO is full further writes are dropped; 0: the oldest bytes are overwritten."""
INT_FIFO_OFLOW: Final = 0x10
"""INT_ENABLE.FIFO_OFLOW_EN / INT_STATUS.FIFO_OFLOW_INT."""
