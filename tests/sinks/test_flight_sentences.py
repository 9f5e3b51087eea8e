"""Each sentence encoder, read back by a hand-written parser and pynmea2 (for NMEA 0183).

Formats as their readers define them (docs/flight-instrument.md cites XCSoar's parsers).
"""

from __future__ import annotations

from datetime import datetime, timezone

import pytest
from tests.sinks.nmea_reader import read_lxwp0, read_sentence

from imuhal.sinks.flight import sentences as fmt

UTC = datetime(2026, 6, 21, 11, 30, 5, 250_000, tzinfo=timezone.utc)


def test_the_checksum_reproduces_the_published_gga_example() -> None:
    assert fmt.checksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") == "47"


def test_lk8ex1_pressure_pa_altitude_m_vario_cm_s_temperature_battery() -> None:
    head, f = read_sentence(fmt.lk8ex1(pressure_pa=95123.4, altitude_m=512.6, climb_m_s=-1.234,
                                       temperature_degc=21.6, battery_v=3.91))
    assert head == "LK8EX1"
    assert f == ["95123", "513", "-123", "22", "3.91", ""]


def test_lk8ex1_uses_the_documented_no_data_values() -> None:
    _, f = read_sentence(fmt.lk8ex1(pressure_pa=None, altitude_m=None, climb_m_s=None,
                                    temperature_degc=None))
    assert f[:5] == ["999999", "99999", "9999", "99", "999"]
    _, f = read_sentence(fmt.lk8ex1(pressure_pa=1e5, altitude_m=0, climb_m_s=0,
                                    temperature_degc=0, battery_percent=77))
    assert f[4] == "1077"


def test_pov_pressure_hpa_temperature_and_no_total_energy_without_an_airspeed() -> None:
    head, f = read_sentence(fmt.pov(pressure_pa=95123.4, temperature_degc=-3.2,
                                    te_vario_m_s=1.256))
    assert head == "POV"
    pairs = dict(zip(f[::2], f[1::2], strict=True))
    assert pairs == {"P": "951.23", "T": "-3.20"}  # E left out: XCSoar uses P for its vario


def test_pov_total_energy_goes_with_the_true_airspeed_in_km_h() -> None:
    _, f = read_sentence(fmt.pov(pressure_pa=95123.4, true_airspeed_m_s=10.0,
                                 te_vario_m_s=1.256))
    assert dict(zip(f[::2], f[1::2], strict=True)) == {"P": "951.23", "S": "36.0", "E": "1.26"}


def test_lxwp0_carries_pressure_altitude_and_one_vario_value_in_lx_order() -> None:
    got = read_lxwp0(fmt.lxwp0(pressure_altitude_m=1665.54, climb_m_s=1.714))
    assert got == {"logger": "N", "tas_km_h": None, "pressure_altitude_m": 1665.5,
                   "vario_m_s": 1.71, "vario2": None, "vario3": None, "vario4": None,
                   "vario5": None, "vario6": None, "heading_deg": None,
                   "wind_from_deg": None, "wind_km_h": None}


def test_lxwp0_speeds_are_km_h_and_directions_degrees() -> None:
    got = read_lxwp0(fmt.lxwp0(logger_recording=True, true_airspeed_m_s=61.75,
                               pressure_altitude_m=-20.0, climb_m_s=-0.5, heading_deg=-121,
                               wind_from_deg=174, wind_speed_m_s=2.8055))
    assert (got["logger"], got["tas_km_h"], got["pressure_altitude_m"], got["vario_m_s"]) == \
        ("Y", 222.3, -20.0, -0.5)
    assert (got["heading_deg"], got["wind_from_deg"], got["wind_km_h"]) == (239, 174, 10.1)


def test_prs_is_pressure_in_pa_as_hex() -> None:
    text = fmt.prs(97466.0)
    assert text == "_PRS 00017CBA\n"  # XCSoar's FlyNet parser comment: "_PRS 00017CBA"
    assert int(read_sentence(text)[1][0], 16) == 97466


def test_xctrc_fields_in_xcsoars_order_and_units() -> None:
    head, f = read_sentence(fmt.xctrc(utc=UTC, latitude_deg=46.947508, longitude_deg=7.453117,
                                      gps_altitude_m=540.32, ground_speed_m_s=12.35,
                                      course_deg=270.4, climb_m_s=2.78, pressure_pa=96493.0,
                                      battery_percent=98))
    assert head == "XCTRC"
    assert f[:7] == ["2026", "6", "21", "11", "30", "5", "25"]
    assert [float(x) for x in f[7:13]] == [46.947508, 7.453117, 540.32, 12.35, 270.4, 2.78]
    assert f[13:16] == ["", "", ""]
    assert (float(f[16]), f[17]) == (964.93, "98")


def test_gga_and_rmc_read_back_through_pynmea2() -> None:
    pynmea2 = pytest.importorskip("pynmea2", reason="the gps extra is not installed")
    gga = pynmea2.parse(fmt.gga(utc=UTC, latitude_deg=-33.856785, longitude_deg=151.215296,
                                quality=1, satellites=9, hdop=0.9, altitude_msl_m=58.3,
                                geoid_separation_m=None).strip(), check=True)
    assert gga.latitude == pytest.approx(-33.856785, abs=2e-6)
    assert gga.longitude == pytest.approx(151.215296, abs=2e-6)
    assert (gga.altitude, int(gga.num_sats), gga.geo_sep) == (58.3, 9, "")
    rmc = pynmea2.parse(fmt.rmc(utc=UTC, valid=True, latitude_deg=46.5, longitude_deg=-8.25,
                                ground_speed_m_s=10.0, course_deg=-90.0).strip(), check=True)
    assert rmc.spd_over_grnd == pytest.approx(10.0 * 3600 / 1852, abs=0.006)
    assert rmc.true_course == 270.0 and rmc.status == "A"
    assert rmc.datestamp.isoformat() == "2026-06-21"


def test_a_position_that_rounds_to_sixty_minutes_carries_into_the_degree() -> None:
    _, f = read_sentence(fmt.gga(utc=UTC, latitude_deg=46.9999999, longitude_deg=7.99999999,
                                 quality=1, satellites=5, hdop=None, altitude_msl_m=0,
                                 geoid_separation_m=None))
    assert (f[1], f[3]) == ("4700.0000", "00800.0000")
