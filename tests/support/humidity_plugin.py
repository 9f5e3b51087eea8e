"""A third party's plugin for a fictional relative-humidity chip, written only against
imuhal's public plugin API: it adds a quantity (humidity, %RH), its sample class, a driver and
emulator, a scenario whose world has humidity, a sink and a command.
tests/plugins/test_out_of_tree_plugin.py installs it as a separate package.

HH1 registers: 0x0F WHO_AM_I = 0xA7; 0x00..0x01 humidity, uint16 big-endian, 65535 = 100 %RH.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from imuhal.bus.base import BusKind
from imuhal.bus.registers import RegisterView
from imuhal.core.errors import DeviceNotFoundError, ImuhalError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import ScalarSample
from imuhal.drivers.base import DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal.emulation import ChipEmulator
from imuhal.plugins import Command, Registry, hookimpl
from imuhal.sim.scenario import TruthState
from imuhal.sim.static import StaticScenario
from imuhal.sinks import Event, SinkPlugin

HUMIDITY = Quantity("humidity", "%RH", (), "Relative humidity.")
WHO_AM_I, DATA, IDENTITY = 0x0F, 0x00, 0xA7
EMULATED_RH_PCT = 41.5
"""What the emulated chip measures when the scenario's world has no humidity."""


@dataclass(frozen=True, slots=True, kw_only=True)
class HumiditySample(ScalarSample):
    """Relative humidity in %RH."""

    humidity_pct: float = 0.0
    channel: ClassVar[Quantity] = HUMIDITY

    @property
    def scalar(self) -> float:
        return self.humidity_pct


class HH1Settings(DriverSettings):
    odr_hz: float = 10.0


class HH1Driver(Driver):
    name: ClassVar[str] = "hh1"
    description: ClassVar[str] = "fictional relative-humidity chip"
    Settings = HH1Settings
    channels = (HUMIDITY,)
    bus_kinds = frozenset({BusKind.I2C})

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.regs = RegisterView(self.link)

    def probe(self) -> DeviceIdentity:
        found = self.regs.read_u8(WHO_AM_I)
        if found != IDENTITY:
            raise DeviceNotFoundError(driver=self.name, bus=self.link.bus.name,
                                      address=self.link.target, expected="WHO_AM_I=0xA7",
                                      found=f"WHO_AM_I=0x{found:02X}")
        return DeviceIdentity(self.name, self.link.bus.name, self.link.target, "WHO_AM_I=0xA7")

    def configure(self) -> None:
        """Nothing to set: the chip measures continuously."""

    def poll(self, now_ns: int) -> PollResult:
        hi, lo = self.regs.read(DATA, 2)
        sample = HumiditySample(t_ns=now_ns, device=self.device,
                                humidity_pct=((hi << 8) | lo) * 100.0 / 65535)
        return PollResult([sample], now_ns + round(1e9 / self.settings.odr_hz))


class HH1Emulator(ChipEmulator):
    chip = "hh1"

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        if write and write[0] == WHO_AM_I:
            return bytes([IDENTITY])[:read_len]
        rh = float(self.physics.other.get("humidity", EMULATED_RH_PCT))  # type: ignore[arg-type]
        raw = round(min(max(rh, 0.0), 100.0) / 100.0 * 65535)
        return bytes([raw >> 8, raw & 0xFF])[:read_len]


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


@hookimpl
def imuhal_register_drivers(register: Any) -> None:
    register(HH1Driver)


@hookimpl
def imuhal_register_emulators(register: Any) -> None:
    register(HH1Emulator)


@hookimpl
def imuhal_register_scenarios(register: Any) -> None:
    register(HumidStatic)


@hookimpl
def imuhal_register_sinks(register: Any) -> None:
    register(HumidityLog)


@hookimpl
def imuhal_register_commands(register: Any) -> None:
    register(HumidityStats)
