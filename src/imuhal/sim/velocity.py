"""A simulated GNSS-grade velocity source: what a GPS receiver would report about a scenario.

A receiver measures velocity over ground at a fixed rate, with white noise, and reports each
epoch some time later (its latency). :func:`gnss_velocity_samples` turns a scenario's truth
into the :class:`~imuhal.core.samples.VelocitySample` stream such a receiver produces: each
sample's ``t_ns`` is its measurement epoch, and it is paired with the time it arrives, so a
consumer can be fed in arrival order exactly as a live pipeline would feed it. The defaults
(5 Hz, 0.1 m/s noise per axis, 100 ms latency) are an ordinary u-blox-class receiver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imuhal.core.samples import VelocitySample
from imuhal.sim.scenario import Scenario


@dataclass(frozen=True)
class GnssVelocityModel:
    """Rate (Hz), white noise per NED axis (m/s, 1 sigma) and latency (s) of the receiver."""

    rate_hz: float = 5.0
    noise_m_s: float = 0.1
    latency_s: float = 0.1

    def __post_init__(self) -> None:
        if not (self.rate_hz > 0 and self.noise_m_s >= 0 and self.latency_s >= 0):
            raise ValueError(f"GNSS velocity model needs rate > 0, noise >= 0, latency >= 0: "
                             f"{self}")


def gnss_velocity_samples(scenario: Scenario, duration_s: float,
                          model: GnssVelocityModel = GnssVelocityModel(), *, seed: int = 0,
                          device: str = "gnss") -> list[tuple[int, VelocitySample]]:
    """(arrival time ns, sample) pairs for epochs at 0, 1/rate, ... < ``duration_s``; the
    noise is seeded by ``seed`` alone (independent of the scenario's own randomness)."""
    rng = np.random.default_rng(seed)
    period_ns = round(1e9 / model.rate_hz)
    latency_ns = round(model.latency_s * 1e9)
    out: list[tuple[int, VelocitySample]] = []
    t_ns = 0
    while t_ns < duration_s * 1e9:
        v = scenario.truth(t_ns / 1e9).velocity_ned_m_s + rng.normal(0.0, model.noise_m_s, 3)
        sample = VelocitySample(t_ns=t_ns, device=device, accuracy_m_s=model.noise_m_s,
                                velocity_ned_m_s=(float(v[0]), float(v[1]), float(v[2])))
        out.append((t_ns + latency_ns, sample))
        t_ns += period_ns
    return out
