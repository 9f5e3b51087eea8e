"""Opening a board profile as an emulated board: the one entry point for emulated runs.

:func:`open_emulated` builds the profile's buses and chips as register-level emulators,
flying a scenario on a simulated clock, and returns an ordinary
:class:`~imuhal.pipeline.Pipeline` over them. Everything simulation-specific (scenario,
seed, sensor error models, pacing against the wall clock) is chosen here; the pipeline only
sees a :class:`~imuhal.pipeline.board.Board`. ``EmulatedBoard.of(pipeline)`` returns the
board, typed (its ``emulators`` by device name, its ``scenario`` and ``truth_at(t_ns)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from imuhal.bus.recording.recorder import BusRecorder
from imuhal.bus.spy import Transfer
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ImuhalError
from imuhal.core.frames import MountError, parse_mount
from imuhal.core.poll_plan import POLL_PLAN
from imuhal.core.samples import Quantity
from imuhal.emulation import user_calibration
from imuhal.emulation.board import EmulatedBoard
from imuhal.emulation.mounting import chip_rotations
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.faults import FaultSpec
from imuhal.profile.model import BoardProfile, MountSpec
from imuhal.profile.topology import device_order
from imuhal.sim.errors import SensorErrorModel, SensorErrorSpec, device_seed, error_spec_of


def open_emulated(
    profile: BoardProfile,
    registry: Registry,
    *,
    scenario: str | None = None,
    scenario_params: dict[str, Any] | None = None,
    seed: int | None = None,
    realtime: bool = False,
    sensor_errors: bool | None = None,
    error_specs: Mapping[str, SensorErrorSpec | None] | None = None,
    calibrated: bool = True,
    trace: Callable[[Transfer], None] | None = None,
    faults: Sequence[FaultSpec] = (),
    physical_mounts: Mapping[str, MountSpec] | None = None,
    recorder: BusRecorder | None = None,
    calibrate_missing: bool = False,
    start_s: float = 0.0,
    poll_plan: int | None = None,
) -> Pipeline:
    """A pipeline over ``profile``'s board, emulated, flying ``scenario``.

    ``scenario`` (default: the profile's ``emulation.scenario``) names a registered
    scenario; ``scenario_params`` are added to the profile's own params when it is the
    profile's scenario. ``seed`` (default: the profile's) seeds the world and every chip's
    error model. ``realtime`` paces the simulated clock against the wall. ``sensor_errors``
    (default: the profile's ``emulation.sensor_errors``) applies each chip's datasheet noise
    and bias model (as its emulator declares); False gives ideal chips (quantisation and
    range only). ``error_specs`` (device -> spec; devices not named are ideal) replaces
    those models, for tests and studies that need known offsets, scale errors and iron.
    ``faults`` are injected into the board on top of the profile's ``emulation.faults``
    (imuhal.emulation.faults, docs/reliability.md). ``calibrated``, ``trace`` and
    ``recorder`` are the pipeline's (see :class:`Pipeline`).
    ``physical_mounts`` (device -> mount, as in a profile) places those chips on the board
    differently from what the profile says: the pipeline still rotates by the profile's
    mount, so a wrong profile can be emulated (``imuhal check-mounts`` finds it).
    ``calibrate_missing`` first measures the accelerometer and magnetometer records the
    profile lacks, as its user would (:func:`calibrated_as_user`), and flies the board with
    them (so nothing learns in flight); default off: the board flies as its file says,
    and a device without a record learns it in flight where the board makes that
    observable, unless the profile turns it off (imuhal.pipeline.learning).
    ``start_s`` switches the board on at that time of the scenario (s, >= 0): the world is
    already there (in flight, for a flight scenario), as after a brown-out reboot or a
    battery swap in the air; the pipeline's start-up and every filter begin then. Times
    stay the scenario's: estimates, the truth and ``faults``' ``start_s`` count from the
    scenario's 0, not from the switch-on. ``poll_plan`` (default: the newest,
    imuhal.core.poll_plan) runs the drivers on an older plan, as a replay of a recording
    made under it does: to compare the bus traffic of two plans on one flight (not with
    ``recorder``, whose header holds the newest plan).
    """
    if poll_plan is not None and recorder is not None and poll_plan != POLL_PLAN:
        raise ImuhalError(f"poll_plan={poll_plan}: a recording's header holds the newest "
                          f"poll plan ({POLL_PLAN}); record without poll_plan")
    if not (math.isfinite(start_s) and start_s >= 0.0):
        raise ImuhalError(f"start_s={start_s!r}: the switch-on time must be a finite "
                          "number of seconds >= 0 into the scenario")
    if calibrate_missing:
        profile, _ = calibrated_as_user(profile, registry, seed=seed,
                                        sensor_errors=sensor_errors, error_specs=error_specs)
    name = profile.emulation.scenario if scenario is None else scenario
    start_ns = round(start_s * 1e9)
    clock = SimulatedClock(start_ns, realtime=realtime)
    scenario_cls = registry.scenarios.get(name)
    params = dict(profile.emulation.scenario_params) if name == profile.emulation.scenario \
        else {}
    params.update(scenario_params or {})
    run_seed = profile.emulation.seed if seed is None else seed
    world = scenario_cls(params or None, seed=run_seed)
    use_errors = profile.emulation.sensor_errors if sensor_errors is None else sensor_errors
    errors: dict[str, SensorErrorModel] | None
    if error_specs is not None:
        errors = {dev: SensorErrorModel(spec, seed=device_seed(run_seed, dev))
                  for dev, spec in error_specs.items() if spec is not None}
    else:
        errors = error_models_for(profile, registry, run_seed) if use_errors else None
    # The emulation's own reading of the mounts, not the pipeline's: see emulation.mounting.
    rotations = chip_rotations(_physically_mounted(profile, physical_mounts or {}))
    board = EmulatedBoard(profile, registry, clock, world, rotations, errors,
                          faults=[*profile.emulation.faults, *faults], seed=run_seed)
    if poll_plan is not None:
        board.poll_plan = poll_plan
    board.update(start_ns)
    return Pipeline(profile, registry, board, calibrated=calibrated, trace=trace,
                    recorder=recorder)


def calibrated_as_user(
    profile: BoardProfile, registry: Registry, *, seed: int | None = None,
    sensor_errors: bool | None = None,
    error_specs: Mapping[str, SensorErrorSpec | None] | None = None,
) -> tuple[BoardProfile, dict[str, tuple[Quantity, ...]]]:
    """``profile`` after its user followed docs/calibration.md on the emulated board: the
    accelerometer and magnetometer records it lacks (stored ones are kept) measured by
    imuhal's procedures while the board, with ``seed``'s sensor errors (default: the
    profile's seed; ``sensor_errors`` and ``error_specs`` as :func:`open_emulated` takes
    them), flies the calibration scenario; and what was measured (device -> channels, empty
    when nothing was missing). Measuring takes a few seconds of the simulated clock per
    procedure, not of the run that follows (user_calibration)."""
    missing = user_calibration.missing_calibrations(profile, registry)
    if not missing:
        return profile, {}
    scenario = user_calibration.CALIBRATION_SCENARIO
    raw = user_calibration.with_calibration(profile, {})
    with open_emulated(raw, registry, scenario=scenario, seed=seed, calibrated=False,
                       sensor_errors=sensor_errors, error_specs=error_specs) as pipeline:
        measured = user_calibration.measure_calibrations(
            pipeline, raw, missing, registry.scenarios.get(scenario).default_duration_s)
    return user_calibration.with_measured(profile, measured), missing


def _physically_mounted(profile: BoardProfile, mounts: Mapping[str, MountSpec]
                        ) -> BoardProfile:
    """``profile`` with the named devices' mounts replaced by where the chips really sit."""
    if not mounts:
        return profile
    devices = dict(profile.devices)
    for device, mount in mounts.items():
        if device not in devices or not devices[device].enabled:
            enabled = ", ".join(n for n, d in devices.items() if d.enabled)
            raise ImuhalError(f"physical mount for {device!r}: the profile has no enabled "
                              f"device of that name; it has {enabled}")
        try:
            parse_mount(mount)
        except MountError as exc:
            raise ImuhalError(f"physical mount for {device!r}: {exc}") from None
        devices[device] = devices[device].model_copy(update={"mount": mount})
    return profile.model_copy(update={"devices": devices})


def error_models_for(profile: BoardProfile, registry: Registry, seed: int
                     ) -> dict[str, SensorErrorModel]:
    """Each enabled device's datasheet error model (as its emulator declares), seeded per
    device from the run seed so adding a device does not change the others' noise."""
    models = {}
    for name in device_order(profile):
        driver = profile.devices[name].driver
        reg = registry.emulators.entries.get(driver)
        spec = error_spec_of(reg.obj) if reg is not None else None
        if spec is not None:
            models[name] = SensorErrorModel(spec, seed=device_seed(seed, name))
    return models
