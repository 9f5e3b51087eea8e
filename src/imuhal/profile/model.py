"""The board profile schema (version 1).

A profile names the buses, the devices on them (driver, address, mount rotation, settings in
physical units, stored calibration) and the estimators to run. This schema checks structure;
driver, bus and estimator settings are checked by their plugins' own models after plugins load
(see loader.py), so a third-party driver's settings get the same located errors.
"""

from __future__ import annotations

import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from imuhal.calibration.model import DeviceCalibration
from imuhal.core.conventions import convention_name
from imuhal.core.frames import MountError, parse_mount
from imuhal.profile.faults import FaultSpec
from imuhal.sinks.flight.audio import VarioAudioSettings
from imuhal.sinks.flight.igc import IgcLogSettings
from imuhal.sinks.mavlink.settings import MavlinkSettings
from imuhal.sinks.ros.settings import RosSettings

SCHEMA_VERSION = 1
MountSpec = str | list[list[float]]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _valid_mount(value: MountSpec) -> MountSpec:
    try:
        parse_mount(value)
    except MountError as exc:
        raise ValueError(str(exc)) from None
    return value


class BusConfig(BaseModel):
    """``kind`` picks the bus plugin; the other keys are that plugin's settings."""

    model_config = ConfigDict(extra="allow", frozen=True)
    kind: str

    def plugin_settings(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


_GPIO_CHIP = re.compile(r"(/dev/)?gpiochip[0-9]+")


class InterruptConfig(_Strict):
    """The GPIO line a chip's INT pin is wired to (docs/acquisition.md, "Triggers"): the
    pipeline then reads the chip when the line says so (data-ready), with the kernel's edge
    time stamps, and falls back to polling while the line stays silent."""

    chip: str
    """The GPIO character device: ``gpiochip0`` or ``/dev/gpiochip0`` (``gpiodetect``)."""
    line: int | str
    """The line's offset on that chip (``gpioinfo``), or its name."""
    edge: Literal["rising", "falling", "both"] = "rising"
    """Which edges are data-ready events: ``rising`` for an active-high pulse (the
    MPU-9250 as imuhal configures it)."""
    watchdog_periods: float = Field(4.0, ge=1.5, le=100_000)
    """How many of the chip's output periods the line may stay silent before the pipeline
    polls the chip instead (and says so once); 4 at 200 Hz is 20 ms (PX4: 10 ms)."""
    edges_per_read: int = Field(1, ge=1, le=1000)
    """Edges counted to one read: a watermark for a chip read in bursts from its FIFO
    (``read: fifo``, as PX4 counts data-ready edges); 1 reads at every edge."""

    @field_validator("chip")
    @classmethod
    def _chip_device(cls, value: str) -> str:
        if not _GPIO_CHIP.fullmatch(value):
            raise ValueError("not a GPIO character device: give gpiochipN or "
                             "/dev/gpiochipN (list them with gpiodetect)")
        return value

    @field_validator("line")
    @classmethod
    def _line_offset(cls, value: int | str) -> int | str:
        if isinstance(value, int) and value < 0:
            raise ValueError("a line offset is 0 or more: give the offset gpioinfo lists "
                             "(on a Raspberry Pi the BCM GPIO number)")
        if isinstance(value, str) and not value.strip():
            raise ValueError("a line name cannot be empty: give the offset or the name "
                             "gpioinfo lists")
        return value

    @property
    def chip_path(self) -> str:
        """The character device's path."""
        return self.chip if self.chip.startswith("/") else f"/dev/{self.chip}"


class DeviceConfig(_Strict):
    driver: str
    """Driver name as listed by ``imuhal plugins``."""
    bus: str
    """A bus name from ``buses``, or ``DEVICE/CHILD`` for a bus another chip provides
    (e.g. ``imu/aux``: the MAX21100's I2C master)."""
    address: int = Field(ge=0, le=0x3FF)
    """I2C 7-bit address, or SPI chip select."""
    mount: MountSpec = "+X+Y+Z"
    """Rotation chip -> board: signed axes (``"-Y-X-Z"``: board x = -chip y, ...) or 3x3."""
    settings: dict[str, Any] = Field(default_factory=dict)
    calibration: DeviceCalibration | None = None
    enabled: bool = True
    required: bool = True
    """False: the run starts without this device if it does not answer, and the device
    joins when it appears (it is probed again every second)."""
    interrupt: InterruptConfig | None = None
    """The GPIO line the chip's INT pin drives (data-ready trigger); None: the device is
    polled on its own grid (timer trigger)."""

    _mount = field_validator("mount")(_valid_mount)


class EstimatorConfig(_Strict):
    estimator: str
    """Estimator name as listed by ``imuhal plugins``."""
    settings: dict[str, Any] = Field(default_factory=dict)
    inputs: list[str] | None = None
    """Devices and estimators whose output this one consumes; default: all."""


class EmulationConfig(_Strict):
    """How ``--emulate`` runs this board when no hardware is attached."""

    scenario: str = "thermal"
    seed: int = Field(1, ge=0)
    """Seed of the simulated world and sensor errors, 0 or more (as ``--seed``)."""
    scenario_params: dict[str, Any] = Field(default_factory=dict)
    sensor_errors: bool = True
    """Apply each chip's datasheet noise, bias, scale and misalignment model (as its
    emulator declares); false: ideal chips, limited only by their resolution and range."""
    faults: list[FaultSpec] = Field(default_factory=list)
    """Faults injected into the emulated board (docs/reliability.md): each names a device,
    a kind, and a start and end time in simulated seconds."""


MOVED_SECTIONS = {"igc": "igc", "ros": "mcap", "mavlink": "mavlink"}
"""Top-level sections of earlier profiles -> their place under ``outputs`` (same keys)."""


class OutputsConfig(BaseModel):
    """The settings of every output, by its name. The built-in outputs' sections are typed
    here; any other key is a plugin sink's section (``mqtt: {board: glider-7, ...}``),
    checked by that sink's own Settings when the profile loads (loader.py). An output is
    switched on by its command-line option (``--igc``, ``--mcap``, ``--mavlink``, ``--mqtt``,
    ``--sink NAME``); its section only configures it."""

    model_config = ConfigDict(extra="allow", frozen=True)
    __pydantic_extra__: dict[str, dict[str, Any]] = Field(init=False)
    """A plugin sink's section is a mapping (its keys are checked by the sink)."""

    igc: IgcLogSettings = Field(default_factory=IgcLogSettings)
    """Pilot, glider and fix interval of the IGC log (``--igc``;
    docs/flight-instrument.md)."""
    mcap: RosSettings = Field(default_factory=RosSettings)
    """Frame id and sensor noise of the ROS 2 messages (``--mcap``; docs/outputs.md)."""
    mavlink: MavlinkSettings = Field(default_factory=MavlinkSettings)
    """System and component id and message rates (``--mavlink``; docs/outputs.md)."""

    def plugin_sections(self) -> dict[str, dict[str, Any]]:
        """The plugin sinks' sections (``--sink NAME``, ``--mqtt``), by sink name."""
        return {name: dict(section) for name, section in (self.model_extra or {}).items()}


class BoardProfile(_Strict):
    schema_version: Literal[1]
    name: str
    description: str = ""
    board_to_body: MountSpec = "+X+Y+Z"
    """Rotation board -> body (NED body: x forward, y right, z down)."""
    buses: dict[str, BusConfig]
    devices: dict[str, DeviceConfig]
    estimators: dict[str, EstimatorConfig] = Field(default_factory=dict)
    emulation: EmulationConfig = Field(default_factory=EmulationConfig)
    audio: VarioAudioSettings = Field(default_factory=VarioAudioSettings)
    """The vario audio curve (``imuhal run --audio``; docs/flight-instrument.md)."""
    outputs: OutputsConfig = Field(default_factory=OutputsConfig)
    """Settings of the run's outputs by output name (``igc``, ``mcap``, ``mavlink``, a
    plugin sink's name such as ``mqtt``); ``--sink-set NAME.KEY=VALUE`` overrides a plugin
    sink's. The output itself is switched on by its command-line option."""

    output_frame: str = "ned"
    """Convention of what the run hands out: its CSV and console sinks and
    ``Pipeline.framed_events`` (ned, aerospace, enu/ros, android, win8; see
    docs/units-and-frames.md). Estimators always work in ned; this converts at the edge."""

    _mount = field_validator("board_to_body")(_valid_mount)
    _frame = field_validator("output_frame")(convention_name)
