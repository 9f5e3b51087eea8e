"""The ``thermal`` scenario: a paraglider working thermals, the seed's own use case.

The glider sits still on launch, then flies at a constant airspeed along its heading while
a climb-rate schedule (glide sink, thermal climbs, strong sinks) plays out with smooth
raised-cosine transitions. In every thermal (climb at least ``circle_min_climb_m_s``) it
circles at a constant turn rate with a coordinated bank (tan(bank) = V * turn rate / g),
alternating left and right. Turbulence adds seeded vertical gusts and the pilot's pendulum
swing in roll and pitch; a constant wind drifts the whole flight.

Altitude, climb rate and vertical acceleration are exact derivatives of one another, and
so are heading, turn rate and bank; see :mod:`imuhal.sim.motion`.
"""

from __future__ import annotations

import itertools
import math
from typing import ClassVar

from pydantic import Field, model_validator

from imuhal.sim.motion import FlightMotion, Motion
from imuhal.sim.signals import Signal
from imuhal.sim.world import MotionScenario, WorldParams


class ThermalParams(WorldParams):
    schedule: tuple[tuple[float, float], ...] = (
        (0.0, 0.0),     # on the ground, still, for the first seconds
        (5.0, -1.1),    # glide
        (15.0, 2.5),    # first thermal
        (35.0, -3.0),   # sink
        (42.0, 1.2),    # weak thermal
        (60.0, -1.1),   # glide
    )
    """(start time s, climb rate m/s, up +) segments; the last lasts to the end."""
    transition_s: float = Field(3.0, gt=0)
    """Each change of climb rate (and of turn rate, airspeed) takes this long (raised cosine)."""
    launch_s: float = Field(5.0, ge=0)
    """Still on launch until then; the airspeed builds up over ``transition_s``."""
    airspeed_m_s: float = Field(10.0, ge=0)
    """Horizontal speed through the air, along the heading (trim speed of a paraglider)."""
    heading_deg: float = 0.0
    """Initial heading, from true north, clockwise."""
    circle_min_climb_m_s: float = 0.5
    """Segments climbing at least this fast are thermals: the glider circles in them."""
    turn_period_s: float = Field(20.0, gt=0)
    """Time for one full circle in a thermal."""
    first_turn_right: bool = True
    """Direction of the first thermal's circles; later thermals alternate."""
    gust_rms_m_s: float = Field(0.15, ge=0)
    """RMS of the vertical gusts (m/s) once airborne."""
    pendulum_rms_deg: float = Field(2.0, ge=0)
    """RMS of the pilot's pendulum swing in roll and in pitch once airborne."""
    wind_ne_m_s: tuple[float, float] = (2.0, 1.0)
    """Horizontal wind (north, east), which drifts the glider once airborne."""

    @model_validator(mode="after")
    def _schedule_is_playable(self) -> ThermalParams:
        starts = [s for s, _ in self.schedule]
        if not starts:
            raise ValueError("schedule needs at least one (start, climb) segment")
        for a, b in itertools.pairwise(starts[1:]):
            if b < a + self.transition_s:
                raise ValueError(f"schedule changes at {a} s and {b} s are closer than "
                                 f"transition_s = {self.transition_s} s")
        return self


class ThermalScenario(MotionScenario):
    name: ClassVar[str] = "thermal"
    description: ClassVar[str] = ("paraglider launching, gliding, circling in thermals with "
                                  "coordinated banked turns, sinking, with turbulence")
    Params = ThermalParams
    default_duration_s: ClassVar[float] = 60.0

    def build_motion(self) -> Motion:
        p: ThermalParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        tau = p.transition_s
        sched = p.schedule
        down = Signal(0.0, rate=-sched[0][1])
        yaw = Signal(math.radians(p.heading_deg))
        turn_rate = 2.0 * math.pi / p.turn_period_s
        direction = 1.0 if p.first_turn_right else -1.0
        bounds = [*sched[1:], (math.inf, 0.0)]
        for i, (start, climb) in enumerate(sched):
            end = bounds[i][0]
            if i > 0:
                down.rate_to(start, tau, -climb)
            if climb >= p.circle_min_climb_m_s and math.isfinite(end):
                yaw.rate_to(max(start, 0.0), tau, direction * turn_rate)
                yaw.rate_to(end, tau, 0.0)
                self.add_phase(f"thermal {'right' if direction > 0 else 'left'}", start, end)
                direction = -direction
            elif climb >= p.circle_min_climb_m_s:
                yaw.rate_to(max(start, 0.0), tau, direction * turn_rate)
                self.add_phase("thermal", start, math.inf)
        self.add_phase("on launch", 0.0, p.launch_s)

        speed = Signal(0.0)
        if p.airspeed_m_s > 0:
            speed.step_to(p.launch_s, tau, p.airspeed_m_s)
        airborne = p.launch_s + tau
        roll, pitch = Signal(), Signal()
        if p.pendulum_rms_deg > 0:
            for sig in (roll, pitch):
                sig.turbulence(self.rng, math.radians(p.pendulum_rms_deg), f_min_hz=0.2,
                               f_max_hz=0.6, tones=6, t_on=airborne, ramp_s=3.0)
        if p.gust_rms_m_s > 0:
            down.turbulence(self.rng, p.gust_rms_m_s, f_min_hz=0.05, f_max_hz=0.4,
                            tones=8, t_on=airborne, ramp_s=3.0, derivative=1)
        # The wind carries the glider only once it is airborne (drift builds up with speed).
        north = east = None
        if p.wind_ne_m_s != (0.0, 0.0):
            north = Signal().rate_to(p.launch_s, tau, p.wind_ne_m_s[0])
            east = Signal().rate_to(p.launch_s, tau, p.wind_ne_m_s[1])
        return FlightMotion(yaw=yaw, pitch=pitch, roll=roll, coordinated_bank=True,
                            speed_along_heading=speed, down=down, north=north, east=east,
                            gravity_m_s2=p.environment.gravity_m_s2)
