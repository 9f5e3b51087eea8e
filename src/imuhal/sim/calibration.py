"""The ``calibration`` scenario: the seed's calibration procedure, performed by hand.

First the six accelerometer positions (each body axis pointing down, then up), each held
still for ``hold_s`` and joined by smooth ``move_s`` turns; then the magnetometer
figure-of-8: roll and pitch swing as a 1:2 Lissajous figure while the heading sweeps full
circles, so the board visits orientations all over the sphere. Each hold is a phase named
after the body axis that points down (``"+z down"`` is level).
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import Field

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams

# (name, roll deg, pitch deg): angles are reached continuously from one to the next.
SIX_POSITIONS: tuple[tuple[str, float, float], ...] = (
    ("+z down", 0.0, 0.0),        # level, as the seed's step 1
    ("-z down", 180.0, 0.0),      # upside down
    ("-y down", 270.0, 0.0),      # roll -90: left side down (body +y points up)
    ("+y down", 450.0, 0.0),      # roll +90: right side down, reached by rolling on
    ("+x down", 360.0, -90.0),    # nose down
    ("-x down", 360.0, 90.0),     # nose up
)


class CalibrationParams(WorldParams):
    positions: tuple[tuple[str, float, float], ...] = SIX_POSITIONS
    """(name, roll deg, pitch deg) held in turn; angles are unwrapped targets."""
    hold_s: float = Field(4.0, gt=0)
    move_s: float = Field(3.0, gt=0)
    yaw_deg: float = 30.0
    figure8_cycles: int = Field(3, ge=0)
    figure8_period_s: float = Field(10.0, gt=0)
    figure8_roll_deg: float = Field(130.0, ge=0)
    """Well past 90 deg, so the board's z axis also points up into steep fields (64 deg dip)."""
    figure8_pitch_deg: float = Field(60.0, ge=0)
    figure8_yaw_turns_per_cycle: float = 0.618
    """Heading turns per figure-8 cycle; not a simple ratio, so successive cycles visit new
    orientations instead of retracing the same curve."""
    figure8_ramp_s: float = Field(2.0, gt=0)
    final_hold_s: float = Field(2.0, ge=0)


class CalibrationScenario(MotionScenario):
    name: ClassVar[str] = "calibration"
    description: ClassVar[str] = ("six accelerometer positions held still, then a "
                                  "figure-of-8 magnetometer motion")
    Params = CalibrationParams
    default_duration_s: ClassVar[float] = 80.0

    def build_motion(self) -> Motion:
        p: CalibrationParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        first = p.positions[0] if p.positions else ("+z down", 0.0, 0.0)
        roll = Signal(math.radians(first[1]))
        pitch = Signal(math.radians(first[2]))
        yaw = Signal(math.radians(p.yaw_deg))
        t = 0.0
        for i, (name, r_deg, p_deg) in enumerate(p.positions):
            if i > 0:
                roll.step_to(t, p.move_s, math.radians(r_deg))
                pitch.step_to(t, p.move_s, math.radians(p_deg))
                t += p.move_s
            self.add_phase(name, t, t + p.hold_s)
            t += p.hold_s
        # Back to level (roll a multiple of a full turn) for the figure of 8.
        r_now = roll.base_state(t)[0]
        roll.step_to(t, p.move_s, 2 * math.pi * round(r_now / (2 * math.pi)))
        pitch.step_to(t, p.move_s, 0.0)
        t += p.move_s
        if p.figure8_cycles:
            ramp = p.figure8_ramp_s
            span = p.figure8_cycles * p.figure8_period_s + 2 * ramp
            roll.oscillate(math.radians(p.figure8_roll_deg), p.figure8_period_s,
                           t_on=t, t_off=t + span, ramp_s=ramp,
                           phase_rad=-2 * math.pi * t / p.figure8_period_s)
            pitch.oscillate(math.radians(p.figure8_pitch_deg), p.figure8_period_s / 2,
                            t_on=t, t_off=t + span, ramp_s=ramp,
                            phase_rad=-4 * math.pi * t / p.figure8_period_s)
            yaw.sweep(t, span, 2 * math.pi * p.figure8_cycles * p.figure8_yaw_turns_per_cycle,
                      ramp)
            self.add_phase("figure-8", t, t + span)
            t += span
        self.add_phase("final hold", t, t + p.final_hold_s)
        return FlightMotion(roll=roll, pitch=pitch, yaw=yaw,
                            gravity_m_s2=p.environment.gravity_m_s2)
