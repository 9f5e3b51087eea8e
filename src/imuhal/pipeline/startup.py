"""Gyro offsets measured again at every start-up (profile option ``gyro_at_startup``).

Gyro offsets drift from one power-up to the next (the seed: calibrate "ideally ... each time
on power up"). A device whose calibration holds ``gyro_at_startup: {enabled: true}`` gets its
offsets measured over the first still ``samples`` gyro readings of the run; the stored record
keeps its scale and misalignment and only its offsets are replaced, in memory (the profile
file is not touched). If the board never stays still within ``max_attempts``, the stored
offsets are used and a warning says so.

:class:`GyroStartupStage` is a stage with a narrow port: it is told which devices measure,
is fed raw samples and returns what it found (:class:`StartupMeasurement`: offsets to
install, or a warning). It knows nothing of the pipeline; ``Pipeline.events`` feeds it raw
samples during the phase (yielding nothing meanwhile) and installs what it returns.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.gyro import GyroOffsetProcedure, GyroOffsetResult
from imuhal.calibration.model import (
    CalibrationBinding,
    DeviceCalibration,
    GyroCalibration,
    GyroStartupSettings,
    now,
)
from imuhal.calibration.progress import ProgressCallback
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Sample

PROCEDURE = "gyro-at-startup"
"""The ``procedure`` a record measured at start-up carries."""


def startup_settings(calibrations: Mapping[str, DeviceCalibration | None],
                     channels: Mapping[str, tuple[Quantity, ...]]
                     ) -> dict[str, GyroStartupSettings]:
    """Devices that ask for start-up gyro offsets, with their settings: those whose profile
    ``calibrations`` enable ``gyro_at_startup`` and whose driver's ``channels`` hold a gyro."""
    out = {}
    for name, quantities in channels.items():
        cal = calibrations.get(name)
        opt = cal.gyro_at_startup if cal is not None else None
        if opt is not None and opt.enabled and Quantity.GYRO in quantities:
            out[name] = opt
    return out


@dataclass(frozen=True)
class StartupMeasurement:
    """What the start-up phase found for one device: offsets measured, or a warning why not
    (then the stored offsets stay)."""

    device: str
    result: GyroOffsetResult | None
    """The measured offsets (sensor frame, rad/s); None when the board never stayed still."""
    warning: str | None = None
    moved: bool = False
    """Not measured because the board moved (a start in flight, a board in a hand), not
    because of the chip (imuhal.calibration.gyro, ``GyroOffsetProcedure.moved``)."""

    def calibration(self, stored: DeviceCalibration | None,
                    binding: CalibrationBinding) -> DeviceCalibration | None:
        """``stored`` with its gyro offsets replaced by the measured ones (scale and
        misalignment kept), bound to the probed chip ``binding``; ``stored`` unchanged when
        nothing was measured."""
        if self.result is None:
            return stored
        cal = stored or DeviceCalibration()
        record = self.result.record(cal.gyro or GyroCalibration(), date=now())
        record = record.model_copy(update={"binding": binding, "procedure": PROCEDURE})
        return cal.model_copy(update={"gyro": record})


class GyroStartupStage:
    """One gyro offset procedure per device that asks for start-up offsets, fed raw samples
    (sensor frame, uncalibrated) until every one has finished or given up."""

    def __init__(self, settings: Mapping[str, GyroStartupSettings],
                 progress: ProgressCallback | None = None) -> None:
        """``settings``: the devices that measure (:func:`startup_settings`)."""
        self._pending = {name: GyroOffsetProcedure(opt, device=name, progress=progress)
                         for name, opt in settings.items()}

    @property
    def done(self) -> bool:
        """Every device has its offsets or has given up."""
        return not self._pending

    def feed(self, sample: Sample) -> StartupMeasurement | None:
        """Hand one raw sample to its device's procedure; what it found when it finishes."""
        proc = self._pending.get(sample.device)
        if proc is None:
            return None
        try:
            finished = proc.feed(sample)
        except CalibrationError as exc:
            del self._pending[sample.device]
            return StartupMeasurement(
                sample.device, None,
                warning=f"{sample.device}: start-up gyro offsets not measured ({exc}); "
                        "using the stored offsets", moved=proc.moved)
        if not finished:
            return None
        del self._pending[sample.device]
        return StartupMeasurement(sample.device, proc.finish())
