"""Wiring procedures to a board: pick the device, open the pipeline in uncalibrated mode
(real buses or an emulated board whose chips carry sensor errors), feed the procedure, and
bind the result to the probed chip (``Pipeline.calibration_binding``).

The procedures themselves (:mod:`imuhal.calibration`) only see samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.guidance import describe_position, guided_order
from imuhal.calibration.procedure import Procedure
from imuhal.core.samples import Quantity, Sample
from imuhal.emulation.open import open_emulated
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.sim.errors import SensorErrorSpec

__all__ = ["describe_position", "devices_with", "guided_order", "open_raw_pipeline",
           "pick_device", "run_procedure"]

R = TypeVar("R")


def devices_with(profile: BoardProfile, registry: Registry, channel: Quantity) -> list[str]:
    """Enabled devices whose driver provides ``channel``, in profile order."""
    out = []
    for name, cfg in profile.devices.items():
        reg = registry.drivers.entries.get(cfg.driver)
        if cfg.enabled and reg is not None and channel in reg.obj.channels:
            out.append(name)
    return out


def pick_device(profile: BoardProfile, registry: Registry, channel: Quantity,
                name: str | None = None) -> str:
    """The device to calibrate: ``name``, or the only one with ``channel``."""
    found = devices_with(profile, registry, channel)
    if name is not None:
        if name not in profile.devices:
            raise CalibrationError(f"no device {name!r} in profile {profile.name!r}",
                                   f"choose one of: {', '.join(profile.devices)}")
        if name not in found:
            raise CalibrationError(
                f"device {name!r} ({profile.devices[name].driver}) has no {channel.value} "
                "channel (or is disabled)",
                f"devices with one: {', '.join(found) or 'none'}")
        return name
    if not found:
        raise CalibrationError(f"no device in profile {profile.name!r} measures "
                               f"{channel.value}", "add one, or check the driver names")
    if len(found) > 1:
        raise CalibrationError(f"several devices measure {channel.value}: {', '.join(found)}",
                               "choose one with --device NAME")
    return found[0]


def open_raw_pipeline(
    profile: BoardProfile, registry: Registry, *, emulate: str | None = None,
    seed: int | None = None, realtime: bool = False, sensor_errors: bool | None = None,
    error_specs: Mapping[str, SensorErrorSpec] | None = None,
    scenario_params: dict[str, Any] | None = None,
) -> Pipeline:
    """A pipeline yielding raw sensor-frame samples (``calibrated=False``).

    Without ``emulate`` the profile's real buses are opened. With it, an emulated board flies
    scenario ``emulate``; its chips measure through their datasheet error models unless
    ``sensor_errors`` is False (default: the profile's ``emulation.sensor_errors``).
    ``error_specs`` replaces those models by the given specs (device name -> spec; devices
    not named are ideal), for tests that need known offsets, scale errors and iron.
    """
    if emulate is None:
        return Pipeline.open(profile, registry, calibrated=False)
    return open_emulated(profile, registry, scenario=emulate, seed=seed, realtime=realtime,
                         scenario_params=scenario_params, calibrated=False,
                         sensor_errors=sensor_errors, error_specs=error_specs)


def run_procedure(procedure: Procedure[R], pipeline: Pipeline,
                  duration_s: float | None) -> R:
    """Feed the pipeline's raw samples to ``procedure`` until it is done or ``duration_s``
    (None: until done) has passed, then return its result."""
    for event in pipeline.events(duration_s):
        if isinstance(event, Sample) and procedure.feed(event):
            break
    return procedure.finish()
