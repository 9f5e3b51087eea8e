"""A GNSS receiver that restarts with stale navigation data (issue 26 item 2), through the
fault-injection interface (``stale_navigation``): from the fault's start the receiver sends
its last solution again each epoch, claiming a fix, either with that solution's own time
(iTOW and UTC repeated; NMEA's UTC repeated) or with its running clock's time marked not
valid (NAV-PVT's validDate, validTime and fullyResolved cleared). Every such epoch is
flagged STALE, velocity and position, counted per reason in the driver's
``stats.stale_epochs``, and never valid; the receiver's fresh epochs after it are valid
again, and a clean flight flags none.
"""

from __future__ import annotations

import pytest

pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.core.samples import PositionSample, SampleFlag, VelocitySample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import StaleNavigation
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile, read_profile_text
from imuhal_chips.gnss.driver import STALE_TIME_INVALID, STALE_TIME_REPEATED, GnssStats

START_S, END_S = 4.0, 6.0
SECONDS = 8.0
UBX = ("      protocol: ubx\n      baud_rates: [9600, 115200]\n      rate_hz: 5\n"
       "      messages: [NAV-PVT]\n")
NMEA = ("      protocol: nmea\n      baud_rates: [9600, 115200]\n      rate_hz: 1\n"
        "      messages: [RMC, VTG, GGA, GSA]\n")

GnssEvent = PositionSample | VelocitySample


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _flight(registry: Registry, time: str | None, *, nmea: bool = False,
            seconds: float = SECONDS) -> tuple[list[GnssEvent], GnssStats]:
    """The seed GPS vario in its thermal (launch at 5 s, 10 m/s from 8 s), its receiver
    stale from START_S to END_S (``time`` None: a clean line); every GNSS sample and the
    driver's stats."""
    text = read_profile_text(bundled_profiles()["seed-gps-vario.yaml"])
    assert UBX in text
    profile = parse_profile(text.replace(UBX, NMEA) if nmea else text, "seed-gps-vario",
                            registry)
    faults = [] if time is None else [StaleNavigation(device="gps", start_s=START_S,
                                                      end_s=END_S, time=time)]
    with open_emulated(profile, registry, seed=1, faults=faults, calibrated=False) as p:
        events = [e for e in p.events(seconds) if isinstance(e, GnssEvent)]
        stats = p.devices["gps"].driver.stats  # type: ignore[attr-defined]  # the GNSS driver
    return events, stats


def _fixes(events: list[GnssEvent]) -> list[PositionSample]:
    return [e for e in events if isinstance(e, PositionSample)
            and not (e.flags & SampleFlag.STALE and e.fix_type == 0)]


@pytest.mark.parametrize(("time", "reason"), [("repeated", STALE_TIME_REPEATED),
                                              ("unresolved", STALE_TIME_INVALID)])
def test_a_receiver_sending_its_last_solution_again_is_flagged_stale_and_counted(
        registry: Registry, time: str, reason: str) -> None:
    """Ten NAV-PVT epochs (2 s at 5 Hz) repeat the solution of 3.8 s, each claiming a 3D
    fix: with 3.8 s's iTOW and UTC, or with the running time marked not valid. Each is
    flagged STALE (velocity and position), counted under its reason, and none is valid; the
    fresh epochs after the fault are valid again."""
    events, stats = _flight(registry, time)
    stale = [e for e in events if e.flags == SampleFlag.STALE]
    stale_fixes = [e for e in stale if isinstance(e, PositionSample) and e.fix_type != 0]
    assert len(stale_fixes) == 10 and stats.stale_epochs == {reason: 10}
    assert sum(isinstance(e, VelocitySample) for e in stale) == 10
    assert len({(f.latitude_deg, f.longitude_deg, f.height_m) for f in stale_fixes}) == 1
    last_before = max((e for e in events if isinstance(e, PositionSample) and e.valid
                       and e.t_ns < START_S * 1e9), key=lambda e: e.t_ns)
    assert (stale_fixes[0].latitude_deg, stale_fixes[0].height_m) == \
        (last_before.latitude_deg, last_before.height_m)
    assert not any(e.valid for e in events if START_S * 1e9 + 1e8 < e.t_ns < END_S * 1e9)
    assert sum(e.valid for e in _fixes(events) if e.t_ns > END_S * 1e9 + 1e8) >= 8


def test_an_nmea_receiver_whose_time_does_not_advance_is_flagged_stale(
        registry: Registry) -> None:
    """The receiver left in NMEA at 1 Hz repeats the 3 s epoch's RMC, VTG, GGA and GSA, time
    included, at 4 and 5 s: both epochs are flagged STALE ('time not advancing'), velocity
    and position; the 6 s epoch and those after it are fresh."""
    events, stats = _flight(registry, "repeated", nmea=True, seconds=9.0)
    assert stats.stale_epochs == {STALE_TIME_REPEATED: 2}
    stale = [e for e in events if e.flags & SampleFlag.STALE and isinstance(e, PositionSample)
             and e.fix_type != 0]
    assert len(stale) == 2 and not any(e.valid for e in stale)
    assert any(e.valid for e in events if isinstance(e, PositionSample)
               and e.t_ns > 7.5e9)


@pytest.mark.parametrize("nmea", [False, True], ids=["ubx", "nmea"])
def test_a_clean_receiver_is_never_flagged_stale_by_its_time(registry: Registry,
                                                               nmea: bool) -> None:
    events, stats = _flight(registry, None, nmea=nmea, seconds=20.0)
    assert stats.stale_epochs == {}
    assert sum(e.valid for e in _fixes(events)) >= (17 if nmea else 90)
