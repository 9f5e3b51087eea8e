"""A plugin for a fictional 3-axis air-flow sensor: a vector quantity imuhal does not know
(used to test calibration of any vector quantity; nothing here is known to imuhal).

AF3 registers: 0x0F WHO_AM_I = 0xAF; 0x00..0x05 flow x, y, z, int16 little-endian,
1/1024 m/s per count. The emulated chip reads a fixed zero offset in still air
(``ZERO_OFFSET_M_S``), which a calibration should remove.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any, ClassVar

from imuhal.bus.base import BusKind
from imuhal.bus.registers import RegisterView
from imuhal.core.errors import DeviceNotFoundError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame, Vec3, VectorSample
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal.emulation import ChipEmulator
from imuhal.plugins import hookimpl

AIRFLOW = Quantity("airflow", "m/s", (3,), "Air velocity relative to the board.")
WHO_AM_I, DATA, IDENTITY = 0x0F, 0x00, 0xAF
M_S_PER_COUNT = 1.0 / 1024
ZERO_OFFSET_M_S: Vec3 = (0.5, -0.25, 0.125)


@dataclass(frozen=True, slots=True, kw_only=True)
class AirflowSample(VectorSample):
    """Air velocity in m/s."""

    airflow_m_s: Vec3 = field(default=(0.0, 0.0, 0.0))
    channel: ClassVar[Quantity] = AIRFLOW

    @property
    def vector(self) -> Vec3:
        return self.airflow_m_s

    def with_vector(self, vector: Vec3, frame: Frame) -> AirflowSample:
        return AirflowSample(t_ns=self.t_ns, device=self.device, flags=self.flags, frame=frame,
                             airflow_m_s=(float(vector[0]), float(vector[1]), float(vector[2])))


class AF3Settings(DriverSettings):
    odr_hz: float = 50.0


class AF3Driver(Driver):
    name: ClassVar[str] = "af3"
    description: ClassVar[str] = "fictional 3-axis air-flow sensor"
    Settings = AF3Settings
    channels = (AIRFLOW,)
    bus_kinds = frozenset({BusKind.I2C})

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.regs = RegisterView(self.link)

    def probe(self) -> DeviceIdentity:
        found = self.regs.read_u8(WHO_AM_I)
        if found != IDENTITY:
            raise DeviceNotFoundError(driver=self.name, bus=self.link.bus.name,
                                      address=self.link.target, expected="WHO_AM_I=0xAF",
                                      found=f"WHO_AM_I=0x{found:02X}")
        return DeviceIdentity(self.name, self.link.bus.name, self.link.target, "WHO_AM_I=0xAF")

    def configure(self) -> None:
        """Nothing to set: the chip measures continuously."""

    def poll(self, now_ns: int) -> PollResult:
        x, y, z = struct.unpack("<hhh", self.regs.read(DATA, 6))
        sample = AirflowSample(t_ns=now_ns, device=self.device,
                               airflow_m_s=(x * M_S_PER_COUNT, y * M_S_PER_COUNT,
                                            z * M_S_PER_COUNT))
        return PollResult([sample], now_ns + round(1e9 / self.settings.odr_hz))


class AF3Emulator(ChipEmulator):
    """Still air: the chip reads only its zero offset."""

    chip = "af3"

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if write and write[0] == WHO_AM_I:
            return bytes([IDENTITY])[:read_len]
        counts = [round(v / M_S_PER_COUNT) for v in ZERO_OFFSET_M_S]
        return struct.pack("<hhh", *counts)[:read_len]


@hookimpl
def imuhal_register_quantities(register: Any) -> None:
    register(AirflowSample)


@hookimpl
def imuhal_register_drivers(register: Any) -> None:
    register(AF3Driver)


@hookimpl
def imuhal_register_emulators(register: Any) -> None:
    register(AF3Emulator)
