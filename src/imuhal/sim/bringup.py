"""The ``bringup`` scenario: the board bring-up motions, performed on cue.

What a user does at the bench when ``imuhal check-mounts`` (or the live page) asks: the
board rests level, then tilts its nose up, returns level, rolls right (right side down),
returns level, turns right (clockwise seen from above). Each motion has a phase named for
it (``nose-up``, ``roll-right``, ``turn-right``) that starts still, contains the whole
motion and ends holding it; the returns to level are phases named ``return``.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class BringupParams(WorldParams):
    settle_s: float = Field(2.0, ge=0)
    """Level and still at the start (start-up gyro offsets are measured then)."""
    window_s: float = Field(3.0, gt=0)
    """Length of each motion's phase: still, the motion, then held."""
    move_s: float = Field(1.0, gt=0)
    """Duration of each motion (and of each return to level), s."""
    return_s: float = Field(2.0, gt=0)
    """Time between one motion's phase and the next (the board goes back to level)."""
    tilt_deg: float = 30.0
    """Nose-up pitch and right roll (deg)."""
    turn_deg: float = 90.0
    """Right turn (deg)."""
    heading_deg: float = 0.0
    """Heading at the start (deg from true north)."""


class BringupScenario(MotionScenario):
    name: ClassVar[str] = "bringup"
    description: ClassVar[str] = ("board bring-up motions on cue: nose up, roll right, turn "
                                  "right (imuhal check-mounts)")
    Params = BringupParams
    default_duration_s: ClassVar[float] = 16.0

    def build_motion(self) -> Motion:
        p: BringupParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        lead = min(0.5, max(0.0, (p.window_s - p.move_s) / 2))
        pitch, roll = Signal(), Signal()
        yaw = Signal(math.radians(p.heading_deg))
        t = p.settle_s
        self.add_phase("still", 0.0, t)
        for key, signal, angle in (("nose-up", pitch, p.tilt_deg),
                                   ("roll-right", roll, p.tilt_deg)):
            self.add_phase(key, t, t + p.window_s)
            signal.step_to(t + lead, p.move_s, math.radians(angle))
            t += p.window_s
            self.add_phase("return", t, t + p.return_s)
            signal.step_to(t + max(0.0, min(lead, p.return_s - p.move_s)), p.move_s, 0.0)
            t += p.return_s
        self.add_phase("turn-right", t, t + p.window_s)
        yaw.step_to(t + lead, p.move_s, math.radians(p.heading_deg + p.turn_deg))
        self.add_phase("still", t + p.window_s, math.inf)
        return FlightMotion(roll=roll, pitch=pitch, yaw=yaw,
                            gravity_m_s2=p.environment.gravity_m_s2)
