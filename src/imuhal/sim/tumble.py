"""The ``tumble`` scenario: full turns about each body axis and about skewed axes, then a
free tumble with all three Euler angles swinging at once."""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from imuhal.sim.motion import BodyRotation, FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class TumbleParams(WorldParams):
    axes: tuple[tuple[float, float, float], ...] = (
        (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 1.0), (1.0, -2.0, 0.5))
    """Body axes to turn about, in order (normalised on use)."""
    turns: float = 1.0
    """Turns about each axis (negative: the other way)."""
    rotation_s: float = Field(4.0, gt=0)
    ramp_s: float = Field(0.8, gt=0)
    hold_s: float = Field(2.0, ge=0)
    """Still before the first and after every rotation."""
    free_tumble_s: float = Field(12.0, ge=0)
    free_amplitude_deg: float = Field(120.0, ge=0)
    """Amplitude of the roll/pitch/yaw swings in the free tumble (seeded periods)."""


class TumbleScenario(MotionScenario):
    name: ClassVar[str] = "tumble"
    description: ClassVar[str] = "rotations about every body axis and skewed axes, then a tumble"
    Params = TumbleParams
    default_duration_s: ClassVar[float] = 50.0

    def build_motion(self) -> Motion:
        p: TumbleParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        t = p.hold_s
        self.add_phase("still", 0.0, t)
        rotations = []
        for axis in p.axes:
            angle = Signal().sweep(t, p.rotation_s, 2 * math.pi * p.turns, p.ramp_s)
            rotations.append(BodyRotation(axis, angle))
            self.add_phase(f"turn about {axis}", t, t + p.rotation_s)
            t += p.rotation_s + p.hold_s
        roll, pitch, yaw = Signal(), Signal(), Signal()
        if p.free_tumble_s > 0:
            amp = math.radians(p.free_amplitude_deg)
            for sig in (roll, pitch, yaw):
                period = float(self.rng.uniform(3.0, 6.0))
                sig.oscillate(amp, period, t_on=t, t_off=t + p.free_tumble_s,
                              ramp_s=min(2.0, p.free_tumble_s / 2),
                              phase_rad=float(self.rng.uniform(0, 2 * math.pi)))
            self.add_phase("free tumble", t, t + p.free_tumble_s)
            t += p.free_tumble_s
        self.add_phase("still", t, math.inf)
        return FlightMotion(roll=roll, pitch=pitch, yaw=yaw, body_rotations=rotations,
                            gravity_m_s2=p.environment.gravity_m_s2)
