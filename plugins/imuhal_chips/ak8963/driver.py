"""AK8963 (AKM) 3-axis magnetometer driver, standalone or behind an MPU-9250.

Source of the register facts: MPU-9250 Register Map RM-MPU-9250A-00 rev 1.4 section 5 and
Linux ``inv_mpu_magn.c`` (imuhal shared chip facts, section 4).

The driver speaks plain I2C to address 0x0C. Inside an MPU-9250 (GY-91, MPU-9250 modules)
the AK8963 is reached through the MPU's ``aux`` child bus: its bypass (host I2C) or its
internal I2C master (also when the MPU is on SPI); this driver does not know which.

configure(): soft reset, fuse-ROM mode to read the sensitivity adjustment ASAX..ASAZ,
power-down, then continuous mode at ``odr_hz`` and ``resolution_bits``, read back and verified.
poll(): one burst ST1..ST2 (0x02..0x09): ST1.DRDY says whether it is new, and reading ST2 last
releases the data for the next measurement. HOFL -> SampleFlag.OVERFLOW (never valid);
a count at the data range limit -> SATURATED. Output: uT in the AK8963's own axes
(mag X = MPU accel Y, mag Y = MPU accel X, mag Z = -MPU accel Z); the profile's mount
rotation takes it to the body frame.
"""

from __future__ import annotations

import math
from typing import ClassVar, Literal

from imuhal.bus.base import BusKind, Link
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.core.errors import ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.samples import Channel, MagSample, SampleFlag
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal_chips.ak8963 import registers as r
from imuhal_chips.ak8963.decode import Measurement, decode_burst

BEHIND_MPU_HINT = (
    "inside an MPU-9250 the AK8963 answers only when the MPU's bypass is enabled or through "
    "its I2C master: put this device on the mpu9250's 'aux' bus"
)


class AK8963Settings(DriverSettings):
    """AK8963 settings: continuous measurement rate and output resolution."""

    odr_hz: Literal[8, 100] = 100
    """Continuous mode 1 (8 Hz) or 2 (100 Hz)."""
    resolution_bits: Literal[14, 16] = 16
    """14-bit (0.6 uT/LSB) or 16-bit (0.15 uT/LSB) output."""


class AK8963Driver(Driver):
    """AKM AK8963 magnetometer (the magnetometer die of the MPU-9250)."""

    name = "ak8963"
    description = "AKM AK8963 magnetometer, I2C 0x0C (inside the MPU-9250: use its aux bus)"
    Settings = AK8963Settings
    channels: ClassVar[tuple[Channel, ...]] = (Channel.MAG,)
    bus_kinds: ClassVar[frozenset[BusKind]] = frozenset({BusKind.I2C})

    STALE_AFTER_PERIODS = 2.5
    """No DRDY for this many periods: the sample slot is reported STALE."""
    CONFIG_CHECK_S = 1.0
    """How often CNTL1 is re-read to catch a silent reset."""

    def __init__(self, link: Link, settings: DriverSettings, *, device: str,
                 clock: Clock) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.settings: AK8963Settings
        self.regs = RegisterView(link)
        self.asa: tuple[int, int, int] = (128, 128, 128)
        self._cntl1 = r.cntl1_value(self.settings.odr_hz, self.settings.resolution_bits)
        self._period_ns = round(1e9 / self.settings.odr_hz)
        self._last_data_ns = 0
        self._next_check_ns = 0
        self.last: Measurement | None = None

    def _not_found(self, found: str, hint: str) -> DeviceNotFoundError:
        return DeviceNotFoundError(
            driver=self.name, bus=self.link.bus.name, address=self.link.target,
            expected=f"WIA 0x{r.WIA:02X} at register 0x{r.REG_WIA:02X}", found=found, hint=hint)

    def probe(self) -> DeviceIdentity:
        try:
            wia = self.regs.read_u8(r.REG_WIA)
        except NackError as exc:
            raise self._not_found("no answer (NACK)", BEHIND_MPU_HINT) from exc
        if wia != r.WIA:
            hint = (BEHIND_MPU_HINT if wia in (0x00, 0xFF)
                    else "another chip or an AK8963 clone answers at this address")
            raise self._not_found(f"0x{wia:02X}", hint)
        self.identity = DeviceIdentity(self.name, self.link.bus.name, self.link.target,
                                       f"WIA=0x{wia:02X}")
        return self.identity

    def _set_mode(self, value: int) -> None:
        self.regs.write(r.REG_CNTL1, value)
        self.clock.sleep(r.MODE_CHANGE_S)

    def configure(self) -> None:
        self.regs.write(r.REG_CNTL2, r.CNTL2_SRST)
        self.clock.sleep(r.RESET_S)
        # ASA is readable only in fuse-ROM mode; modes change only through power-down.
        self._set_mode(r.MODE_FUSE_ROM)
        asa = self.regs.read(r.REG_ASAX, 3)
        self.asa = (asa[0], asa[1], asa[2])
        self._set_mode(r.MODE_POWER_DOWN)
        self._set_mode(self._cntl1)
        back = self.regs.read_u8(r.REG_CNTL1)
        if back != self._cntl1:
            raise ConfigurationError(
                f"{self.describe()}: CNTL1 reads back 0x{back:02X}, wrote 0x{self._cntl1:02X}")

    def start(self, now_ns: int) -> int:
        # recover() passes the time from before configure() waited; never start in the past.
        now_ns = max(now_ns, self.clock.now_ns())
        self._last_data_ns = now_ns
        self._next_check_ns = now_ns + round(self.CONFIG_CHECK_S * 1e9)
        return now_ns + round(r.MEASUREMENT_S * 1e9)

    def _config_lost(self) -> bool:
        return self.regs.read_u8(r.REG_CNTL1) != self._cntl1

    def poll(self, now_ns: int) -> PollResult:
        overdue = now_ns - self._last_data_ns > self.STALE_AFTER_PERIODS * self._period_ns
        if overdue or now_ns >= self._next_check_ns:
            self._next_check_ns = now_ns + round(self.CONFIG_CHECK_S * 1e9)
            if self._config_lost():
                self.health.resets_detected += 1
                self.configure()
                self.health.reconfigurations += 1
                return PollResult([], self.start(self.clock.now_ns()))
        m = decode_burst(self.regs.read(r.DATA_BURST_START, r.DATA_BURST_LENGTH), self.asa)
        if not m.data_ready and not overdue:
            return PollResult([], now_ns + self._period_ns // 10)
        flags = SampleFlag.OK
        if not m.data_ready:
            flags |= SampleFlag.STALE
        if m.overflow:
            flags |= SampleFlag.OVERFLOW
        if m.saturated:
            flags |= SampleFlag.SATURATED
        field = m.field_ut if not (flags & SampleFlag.STALE) else (math.nan,) * 3
        sample = MagSample(t_ns=now_ns, device=self.device, flags=flags,
                           mag_ut=(field[0], field[1], field[2]))
        self._last_data_ns = now_ns
        if flags == SampleFlag.OK:
            self.last = m
        return PollResult([sample], now_ns + self._period_ns)

