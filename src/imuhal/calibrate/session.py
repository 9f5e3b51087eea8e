"""Wiring procedures to a board: pick the device, open the pipeline in uncalibrated mode
(real buses or an emulated board whose chips carry sensor errors), feed the procedure, and
bind the result to the probed chip (``Pipeline.calibration_binding``).

The procedures themselves (:mod:`imuhal.calibration`) only see samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from imuhal.calibration.accel import SIX_POSITIONS, Position, position_name
from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.procedure import Procedure
from imuhal.core.frames import FloatArray
from imuhal.core.samples import Channel, Sample
from imuhal.emulation.open import open_emulated
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.sim.errors import SensorErrorSpec

R = TypeVar("R")


def devices_with(profile: BoardProfile, registry: Registry, channel: Channel) -> list[str]:
    """Enabled devices whose driver provides ``channel``, in profile order."""
    out = []
    for name, cfg in profile.devices.items():
        reg = registry.drivers.entries.get(cfg.driver)
        if cfg.enabled and reg is not None and channel in reg.obj.channels:
            out.append(name)
    return out


def pick_device(profile: BoardProfile, registry: Registry, channel: Channel,
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


# --------------------------------------------------------------------------- guidance
_BODY_WORDS = {
    (2, 1): "level, top up",
    (2, -1): "upside down",
    (0, 1): "nose down (front edge down)",
    (0, -1): "nose up (rear edge down)",
    (1, 1): "right side down",
    (1, -1): "left side down",
}
_BODY_ORDER = [(2, 1), (2, -1), (0, 1), (0, -1), (1, 1), (1, -1)]


def _body_down(pos: Position, chip_to_body: FloatArray) -> Position | None:
    d = np.asarray(chip_to_body, dtype=float) @ (pos[1] * np.eye(3)[pos[0]])
    axis = int(np.argmax(np.abs(d)))
    if abs(d[axis]) < 0.99:
        return None
    return (axis, 1 if d[axis] > 0 else -1)


def describe_position(pos: Position, chip_to_body: FloatArray) -> str:
    """Words for the user: which way the board goes, with the sensor axis for reference."""
    body = _body_down(pos, chip_to_body)
    words = _BODY_WORDS[body] if body is not None else "turn the board"
    return f"{words} (sensor {position_name(pos)})"


def guided_order(chip_to_body: FloatArray) -> tuple[str, ...]:
    """The six sensor positions in the order a person handles a board: level, upside down,
    nose down, nose up, right side down, left side down."""
    def rank(p: Position) -> int:
        body = _body_down(p, chip_to_body)
        return _BODY_ORDER.index(body) if body is not None else len(_BODY_ORDER)
    return tuple(position_name(p) for p in sorted(SIX_POSITIONS, key=rank))
