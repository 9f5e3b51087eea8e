"""Issue 25 item 7: at 1 % transient bus errors every device of every bundled board delivers
at least 95 % of what it delivers without faults (the chip's configured output: the fault-free
run is the reference, so a chip clock a little off does not blur the figure).

The cause on the MPU-9250 boards (gy91, seed-gps-vario: about 75 % on every device, the
barometer sharing the bus included): the MPU-9250, AK8963 and BMP280 drivers had no
``resume``, so each bus error cost the full recovery; the MPU-9250's H_RESET alone waits
110 ms on the clock all devices share (docs/reliability.md; figures from
``docs/scripts/delivery_under_bus_errors.py``).

Serial devices (the GNSS receiver) are not held to it: ``bus_errors`` on a UART corrupts or
drops each byte with probability ``rate``, and a UART has no retry, so a 100-byte UBX NAV-PVT
frame survives with probability 0.99^100 = 37 %; the checksum rejects the rest (flagged
CRC_ERROR), which is what the line allows, not a loss the driver could avoid.
"""

from __future__ import annotations

from collections import Counter

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.samples import Quantity, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

SECONDS = 4.0
SETTLE_S = 0.5
"""Start-up (configuration, first conversions) is not counted: errors there cost start-up
time, which the start-up tests bound."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _valid_counts(registry: Registry, board: str, rate: float,
                  on: set[str] | None = None, from_s: float = 0.0
                  ) -> Counter[tuple[str, Quantity]]:
    """Valid samples per device and channel after SETTLE_S, with bus errors at ``rate`` on
    every device (``on``: on these) from ``from_s``."""
    profile = load_profile(bundled_profiles()[board], registry)
    devices = [n for n, d in profile.devices.items() if d.enabled and (on is None or n in on)]
    faults = ([BusErrors(device=d, rate=rate, start_s=from_s) for d in devices] if rate
              else [])
    counts: Counter[tuple[str, Quantity]] = Counter()
    with open_emulated(profile, registry, seed=4, faults=faults, calibrated=False) as p:
        start_ns = p.clock.now_ns() + round(SETTLE_S * 1e9)
        serial = {n for n, d in p.devices.items() if d.driver.link.kind is BusKind.SERIAL}
        for e in p.events(SECONDS):
            if isinstance(e, Sample) and e.valid and e.t_ns >= start_ns \
                    and e.device not in serial:
                counts[(e.device, e.channel)] += 1
    return counts


@pytest.mark.parametrize("board", sorted(bundled_profiles()))
def test_every_device_delivers_95_percent_at_1_percent_bus_errors(
        registry: Registry, board: str) -> None:
    clean = _valid_counts(registry, board, 0.0)
    glitchy = _valid_counts(registry, board, 0.01)
    assert clean and all(n > 0 for n in clean.values())
    short = {f"{dev}.{ch.value}": f"{glitchy[(dev, ch)]} of {n}"
             for (dev, ch), n in clean.items() if glitchy[(dev, ch)] < 0.95 * n}
    assert not short, short


def _resuming(registry: Registry, board: str) -> set[str]:
    """The board's devices whose driver may resume again and again
    (``Driver.resumes_in_a_row``: every resume checks the chip kept its state), which also
    repeat a failed configuration transfer in place (the MPU-9250, AK8963, BMP280 and
    MAX2110x)."""
    profile = load_profile(bundled_profiles()[board], registry)
    return {n for n, d in profile.devices.items()
            if d.enabled and registry.drivers.entries[d.driver].obj.resumes_in_a_row > 1}


@pytest.mark.parametrize("board", sorted(bundled_profiles()))
def test_devices_that_resume_deliver_90_percent_at_10_percent_bus_errors(
        registry: Registry, board: str) -> None:
    """Issue 26: at 10 % bus errors gy91's MPU-9250 delivered 416 of 1,446 frames, the seed
    boards' MAX2110x about a third: a recovery (the MPU-9250's H_RESET and some 30 transfers)
    started over at any failed transfer and so rarely completed, and every second failure
    in a row cost one (110 ms of H_RESET on the clock every device shares). A failed
    configuration transfer is now repeated in place and the plan read back whole, and a
    resume that checks the chip's state may be repeated. (The errors start after
    start-up, which the next test holds; the GNSS UART is left clean: at 10 % of its bytes
    hit, a NAV-PVT rarely passes its checksum.)"""
    mine = _resuming(registry, board)
    clean = _valid_counts(registry, board, 0.0)
    glitchy = _valid_counts(registry, board, 0.1, on=mine, from_s=SETTLE_S)
    assert mine and {dev for dev, _ in clean} >= mine
    short = {f"{dev}.{ch.value}": f"{glitchy[(dev, ch)]} of {n}"
             for (dev, ch), n in clean.items() if dev in mine and glitchy[(dev, ch)] < 0.9 * n}
    assert not short, short


@pytest.mark.parametrize("board", sorted(bundled_profiles()))
def test_devices_that_resume_start_at_10_percent_bus_errors(registry: Registry,
                                                            board: str) -> None:
    """Start-up under the same errors: each of the six bring-up attempts was a whole
    probe-and-configure (some 30 transfers for the MPU-9250), so at 10 % gy91 did not
    start; with each transfer repeated in place every board starts and delivers."""
    mine = _resuming(registry, board)
    glitchy = _valid_counts(registry, board, 0.1, on=mine)
    assert {dev for dev, _ in glitchy} >= mine
