"""What a scenario is: a function of time to the true state of the vehicle and its world."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict

from imuhal.core.frames import FloatArray, euler_deg_from_quat
from imuhal.sim.inputs import NO_OTHER


class ScenarioParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True, slots=True)
class TruthState:
    """The true state at ``t_s`` (float seconds from the scenario start).

    Body frame is NED-aligned FRD (x forward, y right, z down); the earth frame is NED.
    """

    t_s: float
    q_body_to_ned: FloatArray
    angular_rate_body_rad_s: FloatArray
    specific_force_body_m_s2: FloatArray
    """Accelerometer truth: a - g, in body axes (level at rest: (0, 0, -9.81))."""
    position_ned_m: FloatArray
    velocity_ned_m_s: FloatArray
    magnetic_field_body_ut: FloatArray
    """What a magnetometer should read: earth field plus any disturbance, in body axes."""
    pressure_pa: float
    temperature_degc: float
    """The board's temperature (what the chips' thermometers measure)."""
    magnetic_disturbance_ned_ut: FloatArray | None = None
    """The disturbance part of the field in NED (None: the scenario has none)."""
    other: Mapping[str, float | tuple[float, float, float]] = field(
        default_factory=lambda: NO_OTHER)
    """Truth of quantities imuhal does not model (a plugin's scenario fills them), by quantity
    name: a scalar, or a 3-vector in body axes. Chips see it as ``PhysicalInputs.other``."""

    @property
    def euler_deg(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) in degrees, ZYX, yaw in [-180, 180] from true north."""
        return euler_deg_from_quat(self.q_body_to_ned)

    @property
    def altitude_m(self) -> float:
        """Height above the scenario's origin (m, up positive)."""
        return float(-self.position_ned_m[2])

    @property
    def climb_m_s(self) -> float:
        """Vertical speed (m/s, up positive)."""
        return float(-self.velocity_ned_m_s[2])


class ChipTruth(NamedTuple):
    """The part of the truth at ``t_s`` that chips measure, in plain floats: what an
    emulated board computes at every poll of every chip (a :class:`TruthState` holds numpy
    arrays, which cost more to build and to read back than the arithmetic that fills them;
    a named tuple is built faster than a frozen dataclass). Body frame FRD, earth frame
    NED, SI units, as in :class:`TruthState`.

    ``motion=False`` (:meth:`Scenario.chip_truth`): a light truth for chips that measure no
    motion (barometers): the vectors that need the attitude are None.
    """

    t_s: float
    specific_force_body_m_s2: tuple[float, float, float] | None
    angular_rate_body_rad_s: tuple[float, float, float] | None
    magnetic_field_body_ut: tuple[float, float, float] | None
    pressure_pa: float
    temperature_degc: float
    position_ned_m: tuple[float, float, float]
    velocity_ned_m_s: tuple[float, float, float] | None
    other: Mapping[str, float | tuple[float, float, float]] = NO_OTHER


class TruthColumns(NamedTuple):
    """:class:`ChipTruth` at n times as columns: (n,) times and scalars, (n, 3) vectors
    (:meth:`Scenario.chip_truth_columns`), row i the same floats as the ChipTruth of the
    i-th time."""

    t_s: np.ndarray
    specific_force_body_m_s2: np.ndarray
    angular_rate_body_rad_s: np.ndarray
    magnetic_field_body_ut: np.ndarray
    pressure_pa: np.ndarray
    temperature_degc: np.ndarray
    position_ned_m: np.ndarray
    velocity_ned_m_s: np.ndarray


def _floats3(v: FloatArray) -> tuple[float, float, float]:
    x, y, z = np.asarray(v, dtype=float).tolist()
    return (x, y, z)


@dataclass(frozen=True, slots=True)
class Phase:
    """A labelled interval of a scenario (e.g. one calibration position held still)."""

    name: str
    start_s: float
    end_s: float


class Scenario(ABC):
    """A named, parameterised motion and environment with known truth.

    Subclasses set ``name``, ``description``, ``Params`` and ``default_duration_s`` and
    implement ``truth``. ``seed`` drives any randomness (turbulence, gusts), reproducibly.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    Params: ClassVar[type[ScenarioParams]] = ScenarioParams
    default_duration_s: ClassVar[float] = 60.0

    def __init__(self, params: ScenarioParams | dict[str, Any] | None = None, *,
                 seed: int = 0) -> None:
        if params is None:
            params = self.Params()
        elif not isinstance(params, self.Params):
            params = self.Params.model_validate(params)
        self.params = params
        self.seed = seed
        self.rng = np.random.default_rng(seed)

    @abstractmethod
    def truth(self, t_s: float) -> TruthState:
        """The true state at ``t_s``; must be a pure function of ``t_s`` and the seed."""

    def chip_truths(self, t_s: Sequence[float]) -> list[ChipTruth]:
        """:meth:`chip_truth` (with motion) at each time of ``t_s``: what an emulated chip's
        FIFO fill of n instants asks for in one call. The base asks :meth:`chip_truth` at
        each; a scenario that can evaluate many times at once overrides this."""
        return [self.chip_truth(t) for t in t_s]

    def chip_truth_columns(self, t_s: Sequence[float]) -> TruthColumns | None:
        """:meth:`chip_truths` as columns (the same floats); None when the truth carries
        ``other`` quantities, which have no columns. The base stacks :meth:`chip_truths`; a
        scenario that evaluates many times at once in numpy overrides this."""
        truths = self.chip_truths(t_s)
        if not truths or any(t.other for t in truths):
            return None
        return TruthColumns(
            np.array([t.t_s for t in truths], dtype=float),
            *(np.array([getattr(t, name) for t in truths], dtype=float) for name in (
                "specific_force_body_m_s2", "angular_rate_body_rad_s",
                "magnetic_field_body_ut", "pressure_pa", "temperature_degc",
                "position_ned_m", "velocity_ned_m_s")))

    def chip_truth(self, t_s: float, *, motion: bool = True) -> ChipTruth:
        """What chips measure at ``t_s``, in plain floats: the same values as
        ``truth(t_s)``. ``motion=False`` may leave out what needs the attitude (the base
        computes it all; a scenario that can skip it cheaply overrides this)."""
        s = self.truth(t_s)
        return ChipTruth(
            t_s=s.t_s,
            specific_force_body_m_s2=_floats3(s.specific_force_body_m_s2),
            angular_rate_body_rad_s=_floats3(s.angular_rate_body_rad_s),
            magnetic_field_body_ut=_floats3(s.magnetic_field_body_ut),
            pressure_pa=s.pressure_pa,
            temperature_degc=s.temperature_degc,
            position_ned_m=_floats3(s.position_ned_m),
            velocity_ned_m_s=_floats3(s.velocity_ned_m_s),
            other=s.other,
        )

    def phases(self) -> tuple[Phase, ...]:
        """Labelled intervals of the run (holds, manoeuvres); empty unless a scenario has any."""
        return ()
