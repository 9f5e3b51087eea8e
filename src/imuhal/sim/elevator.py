"""The ``elevator`` scenario: pure vertical motion, the vario's cleanest test.

The board rides a lift up ``floors`` floors and back down, with trapezoidal speed profiles
(raised-cosine ramps: linear acceleration bursts of about speed * pi / (2 * ramp) peak),
dwelling at the top; the attitude never changes.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class ElevatorParams(WorldParams):
    floors: int = Field(4, ge=1)
    floor_height_m: float = Field(3.2, gt=0)
    speed_m_s: float = Field(1.6, gt=0)
    ramp_s: float = Field(1.5, gt=0)
    start_hold_s: float = Field(5.0, ge=0)
    dwell_s: float = Field(6.0, ge=0)
    yaw_deg: float = 0.0
    roll_deg: float = 0.0
    pitch_deg: float = 0.0


class ElevatorScenario(MotionScenario):
    name: ClassVar[str] = "elevator"
    description: ClassVar[str] = "a lift ride up and down: pure vertical motion, fixed attitude"
    Params = ElevatorParams
    default_duration_s: ClassVar[float] = 40.0

    def build_motion(self) -> Motion:
        p: ElevatorParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        height = p.floors * p.floor_height_m
        ride = height / p.speed_m_s + p.ramp_s
        down = Signal()
        t = p.start_hold_s
        self.add_phase("still", 0.0, t)
        down.sweep(t, ride, -height, p.ramp_s)
        self.add_phase("up", t, t + ride)
        t += ride
        self.add_phase("top", t, t + p.dwell_s)
        t += p.dwell_s
        down.sweep(t, ride, height, p.ramp_s)
        self.add_phase("down", t, t + ride)
        self.add_phase("still", t + ride, math.inf)
        return FlightMotion(roll=Signal(math.radians(p.roll_deg)),
                            pitch=Signal(math.radians(p.pitch_deg)),
                            yaw=Signal(math.radians(p.yaw_deg)), down=down,
                            gravity_m_s2=p.environment.gravity_m_s2)
