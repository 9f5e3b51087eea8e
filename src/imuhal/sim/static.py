"""The ``static`` scenario: the board lying still on a bench."""

from __future__ import annotations

import math
from typing import ClassVar

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class StaticParams(WorldParams):
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    yaw_deg: float = 0.0
    """Fixed attitude (ZYX Euler, degrees; yaw from true north)."""


class StaticScenario(MotionScenario):
    name: ClassVar[str] = "static"
    description: ClassVar[str] = "board at rest on a bench at a fixed attitude"
    Params = StaticParams
    default_duration_s: ClassVar[float] = 30.0

    def build_motion(self) -> Motion:
        p: StaticParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        self.add_phase("still", 0.0, math.inf)
        return FlightMotion(roll=Signal(math.radians(p.roll_deg)),
                            pitch=Signal(math.radians(p.pitch_deg)),
                            yaw=Signal(math.radians(p.yaw_deg)),
                            gravity_m_s2=p.environment.gravity_m_s2)
