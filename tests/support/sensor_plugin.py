"""A third party's plugin for two fictional chips measuring quantities imuhal does not know,
written only against imuhal's public plugin API (tests/plugins/test_out_of_tree_plugin.py
installs it as a separate package; tests/calibration/test_calibration_vector.py loads it):

* HH1, relative humidity (a scalar, %RH): 0x00..0x01 uint16 big-endian, 65535 = 100 %RH;
  with a scenario whose world has humidity, a sink logging it and a command summarising
  the log.
* AF3, air flow (a 3-vector, m/s): 0x00..0x05 int16 little-endian, 1/1024 m/s per count;
  the emulated chip reads a fixed zero offset in still air (``ZERO_OFFSET_M_S``), which a
  calibration should remove.

Both answer WHO_AM_I at 0x0F (HH1 0xA7, AF3 0xAF) and measure continuously.
"""

from __future__ import annotations

import argparse
import csv
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from imuhal.bus.base import BusKind
from imuhal.bus.registers import RegisterView
from imuhal.core.errors import DeviceNotFoundError, ImuhalError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame, Sample, ScalarSample, Vec3, VectorSample
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal.emulation import ChipEmulator
from imuhal.plugins import Command, Registry, hookimpl
from imuhal.sim.scenario import TruthState
from imuhal.sim.static import StaticScenario
from imuhal.sinks import Event, SinkPlugin

WHO_AM_I, DATA = 0x0F, 0x00

HUMIDITY = Quantity("humidity", "%RH", (), "Relative humidity.")
EMULATED_RH_PCT = 41.5
"""What the emulated HH1 measures when the scenario's world has no humidity."""

AIRFLOW = Quantity("airflow", "m/s", (3,), "Air velocity relative to the board.")
M_S_PER_COUNT = 1.0 / 1024
ZERO_OFFSET_M_S: Vec3 = (0.5, -0.25, 0.125)


@dataclass(frozen=True, slots=True, kw_only=True)
class HumiditySample(ScalarSample):
    """Relative humidity in %RH."""

    humidity_pct: float = 0.0
    channel: ClassVar[Quantity] = HUMIDITY

    @property
    def scalar(self) -> float:
        return self.humidity_pct


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


class RateSettings(DriverSettings):
    odr_hz: float = 10.0


class _ContinuousDriver(Driver):
    """A chip identified by WHO_AM_I that measures continuously; ``_decode`` turns the
    ``data_len`` bytes at DATA into a sample."""

    who_am_i: ClassVar[int]
    data_len: ClassVar[int]
    Settings = RateSettings
    bus_kinds = frozenset({BusKind.I2C})

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.regs = RegisterView(self.link)

    def probe(self) -> DeviceIdentity:
        found = self.regs.read_u8(WHO_AM_I)
        expected = f"WHO_AM_I=0x{self.who_am_i:02X}"
        if found != self.who_am_i:
            raise DeviceNotFoundError(driver=self.name, bus=self.link.bus.name,
                                      address=self.link.target, expected=expected,
                                      found=f"WHO_AM_I=0x{found:02X}")
        return DeviceIdentity(self.name, self.link.bus.name, self.link.target, expected)

    def configure(self) -> None:
        """Nothing to set: the chip measures continuously."""

    def poll(self, now_ns: int) -> PollResult:
        sample = self._decode(now_ns, self.regs.read(DATA, self.data_len))
        return PollResult([sample], now_ns + round(1e9 / self.settings.odr_hz))

    def _decode(self, now_ns: int, raw: bytes) -> Sample:
        raise NotImplementedError


class HH1Driver(_ContinuousDriver):
    name: ClassVar[str] = "hh1"
    description: ClassVar[str] = "fictional relative-humidity chip"
    channels = (HUMIDITY,)
    who_am_i = 0xA7
    data_len = 2

    def _decode(self, now_ns: int, raw: bytes) -> Sample:
        return HumiditySample(t_ns=now_ns, device=self.device,
                              humidity_pct=((raw[0] << 8) | raw[1]) * 100.0 / 65535)


class AF3Driver(_ContinuousDriver):
    name: ClassVar[str] = "af3"
    description: ClassVar[str] = "fictional 3-axis air-flow sensor"
    channels = (AIRFLOW,)
    who_am_i = 0xAF
    data_len = 6

    def _decode(self, now_ns: int, raw: bytes) -> Sample:
        x, y, z = struct.unpack("<hhh", raw)
        return AirflowSample(t_ns=now_ns, device=self.device,
                             airflow_m_s=(x * M_S_PER_COUNT, y * M_S_PER_COUNT,
                                          z * M_S_PER_COUNT))


class _ContinuousEmulator(ChipEmulator):
    """Answers WHO_AM_I, and any other read with ``data()`` (the current measurement)."""

    who_am_i: ClassVar[int]

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if write and write[0] == WHO_AM_I:
            return bytes([self.who_am_i])[:read_len]
        return self.data()[:read_len]

    def data(self) -> bytes:
        raise NotImplementedError


class HH1Emulator(_ContinuousEmulator):
    chip = "hh1"
    who_am_i = 0xA7

    def data(self) -> bytes:
        rh = float(self.physics.other.get("humidity", EMULATED_RH_PCT))  # type: ignore[arg-type]
        raw = round(min(max(rh, 0.0), 100.0) / 100.0 * 65535)
        return bytes([raw >> 8, raw & 0xFF])


class AF3Emulator(_ContinuousEmulator):
    """Still air: the chip reads only its zero offset."""

    chip = "af3"
    who_am_i = 0xAF

    def data(self) -> bytes:
        return struct.pack("<hhh", *(round(v / M_S_PER_COUNT) for v in ZERO_OFFSET_M_S))


class HumidStatic(StaticScenario):
    """The static bench, in air whose humidity rises 10 %RH per second from 40 %RH."""

    name: ClassVar[str] = "humid-static"
    description: ClassVar[str] = "static bench, humidity rising 10 %RH/s from 40 %RH"

    def truth(self, t_s: float) -> TruthState:
        truth = super().truth(t_s)
        return replace(truth, other={**truth.other, "humidity": 40.0 + 10.0 * t_s})


class HumidityLogSettings(BaseModel):
    model_config = ConfigDict(extra="forbid")
    path: Path


class HumidityLog(SinkPlugin):
    """Writes every valid humidity sample as a CSV row (t_s, device, humidity_pct)."""

    name: ClassVar[str] = "humidity-log"
    description: ClassVar[str] = "humidity samples to a CSV file"
    Settings = HumidityLogSettings

    def __init__(self, settings: Any = None) -> None:
        super().__init__(settings)
        self.rows: list[tuple[float, str, float]] = []

    def handle(self, event: Event) -> None:
        if isinstance(event, HumiditySample) and event.valid:
            self.rows.append((event.t_ns / 1e9, event.device, event.humidity_pct))

    def close(self) -> None:
        with open(self.settings.path, "w", newline="") as f:  # type: ignore[attr-defined]
            csv.writer(f).writerows([("t_s", "device", "humidity_pct"), *self.rows])


class HumidityStats(Command):
    """Summarises a humidity log in the quantity's registered unit."""

    name: ClassVar[str] = "humidity-stats"
    help: ClassVar[str] = "summarise a humidity-log CSV file"

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("log", help="CSV written by the humidity-log sink")

    def run(self, args: argparse.Namespace, registry: Registry) -> int:
        path = Path(args.log)
        if not path.is_file():
            raise ImuhalError(f"{path}: no such humidity log; write one with "
                              "`imuhal run --sink humidity-log`")
        with path.open(newline="") as f:
            values = [float(r["humidity_pct"]) for r in csv.DictReader(f)]
        unit = registry.quantities.get("humidity").channel.unit
        print(f"{len(values)} samples, mean {sum(values) / len(values):.2f} {unit}")
        return 0


@hookimpl
def imuhal_register_quantities(register: Any) -> None:
    register(HumiditySample)
    register(AirflowSample)


@hookimpl
def imuhal_register_drivers(register: Any) -> None:
    register(HH1Driver)
    register(AF3Driver)


@hookimpl
def imuhal_register_emulators(register: Any) -> None:
    register(HH1Emulator)
    register(AF3Emulator)


@hookimpl
def imuhal_register_scenarios(register: Any) -> None:
    register(HumidStatic)


@hookimpl
def imuhal_register_sinks(register: Any) -> None:
    register(HumidityLog)


@hookimpl
def imuhal_register_commands(register: Any) -> None:
    register(HumidityStats)
