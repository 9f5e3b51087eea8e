"""Gyro offsets measured again at every start-up (profile option ``gyro_at_startup``).

Gyro offsets drift from one power-up to the next (the seed: calibrate "ideally ... each time
on power up"). A device whose calibration holds ``gyro_at_startup: {enabled: true}`` gets its
offsets measured over the first still ``samples`` gyro readings of the run; the stored record
keeps its scale and misalignment and only its offsets are replaced, in memory (the profile
file is not touched). If the board never stays still within ``max_attempts``, the stored
offsets are used and a warning says so.

:func:`startup_gyro_phase` is applied by ``Pipeline.events`` on its first call: during the
start-up phase it puts the pipeline in raw mode, feeds the gyro procedure and yields nothing;
then it installs the offsets and passes the pipeline's events on as usual.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.gyro import GyroOffsetProcedure
from imuhal.calibration.model import (
    DeviceCalibration,
    GyroCalibration,
    GyroStartupSettings,
    now,
)
from imuhal.calibration.progress import ProgressCallback
from imuhal.core.samples import Quantity, Sample
from imuhal.sinks.base import Event

if TYPE_CHECKING:  # the pipeline applies this phase to itself
    from imuhal.pipeline.pipeline import Pipeline


def startup_settings(pipeline: Pipeline) -> dict[str, GyroStartupSettings]:
    """Devices of the pipeline that ask for start-up gyro offsets, with their settings."""
    out = {}
    for name, dev in pipeline.devices.items():
        cal = pipeline.profile.devices[name].calibration
        opt = cal.gyro_at_startup if cal is not None else None
        if opt is not None and opt.enabled and Quantity.GYRO in type(dev.driver).channels:
            out[name] = opt
    return out


def startup_procedures(pipeline: Pipeline, progress: ProgressCallback | None = None
                       ) -> dict[str, GyroOffsetProcedure]:
    """One gyro offset procedure per device that asks for start-up offsets."""
    return {name: GyroOffsetProcedure(opt, device=name, progress=progress)
            for name, opt in startup_settings(pipeline).items()}


def startup_gyro_phase(pipeline: Pipeline, source: Iterator[Event],
                       progress: ProgressCallback | None = None, *,
                       pending: dict[str, GyroOffsetProcedure] | None = None
                       ) -> Iterator[Event]:
    """``source`` (the pipeline's event stream), preceded by the start-up gyro measurement
    of every device that asks for it (see the module docstring). ``pending`` (default: new
    procedures) carries an unfinished phase from one ``events()`` call to the next; finished
    devices are removed from it."""
    if pending is None:
        pending = startup_procedures(pipeline, progress)
    if not pending:
        yield from source
        return
    calibrated = pipeline.calibrated
    pipeline.calibrated = False
    try:
        for event in source:
            if not isinstance(event, Sample) or event.device not in pending:
                continue
            proc = pending[event.device]
            try:
                finished = proc.feed(event)
            except CalibrationError as exc:
                pipeline.warnings.append(f"{event.device}: start-up gyro offsets not measured "
                                         f"({exc}); using the stored offsets")
                del pending[event.device]
                finished = False
            if finished:
                _install(pipeline, event.device, proc)
                del pending[event.device]
            if not pending:
                break
    finally:
        pipeline.calibrated = calibrated
    # Hand the rest of the stream straight through: no per-event work once the phase is over.
    yield from source


def _install(pipeline: Pipeline, device: str, proc: GyroOffsetProcedure) -> None:
    dev = pipeline.devices[device]
    cal = dev.calibration or DeviceCalibration()
    result = proc.finish()
    record = result.record(cal.gyro or GyroCalibration(), date=now())
    record = record.model_copy(update={"binding": pipeline.calibration_binding(device),
                                       "procedure": "gyro-at-startup"})
    dev.calibration = cal.model_copy(update={"gyro": record})
