"""Issue 26: nothing wrong is marked valid after an HMC5883L reset. A reset chip returns to
its power-on configuration (single measurement mode, gain 1090 LSB/Ga), measures once, goes
idle and keeps RDY set with those bytes; the driver must not hand them out as new fields.
Resets come through the fault-injection interface on seed-rc-vario, whose HMC5883L the
driver reads itself (``read: one-shot``), and on seed-paraglider-vario, whose MAX21100
auto-reads it (``read: auto``: the master copies only the six data bytes, not Mode)."""

from __future__ import annotations

import math
from bisect import bisect_right
from itertools import pairwise
from typing import Any

import pytest
import yaml

from imuhal.core.samples import MagSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors, ChipReset
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile

BOARD = "seed-rc-vario.yaml"
AUTO_READ_BOARD = "seed-paraglider-vario.yaml"
RESETS_S = (1.37, 2.11, 3.53)
"""Between the driver's configuration read-backs (every 0.5 s from the start). On the
auto-read board the third one's zeros and power-on measurement reach the driver in one
poll's copies."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _run(registry: Registry, board: str = BOARD, *, blind_s: float = 0.0,
         **settings: Any) -> tuple[list[MagSample], Pipeline]:
    """The magnetometer's raw samples over 4 s of a static ``board`` reset at RESETS_S, with
    its driver settings changed as given; ``blind_s``: every transfer to it fails for that
    long from each reset (the master's copies, and the driver's own reads)."""
    doc = yaml.safe_load(bundled_profiles()[board].read_text())
    doc["devices"]["mag"]["settings"].update(settings)
    profile = parse_profile(yaml.safe_dump(doc, sort_keys=False), board, registry)
    faults: list[Any] = [ChipReset(device="mag", start_s=t) for t in RESETS_S]
    if blind_s:
        faults += [BusErrors(device="mag", rate=1.0, start_s=t, end_s=t + blind_s)
                   for t in RESETS_S]
    with open_emulated(profile, registry, scenario="static", seed=11, faults=faults,
                       calibrated=False) as p:
        mags = [e for e in p.events(4.0) if isinstance(e, MagSample)]
    return mags, p


@pytest.mark.parametrize("board", [BOARD, AUTO_READ_BOARD])
def test_every_valid_field_after_a_reset_carries_a_measurement_of_its_own(
        registry: Registry, board: str) -> None:
    """The latest measurement the chip completed before each valid sample is a new one:
    no two valid samples carry the same measurement (a reset chip's idle data repeated)."""
    mags, p = _run(registry, board)
    measured = p.board.emulators["mag"].measured_ns
    carried = [bisect_right(measured, s.t_ns) for s in mags if s.valid]
    repeats = [n for n, (a, b) in enumerate(pairwise(carried)) if a == b]
    assert not repeats, f"{len(repeats)} valid fields repeat a measurement"


def test_the_first_poll_after_a_reset_is_stale_counted_and_the_chip_reconfigured(
        registry: Registry) -> None:
    mags, p = _run(registry)
    assert p.devices["mag"].driver.health.resets_detected == len(RESETS_S)
    for t_s in RESETS_S:
        after = [s for s in mags if s.t_ns >= t_s * 1e9]
        first = after[0]
        assert first.flags & SampleFlag.STALE and all(math.isnan(v) for v in first.mag_ut)
        # reconfigured at once: valid again within a few output periods (75 Hz)
        back = next(s for s in after if s.valid)
        assert back.t_ns - first.t_ns < 0.06e9


@pytest.mark.parametrize(("board", "blind_s"),
                         [(BOARD, 0.0), (AUTO_READ_BOARD, 0.0), (AUTO_READ_BOARD, 0.01)])
def test_a_reset_chips_measurement_at_its_power_on_gain_is_never_valid(
        registry: Registry, board: str, blind_s: float) -> None:
    """At +/-8.1 Ga (230 LSB/Ga) the reset chip's single measurement at 1090 LSB/Ga would
    read 4.7 times the field: every valid field keeps the static board's magnitude. Also
    when the master's reads fail for the 6 ms the reset chip measures in, so its copies
    never show the zeros before that measurement (``blind_s``; one 153 uT field came out
    valid after each reset before the driver checked a copy whose magnitude jumped)."""
    mags, p = _run(registry, board, blind_s=blind_s, range_gauss=8.1)
    assert p.devices["mag"].driver.health.resets_detected == len(RESETS_S)
    norms = sorted(math.dist(s.mag_ut, (0.0, 0.0, 0.0)) for s in mags if s.valid)
    median = norms[len(norms) // 2]
    # 230 LSB/Ga: 0.43 uT per count, about 1 % of the field per axis
    assert all(abs(n - median) < 0.05 * median for n in norms), (norms[0], norms[-1])


def test_an_auto_read_reset_is_counted_and_its_power_on_measurement_is_stale(
        registry: Registry) -> None:
    """Behind the MAX21100 every reset is detected (the zeros, then the configuration read
    back), the power-on measurement after the third one's zeros comes out STALE without a
    value, and the chip is valid again within a few output periods (75 Hz)."""
    mags, p = _run(registry, AUTO_READ_BOARD, range_gauss=8.1)
    assert p.devices["mag"].driver.health.resets_detected == len(RESETS_S)
    for t_s in RESETS_S:
        after = [s for s in mags if s.t_ns >= t_s * 1e9]
        first = next(s for s in after if not s.valid)
        assert first.flags & (SampleFlag.STALE | SampleFlag.BLANK)
        assert all(math.isnan(v) for v in first.mag_ut)
        back = next(s for s in after if s.valid and s.t_ns > first.t_ns)
        assert back.t_ns - first.t_ns < 0.06e9
