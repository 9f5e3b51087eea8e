"""GNSS after a receiver's device recovers (issue 26 item 2): the emulated receiver keeps
computing its fixes from the world at its own epochs while the host does not poll it, so
the first epochs after a recovery carry the true velocity (they used to carry the velocity
of before the outage, 12 m/s off, marked valid)."""

from __future__ import annotations

import math

from imuhal.core.samples import VelocitySample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors, BusOSError, ChipAbsent, ChipReset
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

VELOCITY_TOLERANCE_M_S = 2.0
"""The receiver's speed accuracy (0.15 m/s per axis) at 6 sigma, plus what an epoch
between two physics updates extrapolates over 0.2 s of a turning glider."""


def test_no_valid_gnss_velocity_after_a_recovery_is_far_from_the_truth() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    # Port errors alone no longer reconfigure the receiver (the driver resumes after one):
    # a restart and an unplugged spell do.
    faults = [BusErrors(device="gps", rate=0.01), BusOSError(device="gps", rate=0.01),
              ChipReset(device="gps", start_s=10.0),
              ChipAbsent(device="gps", start_s=18.0, end_s=20.0)]
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        errors = [(e.t_ns / 1e9, math.dist(e.velocity_ned_m_s,
                                           scenario.truth(e.t_ns / 1e9).velocity_ned_m_s))
                  for e in pipeline.events(30.0)
                  if isinstance(e, VelocitySample) and e.valid]
        recoveries = pipeline.devices["gps"].driver.health.reconfigurations
    assert recoveries >= 2  # the run did go through recoveries
    assert len(errors) > 20
    assert [(t, err) for t, err in errors if err > VELOCITY_TOLERANCE_M_S] == []
