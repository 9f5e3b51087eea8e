"""The truth of many instants in one numpy pass (``Signal.many``,
``FlightMotion.kinematics_many``, ``Scenario.chip_truths``) gives the floats of the
per-instant path bit for bit: an emulated chip's FIFO fill takes its truth from it, and
board runs are compared bit for bit. numpy's ``sin``/``cos`` agree with ``math``'s on this
platform for these arguments; its ``arctan`` does not everywhere, so the bank uses
``math.atan``."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.plugins.manager import load_registry
from imuhal.sim.motion import FlightMotion
from imuhal.sim.signals import Signal

# Instants off any round grid (4.000001 ms apart, as a chip 0.25 ppm slow), and a few
# random ones, across transitions, tone windows and their ramps.
_TIMES = np.concatenate([np.arange(0, 37_500, 3) * 0.004000001,
                         np.random.default_rng(7).uniform(0.0, 150.0, 1000)])


def _signal() -> Signal:
    sig = Signal(0.3, rate=-0.2).step(2.0, 3.0, 1.5).rate_to(6.0, 2.0, 0.7)
    sig.oscillate(0.4, 1.7, t_on=1.0, t_off=11.0, ramp_s=2.0, phase_rad=-0.8)
    return sig.turbulence(np.random.default_rng(3), 0.25, f_min_hz=0.1, f_max_hz=2.0,
                          tones=7, t_on=3.0, t_off=15.0, ramp_s=1.5, derivative=1)


def test_signal_many_gives_the_per_time_floats_through_transitions_and_tone_ramps() -> None:
    sig = _signal()
    t = np.linspace(0.0, 16.0, 4001)
    v, r, a = sig.many(t)
    assert [tuple(x) for x in np.stack([v, r, a], 1).tolist()] == [sig(x) for x in t.tolist()]


@pytest.mark.parametrize("name", ["thermal", "tumble", "rc-flight", "static"])
def test_chip_truths_equal_chip_truth_at_every_instant(name: str) -> None:
    scenario = load_registry().scenarios.get(name)(None, seed=0)
    times = sorted(float(t) for t in _TIMES[_TIMES < 150.0])
    assert scenario.chip_truths(times) == [scenario.chip_truth(t) for t in times]


def test_the_thermal_flight_is_evaluated_in_one_numpy_pass() -> None:
    """The seed board's scenario takes the vectorised path (not the per-time fallback)."""
    motion = load_registry().scenarios.get("thermal")(None, seed=0).motion
    assert isinstance(motion, FlightMotion) and motion.vectorised()


def test_kinematics_many_refuses_what_it_does_not_cover() -> None:
    """tumble's body rotations keep the per-time path (chip_truths falls back to it)."""
    motion = load_registry().scenarios.get("tumble")(None, seed=0).motion
    assert isinstance(motion, FlightMotion) and motion.body_rotations
    assert not motion.vectorised()
    with pytest.raises(ValueError, match="body rotations"):
        motion.kinematics_many(np.array([0.0, 1.0]))
