"""The ``magnet`` scenario: the board still on a bench while magnets are carried past it.

The disturbance is the dipole field of each pass (see :mod:`imuhal.sim.magnetic`) plus a
slow drift; its truth is ``TruthState.magnetic_disturbance_ned_ut``. Each pass is a phase
(``"magnet pass i"``) spanning the time the disturbance exceeds about 1 % of its peak.
"""

from __future__ import annotations

import math
from typing import ClassVar

from imuhal.sim.magnetic import MagneticDisturbanceSpec, MagnetPass
from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams

DEFAULT_PASSES = MagneticDisturbanceSpec(
    slow_rms_ut=0.5,
    passes=(
        MagnetPass(t_closest_s=10.0, closest_distance_m=0.30, moment_a_m2=0.5),
        MagnetPass(t_closest_s=22.0, closest_distance_m=0.12, moment_a_m2=0.5,
                   moment_direction=(0.0, 0.0, 1.0), path_direction=(1.0, 0.0, 0.0)),
        MagnetPass(t_closest_s=34.0, closest_distance_m=0.06, moment_a_m2=1.0,
                   moment_direction=(0.0, 1.0, 0.0), path_direction=(1.0, 1.0, 0.0),
                   offset_direction=(0.0, 0.0, 1.0), speed_m_s=0.4),
    ),
)


class MagnetParams(WorldParams):
    magnetic: MagneticDisturbanceSpec = DEFAULT_PASSES
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    yaw_deg: float = 45.0


class MagnetScenario(MotionScenario):
    name: ClassVar[str] = "magnet"
    description: ClassVar[str] = "board at rest while magnets pass by (magnetic disturbance)"
    Params = MagnetParams
    default_duration_s: ClassVar[float] = 45.0

    def build_motion(self) -> Motion:
        p: MagnetParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        for i, mp in enumerate(p.magnetic.passes, start=1):
            # |B| ~ 1/r^3: below 1 % of the peak once r > 4.6 d, i.e. |dt| > 4.5 d / v.
            half = 4.5 * mp.closest_distance_m / mp.speed_m_s
            self.add_phase(f"magnet pass {i}", mp.t_closest_s - half, mp.t_closest_s + half)
        return FlightMotion(roll=Signal(math.radians(p.roll_deg)),
                            pitch=Signal(math.radians(p.pitch_deg)),
                            yaw=Signal(math.radians(p.yaw_deg)),
                            gravity_m_s2=p.environment.gravity_m_s2)
