"""GNSS after a receiver's device recovers (issue 26 item 2): the emulated receiver keeps
computing its fixes from the world at its own epochs while the host does not poll it, so
the first epochs after a recovery carry the true velocity (they used to carry the velocity
of before the outage, 12 m/s off, marked valid)."""

from __future__ import annotations

import itertools
import math

from imuhal.core.samples import VelocitySample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors, BusOSError, ChipAbsent, ChipReset, HostStall
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


def test_gnss_epochs_read_late_keep_their_time_stamps_and_match_the_truth() -> None:
    """Another device holds the thread 1 s (a host stall before an IMU poll): the receiver's
    poll comes late and reads five epochs at once. The driver dates what it read by the
    time of the read, not the poll's due time, and each epoch by the bytes that came after
    it, so the UTC-to-clock mapping (the smallest delay seen) is not pulled early. Dated by
    the due time, the epochs read together shared one stamp and every later one was
    stamped the stall early: valid velocities 6.1 m/s off the truth at their stamps."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    faults = [HostStall(device="imu", start_s=5.0, end_s=5.1, stall_s=1.0, every_s=1.0)]
    with open_emulated(profile, registry, seed=1, faults=faults, scenario="thermal",
                       calibrated=False) as pipeline:
        scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        velocities = [e for e in pipeline.events(40.0)
                      if isinstance(e, VelocitySample) and e.valid]
        stalls = pipeline.board.faults.log.injected["imu"]["host_stall"]  # type: ignore[attr-defined]
    assert stalls == 1
    stamps_ns = [v.t_ns for v in velocities]
    period_ns = 1e9 / 5  # the profile's rate_hz
    assert min(b - a for a, b in itertools.pairwise(stamps_ns)) > period_ns / 2
    errors = [math.dist(v.velocity_ned_m_s, scenario.truth(v.t_ns / 1e9).velocity_ned_m_s)
              for v in velocities]
    assert len(errors) > 150 and max(errors) < VELOCITY_TOLERANCE_M_S
