"""The seed board reads its HMC5883L through the MAX21100's slave auto-read (``read: auto``,
as the seed's hardware does): end to end on the emulated board, with faults on the
magnetometer's line behind the master injected through the fault-injection interface
(imuhal.emulation.faults): the master keeps its last copy when its read of the slave fails,
and none of those repeated bytes may come out as a valid sample."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from imuhal.core.samples import MagSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import AllOnes, BusErrors, ChipAbsent, StuckDataReady
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile

SEED = 5
MAG_BOUND_UT = 25.0
"""As in test_seed_board_faults.py: 11.5 uT of hard iron and 2 uT offsets uncalibrated; a
reading of zero on the 41 uT field fails."""
LATENCY_S = 0.013
"""After a fault starts, the last good measurement may still be handed out: one output
period (13.3 ms at 75 Hz) covers the master's copy and the next poll."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def test_the_magnetometer_costs_no_transaction_of_its_own_per_sample(
        registry: Registry) -> None:
    profile = load_profile(default_profile_path(), registry)
    assert profile.devices["mag"].settings["read"] == "auto"
    with open_emulated(profile, registry, seed=SEED) as p:
        list(p.events(0.5))
        aux = p.devices["mag"].driver.link.bus
        before = aux.transfers
        events = list(p.events(2.0))
    valid = [e for e in events if isinstance(e, MagSample) and e.valid]
    assert len(valid) >= 0.95 * 75 * 2.0
    # only the configuration read-back every 0.5 s (one transaction of three bytes)
    assert aux.transfers - before <= 4


def test_faults_behind_the_master_never_make_a_repeated_copy_valid(registry: Registry) -> None:
    profile = load_profile(default_profile_path(), registry)
    faults = [BusErrors(device="mag", start_s=1.0, end_s=1.5, rate=0.5),
              ChipAbsent(device="mag", start_s=2.0, end_s=2.5),
              StuckDataReady(device="mag", start_s=3.0, end_s=3.5),
              AllOnes(device="mag", start_s=4.0, end_s=4.3)]
    with open_emulated(profile, registry, scenario="thermal", seed=SEED, faults=faults) as p:
        events = list(p.events(6.0))
        emulator = p.board.emulators["imu"]
        truth = p.board.truth_at
        summary = p.summary()
    mags = [e for e in events if isinstance(e, MagSample)]
    valid = [m for m in mags if m.valid]
    # the master's failed reads left its copy as it was: the driver saw the same bytes again
    assert emulator.slave_read_failures > 0
    # no valid sample is a copy handed out again
    assert all(a.vector != b.vector for a, b in itertools.pairwise(valid))
    # nothing valid while the chip is unplugged or its line reads 0xFF: the same bytes
    # (flagged STALE once overdue), or 0xFF bytes, which the configuration check finds and
    # hands to the pipeline's recovery (device errors)
    for start_s, end_s in ((2.0, 2.5), (4.0, 4.3)):
        assert not [m for m in valid if start_s + LATENCY_S < m.t_ns / 1e9 < end_s]
    assert summary.flagged["mag"].get("STALE", 0) > 0
    assert summary.device_errors["mag"] > 0
    assert all(m.flags & (SampleFlag.STALE | SampleFlag.BLANK | SampleFlag.FROZEN)
               for m in mags if not m.valid)
    # every valid sample reads the field, and the magnetometer is back at the end
    for m in valid:
        want = truth(m.t_ns).magnetic_field_body_ut
        assert float(np.linalg.norm(np.asarray(m.vector) - want)) <= MAG_BOUND_UT, m
    assert len([m for m in valid if m.t_ns > 5.0e9]) >= 0.9 * 75
