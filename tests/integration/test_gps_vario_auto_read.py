"""The seed GPS vario board reads its AK8963 through the MPU-9250's slave 0 (``read: auto``,
as its firmware does): end to end on the emulated board, with faults on the magnetometer
injected through the fault-injection interface (imuhal.emulation.faults). The MPU keeps
EXT_SENS_DATA when slave 0's read fails, so the same bytes come again; ST1.DRDY and the
driver's comparison keep every such copy from being valid."""

from __future__ import annotations

from bisect import bisect_right

import numpy as np
import pytest
import yaml

from imuhal.core.samples import MagSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import AllOnes, BusErrors, ChipAbsent, ChipReset, StuckDataReady
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile
from imuhal_chips.ak8963.driver import AK8963Driver
from imuhal_chips.ak8963.emulator import AK8963Emulator

PROFILE = bundled_profiles()["seed-gps-vario.yaml"]
SEED = 5
MAG_BOUND_UT = 35.0
"""This board's emulated magnetometer errors, uncalibrated (hard iron and offsets), put every
reading 31.5 to 32.5 uT from the true field, with either read mode (measured at seed 5); a
reading of zero on the 41 uT field, or a word with its bytes swapped, is beyond it."""
LATENCY_S = 0.016
"""After a fault starts, the last good measurement may still be handed out: one AK8963
period (10 ms) plus the MPU's copy and burst (5.6 ms)."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def test_the_magnetometer_costs_no_transaction_of_its_own_per_sample(
        registry: Registry) -> None:
    profile = load_profile(PROFILE, registry)
    assert profile.devices["mag"].settings["read"] == "auto"
    with open_emulated(profile, registry, seed=SEED) as p:
        list(p.events(0.5))
        aux = p.devices["mag"].driver.link.bus
        before = aux.transfers
        events = list(p.events(2.0))
        truth = p.board.truth_at
    valid = [e for e in events if isinstance(e, MagSample) and e.valid]
    assert len(valid) >= 0.95 * 100 * 2.0
    for m in valid:
        want = truth(m.t_ns).magnetic_field_body_ut
        assert float(np.linalg.norm(np.asarray(m.vector) - want)) <= MAG_BOUND_UT, m
    # only the CNTL1 read-back (reset_check_s) through slave 4
    assert aux.transfers - before <= 8


def test_faults_behind_the_master_never_make_a_kept_copy_valid(registry: Registry) -> None:
    profile = load_profile(PROFILE, registry)
    faults = [BusErrors(device="mag", start_s=1.0, end_s=1.5, rate=0.5),
              ChipAbsent(device="mag", start_s=2.0, end_s=2.5),
              StuckDataReady(device="mag", start_s=3.0, end_s=3.5),
              AllOnes(device="mag", start_s=4.0, end_s=4.3)]
    with open_emulated(profile, registry, scenario="thermal", seed=SEED, faults=faults) as p:
        events = list(p.events(6.0))
        truth = p.board.truth_at
        summary = p.summary()
        instants = list(p.board.emulators["mag"].measured_ns)
    mags = [e for e in events if isinstance(e, MagSample)]
    valid = [m for m in mags if m.valid]
    # no valid sample is a copy handed out again: each carries a measurement of its own
    # (the latest the AK8963 completed before the MPU's burst; two equal measurements in a
    # row are two samples)
    taken = [bisect_right(instants, m.t_ns) - 1 for m in valid]
    assert len(set(taken)) == len(taken)
    # nothing valid while the chip is unplugged, stops measuring or its line reads 0xFF
    for start_s, end_s in ((2.0, 2.5), (3.0, 3.5), (4.0, 4.3)):
        assert not [m for m in valid if start_s + LATENCY_S < m.t_ns / 1e9 < end_s]
    assert summary.flagged["mag"].get("STALE", 0) > 0
    assert summary.device_errors["mag"] > 0
    assert all(m.flags & (SampleFlag.STALE | SampleFlag.BLANK | SampleFlag.FROZEN)
               for m in mags if not m.valid)
    for m in valid:
        want = truth(m.t_ns).magnetic_field_body_ut
        assert float(np.linalg.norm(np.asarray(m.vector) - want)) <= MAG_BOUND_UT, m
    assert len([m for m in valid if m.t_ns > 5.0e9]) >= 0.9 * 100


def test_the_gy91_on_i2c_auto_reads_through_its_master_too(registry: Registry) -> None:
    doc = yaml.safe_load(bundled_profiles()["gy91.yaml"].read_text())
    doc["devices"]["imu"]["settings"]["aux"] = "master"
    doc["devices"]["mag"]["settings"]["read"] = "auto"
    profile = parse_profile(yaml.safe_dump(doc, sort_keys=False), "gy91.yaml", registry)
    with open_emulated(profile, registry, seed=SEED) as p:
        list(p.events(0.5))
        events = list(p.events(1.0))
    valid = [e for e in events if isinstance(e, MagSample) and e.valid]
    assert len(valid) >= 0.95 * 100 and len(valid) == len(
        [e for e in events if isinstance(e, MagSample)])


def test_a_garbled_fuse_rom_read_is_never_taken(registry: Registry) -> None:
    """The AK8963's sensitivity adjustment (ASA, fuse ROM) is read through the MPU's slave
    4 at every configuration; at 50 % bus errors on the magnetometer, with the chip reset
    while they last so that it is configured again, a failed slave-4 read hands back 0xFF
    (or 0x00, when the write into fuse-ROM mode failed). The driver never takes such a
    read: its ASA is the part's whenever the device runs (a taken 0xFF scales every field
    1.5 x: 35.9 uT off where the error model gives 32)."""
    profile = load_profile(PROFILE, registry)
    faults = [BusErrors(device="mag", start_s=1.0, end_s=2.0, rate=0.5),
              *(ChipReset(device="mag", start_s=1.1 + 0.2 * i) for i in range(4))]
    with open_emulated(profile, registry, scenario="thermal", seed=SEED, faults=faults) as p:
        dev, chip = p.devices["mag"], p.board.emulators["mag"]
        assert isinstance(chip, AK8963Emulator) and isinstance(dev.driver, AK8963Driver)
        taken = set()
        for _ in p.events(3.0):
            if dev.present and not dev.needs_recovery:
                taken.add(dev.driver.asa)
        summary = p.summary()
    assert taken == {chip.asa}
    assert summary.driver["mag"]["reconfigurations"] >= 1
