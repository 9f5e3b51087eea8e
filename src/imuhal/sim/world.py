"""Scenarios made of a trajectory, an environment and magnetic disturbances.

:class:`MotionScenario` is the base of every built-in scenario: a subclass builds its
:class:`~imuhal.sim.motion.Motion` once (from its params and seed) and the base turns the
kinematics into a :class:`~imuhal.sim.scenario.TruthState` at any time. The helper
:func:`physical_inputs` hands that truth to a chip emulator in the chip's own sensor frame.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from imuhal.sim.environment import Environment
from imuhal.sim.inputs import NO_OTHER, PhysicalInputs
from imuhal.sim.magnetic import MagneticDisturbance, MagneticDisturbanceSpec
from imuhal.sim.motion import FlightMotion, Kinematics, Motion, Vec3, mat_t_vec
from imuhal.sim.scenario import (
    ChipTruth,
    Phase,
    Scenario,
    ScenarioParams,
    TruthColumns,
    TruthState,
)


class WorldParams(ScenarioParams):
    """Parameters every built-in scenario shares."""

    environment: Environment = Environment()
    magnetic: MagneticDisturbanceSpec = MagneticDisturbanceSpec()
    """Disturbances added to the earth field (default none)."""


class MotionScenario(Scenario):
    """A scenario whose truth is ``build_motion()`` in ``params.environment``."""

    Params: ClassVar[type[ScenarioParams]] = WorldParams

    def __init__(self, params: ScenarioParams | dict[str, Any] | None = None, *,
                 seed: int = 0) -> None:
        super().__init__(params, seed=seed)
        p: WorldParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        self.environment: Environment = p.environment
        self._field_ned = p.environment.magnetic_field_ned_tuple()
        self.disturbance = MagneticDisturbance(p.magnetic, seed)
        self._phases: list[Phase] = []
        self.motion: Motion = self.build_motion()

    @abstractmethod
    def build_motion(self) -> Motion:
        """Build the trajectory from ``self.params`` and ``self.rng`` (seeded); may record
        phases with :meth:`add_phase`."""

    @property
    def duration_s(self) -> float:
        """How long a run of this scenario lasts by default (s)."""
        return self.default_duration_s

    def add_phase(self, name: str, start_s: float, end_s: float) -> None:
        self._phases.append(Phase(name, start_s, end_s))

    def phases(self) -> tuple[Phase, ...]:
        return tuple(self._phases)

    def kinematics(self, t_s: float) -> Kinematics:
        return self.motion.kinematics(t_s)

    def field_ned_ut(self, t_s: float) -> tuple[tuple[float, float, float],
                                               tuple[float, float, float] | None]:
        """(total field, disturbance or None) in NED, uT."""
        if not self.disturbance.active:
            return self._field_ned, None
        d = self.disturbance.field_ned(t_s)
        e = self._field_ned
        return (e[0] + d[0], e[1] + d[1], e[2] + d[2]), d

    def truth(self, t_s: float) -> TruthState:
        k = self.motion.kinematics(t_s)
        env = self.environment
        field, dist = self.field_ned_ut(t_s)
        alt = -k.position_ned_m[2]
        return TruthState(
            t_s=float(t_s),
            q_body_to_ned=np.array(k.q_body_to_ned),
            angular_rate_body_rad_s=np.array(k.angular_rate_body_rad_s),
            specific_force_body_m_s2=np.array(k.specific_force_body_m_s2),
            position_ned_m=np.array(k.position_ned_m),
            velocity_ned_m_s=np.array(k.velocity_ned_m_s),
            magnetic_field_body_ut=np.array(mat_t_vec(k.rotation, field)),
            pressure_pa=env.pressure_pa(alt, t_s),
            temperature_degc=env.temperature_degc(alt, t_s),
            magnetic_disturbance_ned_ut=None if dist is None else np.array(dist),
        )


    def chip_truth(self, t_s: float, *, motion: bool = True) -> ChipTruth:
        """:meth:`truth`'s values in plain floats, computed the same way (the same floats);
        ``motion=False``: the position, pressure and temperature only (no attitude). A
        subclass that overrides :meth:`truth` (a plugin's scenario adding ``other``
        quantities) gets the base's ``chip_truth``, which reads its ``truth``."""
        if type(self).truth is not MotionScenario.truth:
            return super().chip_truth(t_s, motion=motion)
        env = self.environment
        if not motion:
            p = self.motion.position_ned(t_s)
            alt = -p[2]
            return ChipTruth(float(t_s), None, None, None, env.pressure_pa(alt, t_s),
                             env.temperature_degc(alt, t_s), p, None)
        _, _, rotation, rate, force, _, position, velocity = \
            self.motion.kinematics_fields(t_s)
        field, _ = self.field_ned_ut(t_s)
        alt = -position[2]
        return ChipTruth(float(t_s), force, rate, mat_t_vec(rotation, field),
                         env.pressure_pa(alt, t_s), env.temperature_degc(alt, t_s), position,
                         velocity)

    def chip_truths(self, t_s: Sequence[float]) -> list[ChipTruth]:
        """:meth:`chip_truth` (with motion) at each time of ``t_s``, the kinematics of all of
        them in one numpy pass (:meth:`chip_truth_columns`); a trajectory or scenario the
        numpy pass does not cover goes time by time."""
        columns = self._columns(t_s)
        if columns is None:
            return super().chip_truths(t_s)
        force, rate, mag, position, velocity = (
            list(map(tuple, c.tolist())) for c in (
                columns.specific_force_body_m_s2, columns.angular_rate_body_rad_s,
                columns.magnetic_field_body_ut, columns.position_ned_m,
                columns.velocity_ned_m_s))
        return [ChipTruth(t, *row) for t, *row in zip(
            columns.t_s.tolist(), force, rate, mag, columns.pressure_pa.tolist(),
            columns.temperature_degc.tolist(), position, velocity, strict=True)]

    def chip_truth_columns(self, t_s: Sequence[float]) -> TruthColumns | None:
        """:meth:`chip_truths` as columns, the kinematics of every time in one numpy pass
        (:meth:`FlightMotion.kinematics_many`, the same operations as the per-time path);
        the air and a magnetic disturbance per time, as there."""
        columns = self._columns(t_s)
        return super().chip_truth_columns(t_s) if columns is None else columns

    def _columns(self, t_s: Sequence[float]) -> TruthColumns | None:
        """The numpy pass of :meth:`chip_truth_columns`; None where it does not apply (a
        subclass's own truth, a trajectory the pass does not cover, fewer than 2 times)."""
        motion = self.motion
        if (type(self).truth is not MotionScenario.truth or not isinstance(motion, FlightMotion)
                or not motion.vectorised() or len(t_s) < 2):
            return None
        times = [float(t) for t in t_s]
        k = motion.kinematics_many(np.asarray(times))
        if self.disturbance.active:
            fields = [self.field_ned_ut(t)[0] for t in times]
            north, east, down = np.asarray(fields).T
            field: tuple[Any, Any, Any] = (north, east, down)
        else:
            field = self._field_ned
        body_field = mat_t_vec(k.rotation, field)  # type: ignore[arg-type]  # arrays
        env = self.environment
        position = np.array(k.position_ned_m).T
        # the air per time, as the scalar path (math's pow and exp, not numpy's)
        pressure, temperature = [], []
        for t, alt in zip(times, (-position[:, 2]).tolist(), strict=True):
            pressure.append(env.pressure_pa(alt, t))
            temperature.append(env.temperature_degc(alt, t))
        return TruthColumns(np.asarray(times), np.array(k.specific_force_body_m_s2).T,
                            np.array(k.angular_rate_body_rad_s).T, np.array(body_field).T,
                            np.asarray(pressure), np.asarray(temperature), position,
                            np.array(k.velocity_ned_m_s).T)


def chip_vectors(truth: ChipTruth, sensor_to_body: list[list[float]] | None
                 ) -> tuple[Vec3 | None, Vec3 | None, Vec3 | None]:
    """The truth's specific force, body rate and field rotated into a chip's sensor frame
    (``sensor_to_body`` as nested lists; None: aligned with the body); a vector the truth
    leaves out stays None. The same floats as :func:`physical_inputs`."""
    f, w, b = truth.specific_force_body_m_s2, truth.angular_rate_body_rad_s, \
        truth.magnetic_field_body_ut
    return (None if f is None else _rotate(f, sensor_to_body),
            None if w is None else _rotate(w, sensor_to_body),
            None if b is None else _rotate(b, sensor_to_body))


def chip_other(truth: ChipTruth, sensor_to_body: list[list[float]] | None
               ) -> Mapping[str, float | Vec3]:
    """The truth's plugin quantities for one chip (3-vectors in its sensor frame)."""
    return _other_to_sensor(truth.other, sensor_to_body) if truth.other else NO_OTHER


def chip_inputs(truth: ChipTruth, sensor_to_body: list[list[float]] | None) -> PhysicalInputs:
    """:func:`physical_inputs` for a :class:`ChipTruth`: its vectors rotated into the chip's
    sensor frame (:func:`chip_vectors`)."""
    f, w, b = chip_vectors(truth, sensor_to_body)
    return PhysicalInputs(
        specific_force_m_s2=f, angular_rate_rad_s=w, magnetic_field_ut=b,
        pressure_pa=truth.pressure_pa, temperature_degc=truth.temperature_degc,
        position_ned_m=truth.position_ned_m, velocity_ned_m_s=truth.velocity_ned_m_s,
        other=chip_other(truth, sensor_to_body))


def physical_inputs(truth: TruthState, sensor_to_body: Sequence[Sequence[float]] | None = None,
                    *, accel: bool = True, gyro: bool = True, mag: bool = True,
                    pressure: bool = True, temperature: bool = True) -> PhysicalInputs:
    """The truth as one chip sees it: vectors rotated into its sensor frame.

    ``sensor_to_body`` is the mount matrix M with ``v_body = M v_sensor`` (as
    :func:`imuhal.core.frames.parse_mount` returns); None means the chip is aligned with the
    body. Flags leave out quantities the chip does not measure (None in the result).
    """
    m = None if sensor_to_body is None else np.asarray(sensor_to_body, dtype=float).tolist()
    return PhysicalInputs(
        specific_force_m_s2=_to_sensor(truth.specific_force_body_m_s2, m) if accel else None,
        angular_rate_rad_s=_to_sensor(truth.angular_rate_body_rad_s, m) if gyro else None,
        magnetic_field_ut=_to_sensor(truth.magnetic_field_body_ut, m) if mag else None,
        pressure_pa=truth.pressure_pa if pressure else None,
        temperature_degc=truth.temperature_degc if temperature else None,
        position_ned_m=_earth(truth.position_ned_m),
        velocity_ned_m_s=_earth(truth.velocity_ned_m_s),
        other=_other_to_sensor(truth.other, m) if truth.other else NO_OTHER,
    )


def _other_to_sensor(other: Mapping[str, Any], m: list[list[float]] | None
                     ) -> dict[str, float | tuple[float, float, float]]:
    """Plugin quantities' truth for one chip: scalars as they are, 3-vectors rotated into its
    sensor frame like the built-in vectors."""
    return {name: float(v) if np.ndim(v) == 0 else _to_sensor(np.asarray(v), m)
            for name, v in other.items()}


def _earth(v: np.ndarray) -> tuple[float, float, float]:
    x, y, z = np.asarray(v, dtype=float).tolist()
    return (x, y, z)


def _to_sensor(v: np.ndarray, m: list[list[float]] | None) -> tuple[float, float, float]:
    """``M^T v`` for the sensor-to-body matrix M (as nested lists), in plain floats: a
    rotation of three components costs less in Python than a numpy call (this runs for
    every chip at every poll), and gives the same floats as ``m.T @ v``."""
    x, y, z = np.asarray(v, dtype=float).tolist()
    return _rotate((x, y, z), m)


def _rotate(v: tuple[float, float, float], m: list[list[float]] | None
            ) -> tuple[float, float, float]:
    """``M^T v`` on plain floats (see :func:`_to_sensor`)."""
    x, y, z = v
    if m is None:
        return (x, y, z)
    (a, b, c), (d, e, f), (g, h, i) = m
    # Each sum starts from +0.0 as numpy's does, so an exact zero keeps numpy's sign (+0.0).
    return (0.0 + a * x + d * y + g * z, 0.0 + b * x + e * y + h * z,
            0.0 + c * x + f * y + i * z)
