"""The ``rc-flight`` scenario: an RC aeroplane taking off and flying aerobatics.

The aeroplane flies along its nose (no angle of attack or sideslip), so a pitch rate q at
speed V loads the wings with V*q: loops and pull-ups reach several g and the push-over goes
through zero g and negative g, far outside the 0.6-1.4 g window in which the seed's gated
Madgwick trusts its accelerometer. Sequence: still on the ground, take-off run (a linear
acceleration burst), climb, loop, axial roll, high-g pull-up and push-over, a coordinated
360 deg banked turn, descent, cruise. Light turbulence in roll and pitch is seeded.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class RcFlightParams(WorldParams):
    cruise_speed_m_s: float = Field(20.0, gt=0)
    ground_s: float = Field(3.0, ge=0)
    """Still on the ground before the take-off run."""
    takeoff_run_s: float = Field(4.0, gt=0)
    climb_pitch_deg: float = 12.0
    loop_s: float = Field(4.0, gt=0)
    roll_s: float = Field(2.5, gt=0)
    pullup_pitch_deg: float = 50.0
    pullup_s: float = Field(1.2, gt=0)
    turn_s: float = Field(8.0, gt=0)
    """Duration of the coordinated 360 deg turn (bank follows from speed and turn rate)."""
    heading_deg: float = 0.0
    turbulence_rms_deg: float = Field(1.5, ge=0)


class RcFlightScenario(MotionScenario):
    name: ClassVar[str] = "rc-flight"
    description: ClassVar[str] = ("RC aeroplane: take-off, loop, roll, high-g pull-up and "
                                  "push-over, banked turn")
    Params = RcFlightParams
    default_duration_s: ClassVar[float] = 60.0

    def build_motion(self) -> Motion:
        p: RcFlightParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        two_pi = 2 * math.pi
        speed, pitch, roll = Signal(), Signal(), Signal()
        yaw = Signal(math.radians(p.heading_deg))
        t = p.ground_s
        self.add_phase("on ground", 0.0, t)
        speed.step_to(t, p.takeoff_run_s, p.cruise_speed_m_s)
        self.add_phase("take-off run", t, t + p.takeoff_run_s)
        t += p.takeoff_run_s - 1.0
        pitch.step(t, 2.0, math.radians(p.climb_pitch_deg))
        pitch.step(t + 6.0, 2.0, -math.radians(p.climb_pitch_deg))
        self.add_phase("climb", t, t + 8.0)
        t += 10.0
        pitch.sweep(t, p.loop_s, two_pi, min(0.6, p.loop_s / 3))
        self.add_phase("loop", t, t + p.loop_s)
        t += p.loop_s + 2.0
        roll.sweep(t, p.roll_s, two_pi, min(0.5, p.roll_s / 3))
        self.add_phase("axial roll", t, t + p.roll_s)
        t += p.roll_s + 2.0
        pitch.step(t, p.pullup_s, math.radians(p.pullup_pitch_deg))
        self.add_phase("pull-up", t, t + p.pullup_s)
        t += p.pullup_s + 0.8
        pitch.step(t, p.pullup_s, -math.radians(p.pullup_pitch_deg))
        self.add_phase("push-over", t, t + p.pullup_s)
        t += p.pullup_s + 2.0
        yaw.sweep(t, p.turn_s, two_pi, min(1.0, p.turn_s / 3))
        self.add_phase("banked turn", t, t + p.turn_s)
        t += p.turn_s + 2.0
        pitch.step(t, 2.0, -math.radians(8.0))
        pitch.step(t + 6.0, 2.0, math.radians(8.0))
        self.add_phase("descent", t, t + 8.0)
        airborne = p.ground_s + p.takeoff_run_s
        if p.turbulence_rms_deg > 0:
            for sig in (roll, pitch):
                sig.turbulence(self.rng, math.radians(p.turbulence_rms_deg), f_min_hz=0.3,
                               f_max_hz=2.0, tones=6, t_on=airborne, ramp_s=2.0)
        return FlightMotion(yaw=yaw, pitch=pitch, roll=roll, coordinated_bank=True,
                            speed_along_nose=speed, gravity_m_s2=p.environment.gravity_m_s2)
