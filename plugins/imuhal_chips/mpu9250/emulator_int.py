"""The MPU-9250's INT pin as its emulator models it, from the register map's side.

RM-MPU-9250A-00 rev 1.4, INT_PIN_CFG (0x37): [7] ACTL, 1 = the pin is active low; [5]
LATCH_INT_EN, 1 = the pin is held active until the interrupt status is cleared, 0 = it
emits a 50 us pulse. (imuhal's chip facts list the bits; the pulse width is the register
map's.) The emulator asserts it where INT_STATUS would gain an enabled bit.
"""

from __future__ import annotations

from typing import Final

INT_ACTL: Final = 0x80
"""INT_PIN_CFG.ACTL: the INT pin is active low."""
INT_LATCH_INT_EN: Final = 0x20
"""INT_PIN_CFG.LATCH_INT_EN: the pin stays active until the status is cleared."""
INT_PULSE_NS: Final = 50_000
"""The INT pulse without LATCH_INT_EN: 50 us."""
