"""The MAX21105's and MAX21100's INT1 pin as their emulators model it: a data-ready pulse per
measurement. For the MAX21105 the registers and the example's values below are its user
guide's [DS]; the pulse's width and the modes not modelled are as stated for both.

Known (imuhal's chip facts, section 6) [V]: the MAX21100's interrupt registers are in bank 1
(0x00..0x0F) with INT_SRC_SEL at 0x17. Their bits are documented only for the MAX21105
(user guide rev 1.4, facts section 5, whose DATA_READY interrupt example writes bank 1:
INT_SRC_CFG 0x17 <- 0x30 gyro_dr + acc_dr, INT_MSK 0x0F <- 0x80, INT_TMO_CFG 0x0C <- 0x00
unlatched, INT_CFG_2 0x0B <- 0x20 INT1 enable; har-in-air's MAX21105 code writes 0x20, the
gyro's data-ready alone). The emulator takes them for the MAX21100, [UNVERIFIED]:

- INT1 asserts at each measurement of a channel whose data-ready source is selected
  (INT_SRC_SEL bit 5 gyro, bit 4 accelerometer), when INT_CFG_2 bit 5 (INT1 enable) and
  INT_MSK bit 7 are set, the chip measuring;
- active high, a pulse of ``INT_PULSE_NS`` (INT_TMO_CFG 0x00 "unlatched"; the pulse's width
  is not documented for either part: 50 us, the MPU-9250's, is assumed). Other INT_TMO_CFG
  values (latched modes) and the other interrupt sources (the motion engine, the FIFO's
  threshold) are not modelled: the pin then stays quiet.
"""

from __future__ import annotations

from typing import Final

INT_CFG_2: Final = 0x0B
INT_TMO_CFG: Final = 0x0C
INT_MSK: Final = 0x0F
INT_SRC_SEL: Final = 0x17
INT1_ENABLE: Final = 0x20
"""INT_CFG_2 bit 5."""
INT_MSK_ENABLE: Final = 0x80
SRC_GYRO_DR: Final = 0x20
SRC_ACCEL_DR: Final = 0x10
INT_PULSE_NS: Final = 50_000
