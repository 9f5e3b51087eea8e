"""NMEA integrity beyond the checksum (issue 26): the seed GPS vario with its receiver left
in NMEA (RMC VTG GGA GSA at 1 Hz), pairs of flipped bits that NMEA's 8-bit XOR cannot see
put on its line through the fault-injection interface (``corrupt_byte``, two in one
sentence: the same bit in two characters cancels in the XOR).

The 4 s epoch's burst is the first thing the host receives after 4.05 s (the receiver's
80 ms output latency); seed 1 makes it (byte offsets from its first ``$``)::

    $GPRMC,110004.00,A,4636.0002,N,00800.0005,E,0.30,206.41,210626,,,A*51   (0)
    $GPVTG,206.41,T,,M,0.30,N,0.56,K,A*3C                                   (71)
    $GPGGA,110004.00,4636.0002,N,00800.0005,E,1,09,0.9,920.5,M,48.0,M,,*62  (110)

Should the burst change, a flip that no longer lands where a test says fails that test:
each checks how the hit epoch came out (the rule that refused it, or its value), not only
that it is missing.
"""

from __future__ import annotations

import math

import pytest

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.core.samples import PositionSample, VelocitySample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import CorruptByte
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile, read_profile_text
from imuhal_chips.gnss.driver import GnssStats
from imuhal_chips.gnss.integrity import Epoch, local_offset_m

START_S = 4.05
HIT_NS = 4_080_000_000
"""The 4 s epoch's time stamp (the profile states no output latency: arrival)."""
SECONDS = 7.0
UBX = ("      protocol: ubx\n      baud_rates: [9600, 115200]\n      rate_hz: 5\n"
       "      messages: [NAV-PVT]\n")


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _flight(registry: Registry, *flips: tuple[int, int], max_acceleration_m_s2: float = 100.0
            ) -> tuple[dict[int, PositionSample], dict[int, VelocitySample], GnssStats]:
    """The seed GPS vario in NMEA at 1 Hz with ``flips`` (byte, mask) from START_S: its
    valid fixes and velocities by time stamp, and the driver's stats."""
    text = read_profile_text(bundled_profiles()["seed-gps-vario.yaml"])
    assert UBX in text
    text = text.replace(UBX, "      protocol: nmea\n      baud_rates: [9600, 115200]\n"
                             "      rate_hz: 1\n      messages: [RMC, VTG, GGA, GSA]\n"
                             f"      max_acceleration_m_s2: {max_acceleration_m_s2}\n")
    profile = parse_profile(text, "seed-gps-vario in NMEA", registry)
    faults = [CorruptByte(device="gps", start_s=START_S, byte=k, mask=mask) for k, mask in flips]
    with open_emulated(profile, registry, seed=1, faults=faults, calibrated=False) as p:
        events = list(p.events(SECONDS))
        stats = p.devices["gps"].driver.stats  # type: ignore[attr-defined]  # the GNSS driver
    fixes = {e.t_ns: e for e in events if isinstance(e, PositionSample) and e.valid}
    velocities = {e.t_ns: e for e in events if isinstance(e, VelocitySample) and e.valid}
    return fixes, velocities, stats


@pytest.fixture(scope="module")
def clean(registry: Registry) -> tuple[dict[int, PositionSample], dict[int, VelocitySample]]:
    fixes, velocities, stats = _flight(registry)
    assert HIT_NS in fixes and HIT_NS in velocities and stats.inconsistent_frames == 0
    return fixes, velocities


def _moved_m(a: PositionSample, b: PositionSample) -> float:
    """How far ``b`` lies from ``a`` horizontally (m)."""
    def epoch(s: PositionSample) -> Epoch:
        return Epoch(t_ns=s.t_ns, latitude_deg=s.latitude_deg, longitude_deg=s.longitude_deg,
                     height_msl_m=s.height_m, velocity_ned_m_s=None, horizontal_accuracy_m=0.0,
                     vertical_accuracy_m=None, speed_accuracy_m_s=0.0)

    return math.hypot(*local_offset_m(epoch(a), epoch(b))[:2])


def test_a_gga_position_the_checksum_missed_is_flagged_against_rmcs(
        registry: Registry, clean: tuple[dict[int, PositionSample], dict[int, VelocitySample]]
        ) -> None:
    """Bit 1 of GGA's latitude digits of 0.01 and 0.001 minute ('0' to '2' each): the fix
    41 m north, inside the horizontal gate of 5 sigma of HDOP 0.9 x 5 m (and 10 g over a
    second), and the GGA position was the one the epoch used. RMC printed the same
    solution's latitude: the two disagree, the epoch is flagged CRC_ERROR and counted."""
    fixes, _, stats = _flight(registry, (110 + 17 + 6, 0x02), (110 + 17 + 7, 0x02))
    assert HIT_NS not in fixes
    assert (stats.inconsistent_frames, stats.checksum_errors) == (1, 0)
    assert stats.last_error.startswith("RMC and GGA disagree on latitude_deg")
    assert all(fix == clean[0][t] for t, fix in fixes.items())
    assert set(clean[0]) - set(fixes) == {HIT_NS}


def test_a_vtg_speed_the_checksum_missed_is_refused_and_rmcs_is_used(
        registry: Registry, clean: tuple[dict[int, PositionSample], dict[int, VelocitySample]]
        ) -> None:
    """Bit 3 of VTG's speed in knots ('0.30' to '8.30', 4.1 m/s more) and of its course's
    tens ('206.41' to '286.41'): under the velocity step limit of a second at 10 g, and
    VTG's speed was the one the epoch used. VTG says its speed twice (knots, km/h): it is
    refused (CRC_ERROR, counted), and the epoch keeps RMC's speed and course, the
    receiver's."""
    fixes, velocities, stats = _flight(registry, (71 + 19, 0x08), (71 + 8, 0x08))
    assert (stats.inconsistent_frames, stats.checksum_errors) == (1, 0)
    assert "VTG" in stats.last_error
    assert velocities[HIT_NS].velocity_ned_m_s == pytest.approx(
        clean[1][HIT_NS].velocity_ned_m_s, abs=0.003)  # RMC's course has 2 decimals
    assert fixes[HIT_NS] == clean[0][HIT_NS]


def test_an_nmea_height_under_the_acceleration_limit_is_contradicted_by_the_barometer(
        registry: Registry,
        clean: tuple[dict[int, PositionSample], dict[int, VelocitySample]]) -> None:
    """Bit 2 of GGA's altitude digits of tens and tenths ('920.5' to '960.1'): 39.6 m up.
    GGA prints the height once, and NMEA's vertical velocity is made from the heights, so
    the receiver's own data hold it only by the velocity step limit: (max_acceleration_m_s2
    x dt + 4.2 m/s) x dt, 104 m at the default 10 g and 1 Hz, and the driver passes it
    (docs/reliability.md). The board's barometer says the vehicle did not climb 40 m in a
    second: the fix, and the two vertical velocities made from it, are flagged
    CONTRADICTED (imuhal.pipeline.crosscheck), with the defaults."""
    fixes, velocities, stats = _flight(registry, (110 + 52, 0x04), (110 + 55, 0x04))
    assert (stats.inconsistent_frames, stats.checksum_errors, stats.decode_errors) == (0, 0, 0)
    assert stats.implausible_epochs.keys() <= {"first fix unconfirmed"}  # the driver passed it
    assert HIT_NS not in fixes
    assert set(clean[0]) - set(fixes) == {HIT_NS}
    assert set(clean[1]) - set(velocities) == {HIT_NS, HIT_NS + 1_000_000_000}
