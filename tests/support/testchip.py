"""A small fictional chip, used to test the core without depending on any real driver.

"TC3" is a 3-axis accelerometer plus a float32 pressure output:
  0x0F WHO_AM_I = 0x5A; 0x20 CTRL (bits 1:0 ODR code 0=off, 1=50 Hz, 2=100 Hz);
  0x27 STATUS bit0 = new data; 0x28..0x2D accel X,Y,Z int16 little-endian, 1 mg/LSB
  (reading 0x2D clears STATUS); 0x30..0x33 pressure float32 little-endian, Pa.
Reads auto-increment. It is registered as a plugin through the same hooks as real chips.
"""

from __future__ import annotations

import struct
from typing import ClassVar, Literal

from imuhal.bus.base import BusKind
from imuhal.bus.registers import RegisterView
from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.errors import DeviceNotFoundError, NackError
from imuhal.core.samples import AccelSample, PressureSample, Quantity, SampleFlag
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal.emulation import ChipEmulator
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.hookspecs import hookimpl

G = 9.80665
WHO_AM_I, CTRL, STATUS, DATA, PRESSURE = 0x0F, 0x20, 0x27, 0x28, 0x30
IDENTITY = 0x5A
ODR_CODES = {50: 1, 100: 2}


class TC3Settings(DriverSettings):
    odr_hz: Literal[50, 100] = 50
    pressure_first: bool = False
    """Emit the pressure sample before the accelerometer sample of the same poll."""


class TC3Driver(Driver):
    name: ClassVar[str] = "tc3"
    description: ClassVar[str] = "fictional test chip (tests only)"
    Settings = TC3Settings
    channels = (Quantity.ACCEL, Quantity.PRESSURE)
    bus_kinds = frozenset({BusKind.I2C, BusKind.SPI})

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.regs = RegisterView(self.link)

    def probe(self) -> DeviceIdentity:
        try:
            found = self.regs.read_u8(WHO_AM_I)
        except NackError:
            raise DeviceNotFoundError(driver=self.name, bus=self.link.bus.name,
                                      address=self.link.target, expected="WHO_AM_I=0x5A",
                                      found="no answer", hint="check wiring") from None
        if found != IDENTITY:
            raise DeviceNotFoundError(driver=self.name, bus=self.link.bus.name,
                                      address=self.link.target, expected="WHO_AM_I=0x5A",
                                      found=f"WHO_AM_I=0x{found:02X}")
        return DeviceIdentity(self.name, self.link.bus.name, self.link.target, "WHO_AM_I=0x5A")

    def configure(self) -> None:
        self.regs.write(CTRL, ODR_CODES[self.settings.odr_hz])

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.settings.odr_hz)

    def poll(self, now_ns: int) -> PollResult:
        raw = self.regs.read(STATUS, 13)
        if not raw[0] & 1:
            return PollResult([], now_ns + self.period_ns)
        x, y, z = struct.unpack_from("<hhh", raw, 1)
        (p,) = struct.unpack_from("<f", raw, 9)
        accel = AccelSample(t_ns=now_ns, device=self.device,
                            accel_m_s2=(x * 1e-3 * G, y * 1e-3 * G, z * 1e-3 * G))
        if max(abs(x), abs(y), abs(z)) >= 32767:
            accel = accel.flagged(SampleFlag.SATURATED)
        pressure = PressureSample(t_ns=now_ns, device=self.device, pressure_pa=p)
        samples = [pressure, accel] if self.settings.pressure_first else [accel, pressure]
        return PollResult(samples, now_ns + self.period_ns)

    def full_scale(self, channel: Quantity) -> float | None:
        """Accel: 32767 counts of 1 mg; pressure: not declared (float32 register)."""
        return 32.767 * G if channel is Quantity.ACCEL else None


class TC3Emulator(ChipEmulator):
    chip = "tc3"

    def __init__(self, clock=None) -> None:  # type: ignore[no-untyped-def]
        super().__init__(clock)
        self.regs = bytearray(0x40)
        self.regs[WHO_AM_I] = IDENTITY
        self.pointer = 0
        self.last_sample_ns: int | None = None

    def _refresh(self) -> None:
        code = self.regs[CTRL] & 3
        if code == 0:
            return
        period = round(1e9 / {1: 50, 2: 100}[code])
        now = self.now_ns()
        if self.last_sample_ns is not None and now - self.last_sample_ns < period:
            return
        self.last_sample_ns = now
        f = self.physics.specific_force_m_s2 or (0.0, 0.0, 0.0)
        counts = [max(-32767, min(32767, round(v / G * 1e3))) for v in f]
        struct.pack_into("<hhh", self.regs, DATA, *counts)
        p = self.physics.pressure_pa if self.physics.pressure_pa is not None else 0.0
        struct.pack_into("<f", self.regs, PRESSURE, p)
        self.regs[STATUS] = 1

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if not write:
            return bytes(read_len)
        addr = write[0] & 0x7F
        if len(write) > 1:
            for i, b in enumerate(write[1:]):
                self.regs[(addr + i) & 0x3F] = b
            return b""
        self._refresh()
        out = bytes(self.regs[(addr + i) & 0x3F] for i in range(read_len))
        if addr <= 0x2D < addr + read_len:
            self.regs[STATUS] = 0
        return out


@hookimpl
def imuhal_register_drivers(register) -> None:  # type: ignore[no-untyped-def]
    register(TC3Driver)


@hookimpl
def imuhal_register_emulators(register) -> None:  # type: ignore[no-untyped-def]
    register(TC3Emulator)


class RecorderSettings(EstimatorSettings):
    pass


class Recorder(Estimator):
    """Records what the pipeline hands it and echoes one VerticalEstimate per pressure."""

    name: ClassVar[str] = "recorder"
    Settings = RecorderSettings
    consumes = (AccelSample, PressureSample)

    def reset(self) -> None:
        self.seen: list[object] = []

    def process(self, item):  # type: ignore[no-untyped-def]
        self.seen.append(item)
        if isinstance(item, PressureSample):
            return [VerticalEstimate(t_ns=item.t_ns, source=self.instance,
                                     altitude_m=altitude_m_from_pressure(item.pressure_pa),
                                     climb_m_s=0.0)]
        return []

    def get_state(self) -> dict:  # type: ignore[type-arg]
        return {"seen": len(self.seen)}

    def set_state(self, state) -> None:  # type: ignore[no-untyped-def]
        pass


@hookimpl
def imuhal_register_estimators(register) -> None:  # type: ignore[no-untyped-def]
    register(Recorder)
