"""Stream specs: the facts a chip's data stream is taken with, read back from the chip.

A driver delivers one stream per quantity it measures (the MAX21100: gyro, accelerometer,
temperature). After ``configure()`` it describes each with a :class:`StreamSpec` derived from
the configuration registers it READ BACK from the chip (never copied from its settings), so
the range, resolution and rate an estimator works with are the ones the chip is running.

The pipeline collects the specs when a device joins or is reconfigured and hands those of
an estimator's inputs to ``Estimator.bind`` (docs/estimators.md, "Streams"): limits and
nominal periods come from here, not from hand-copied profile settings. Specs are plain data:
an estimator never sees a driver or a bus.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum

from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame


class TimeSource(Enum):
    """Where a stream's time stamps come from."""

    HOST_POLL = "host_poll"
    """The host's clock when the poll that found the reading ran (today's drivers)."""
    CHIP_FIFO = "chip_fifo"
    """Frames read from the chip's FIFO, back-dated from the read by the chip's period."""
    CHIP_CLOCK = "chip_clock"
    """Each frame's measurement instant on the chip's own clock, its period and phase
    learned from the host's reads of the chip's frame count (imuhal.drivers.chip_clock):
    host delays do not reach the stamps."""
    DATA_READY = "data_ready"
    """The kernel's time stamp of the chip's data-ready line edge."""
    RECEIVER_EPOCH = "receiver_epoch"
    """The measurement epoch a GNSS receiver reports (its own clock, aligned to GNSS time)."""
    KERNEL_BUFFER = "kernel_buffer"
    """A kernel driver's buffer time stamps (Linux IIO)."""
    LOG = "log"
    """Time stamps read from a recorded log (``imuhal estimate``): the rate is measured."""


@dataclass(frozen=True)
class StreamSpec:
    """One stream a device delivers, as configured in the chip.

    Units are the quantity's SI unit at the pipeline boundary (``quantity.unit``: rad/s,
    m/s^2, uT, Pa, degC, m/s ...). Values are in ``frame`` (the chip's sensor frame for a
    chip; NED for a GNSS velocity); calibration and the mount rotation come later.
    """

    device: str
    """The profile's device name."""
    quantity: Quantity
    frame: Frame | None
    """The frame the driver delivers the values in (``sensor`` for a chip's own axes);
    None for values in no device frame (a GNSS velocity in NED, a geodetic position, a
    scalar)."""
    rate_hz: float
    """Output data rate (Hz) of the chip as configured: the nominal period is 1 / it."""
    scale: float | None = None
    """SI units per count of the chip's output word (resolution); None where a count means
    nothing (a GNSS solution, a kernel-scaled value, a compensated pressure)."""
    full_scale: float | None = None
    """The largest magnitude (SI) a correct component can have in this configuration; the
    pipeline flags anything beyond it OUT_OF_RANGE. None: not bounded by the chip."""
    latency_s: float = 0.0
    """From the physical measurement to its time stamp (s): filter group delay is not
    included, only what the acquisition adds (a conversion time, an auto-read's delay)."""
    time_source: TimeSource = TimeSource.HOST_POLL

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"{self.device} {self.quantity}: rate must be a positive "
                             f"number of Hz, got {self.rate_hz}")
        if self.full_scale is not None and not self.full_scale > 0:
            raise ValueError(f"{self.device} {self.quantity}: full scale must be positive, "
                             f"got {self.full_scale}")

    @property
    def unit(self) -> str:
        """The SI unit of every value (the quantity's)."""
        return self.quantity.unit

    @property
    def period_s(self) -> float:
        """The nominal output period (s): ``1 / rate_hz``."""
        return 1.0 / self.rate_hz

    @property
    def period_ns(self) -> int:
        """The nominal output period in whole nanoseconds (the drivers' poll grids)."""
        return round(1e9 / self.rate_hz)

    def describe(self) -> str:
        """One line: ``imu gyro 250 Hz, +-8.727 rad/s, 0.0002909 rad/s per count``."""
        parts = [f"{self.device} {self.quantity.name} {self.rate_hz:g} Hz"]
        if self.full_scale is not None:
            parts.append(f"+-{self.full_scale:.4g} {self.unit}")
        if self.scale is not None:
            parts.append(f"{self.scale:.4g} {self.unit} per count")
        return ", ".join(parts)


def of_quantity(streams: Iterable[StreamSpec], quantity: Quantity) -> list[StreamSpec]:
    """The specs in ``streams`` that carry ``quantity``, in order."""
    return [s for s in streams if s.quantity == quantity]
