"""The ``thermal`` scenario: a paraglider working a thermal, the seed's own use case.

A scripted climb-rate schedule (glide sink, thermal climbs, strong sinks) with smooth
raised-cosine transitions, so altitude, climb rate and vertical acceleration are exact
derivatives of one another. This first version holds the attitude level and the heading
fixed; banked circling, turbulence and horizontal motion belong to the full simulator.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from pydantic import Field

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.sim.environment import Environment
from imuhal.sim.scenario import Scenario, ScenarioParams, TruthState


class ThermalParams(ScenarioParams):
    schedule: tuple[tuple[float, float], ...] = (
        (0.0, 0.0),     # on the ground, still, for the first seconds
        (5.0, -1.1),    # glide
        (15.0, 2.5),    # first thermal
        (35.0, -3.0),   # sink
        (42.0, 1.2),    # weak thermal
        (60.0, -1.1),   # glide
    )
    """(start time s, climb rate m/s, up +) segments; the last lasts to the end."""
    transition_s: float = Field(2.0, gt=0)
    """Each change of climb rate takes this long (raised cosine)."""
    environment: Environment = Environment()


class ThermalScenario(Scenario):
    name: ClassVar[str] = "thermal"
    description: ClassVar[str] = "paraglider climbing in thermals, sinking and gliding"
    Params = ThermalParams
    default_duration_s: ClassVar[float] = 60.0

    def _vertical(self, t_s: float) -> tuple[float, float, float]:
        """(altitude m, climb m/s, vertical acceleration m/s^2), all up positive."""
        p: ThermalParams = self.params  # type: ignore[assignment]
        sched = p.schedule
        tau = p.transition_s
        climb, accel = sched[0][1], 0.0
        # Integrate segment by segment: each change is a raised cosine from prev to new rate.
        alt = 0.0
        t_prev = 0.0
        rate = sched[0][1]
        for start, new_rate in sched[1:]:
            if t_s <= start:
                break
            alt += rate * (start - t_prev)
            dv = new_rate - rate
            dt = min(t_s - start, tau)
            # v(s) = rate + dv (1 - cos(pi s / tau)) / 2 for s in [0, tau]
            alt += rate * dt + dv / 2 * (dt - tau / math.pi * math.sin(math.pi * dt / tau))
            if t_s - start < tau:
                climb = rate + dv * (1 - math.cos(math.pi * dt / tau)) / 2
                accel = dv * math.pi / (2 * tau) * math.sin(math.pi * dt / tau)
                return alt, climb, accel
            t_prev = start + tau
            rate = new_rate
        alt += rate * (t_s - t_prev)
        return alt, rate, 0.0

    def truth(self, t_s: float) -> TruthState:
        p: ThermalParams = self.params  # type: ignore[assignment]
        env = p.environment
        alt, climb, accel_up = self._vertical(t_s)
        q = quat_from_euler_deg(0.0, 0.0, 0.0)
        r = quat_to_matrix(q)
        accel_ned = np.array([0.0, 0.0, -accel_up])
        specific_force_body = r.T @ (accel_ned - env.gravity_ned())
        return TruthState(
            t_s=t_s,
            q_body_to_ned=q,
            angular_rate_body_rad_s=np.zeros(3),
            specific_force_body_m_s2=specific_force_body,
            position_ned_m=np.array([0.0, 0.0, -alt]),
            velocity_ned_m_s=np.array([0.0, 0.0, -climb]),
            magnetic_field_body_ut=r.T @ env.magnetic_field_ned_ut(),
            pressure_pa=env.pressure_pa(alt, t_s),
            temperature_degc=env.temperature_degc(alt),
        )
