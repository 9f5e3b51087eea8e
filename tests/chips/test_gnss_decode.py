"""GNSS decoding against published sentences and a hand-built UBX frame.

The NMEA examples are the classic ones every NMEA reference quotes (with their published
checksums); the NAV-PVT frame is packed here with struct from the u-blox M8 protocol
description's field table, not with pyubx2, so the decoder is checked against the document.
"""

from __future__ import annotations

import struct

import pytest

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.core.samples import FixType
from imuhal_chips.gnss.decode import DecodeError, decode_nmea, decode_ubx, sentences_disagree
from imuhal_chips.gnss.framing import StreamSplitter

GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
RMC = b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n"
VTG = b"$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n"
GSA = b"$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n"


def test_classic_gga_reads_position_height_and_satellites() -> None:
    f = decode_nmea(GGA)
    assert f.checksum_ok and f.kind == "GGA"
    assert f.latitude_deg == pytest.approx(48 + 7.038 / 60, abs=1e-9)
    assert f.longitude_deg == pytest.approx(11 + 31.0 / 60, abs=1e-9)
    assert (f.height_msl_m, f.satellites, f.hdop) == (545.4, 8, 0.9)
    assert f.height_ellipsoid_m == pytest.approx(545.4 + 46.9)
    assert f.time_of_day_s == 12 * 3600 + 35 * 60 + 19
    assert f.fix_type is FixType.FIX_3D


def test_classic_rmc_reads_speed_in_knots_course_and_date() -> None:
    f = decode_nmea(RMC)
    assert f.ground_speed_m_s == pytest.approx(22.4 * 1852 / 3600)
    assert f.course_deg == 84.4
    assert (f.day.year, f.day.month, f.day.day) == (1994, 3, 23)


def test_classic_vtg_and_gsa() -> None:
    v = decode_nmea(VTG)
    assert v.ground_speed_m_s == pytest.approx(5.5 * 1852 / 3600) and v.course_deg == 54.7
    g = decode_nmea(GSA)
    assert g.fix_type is FixType.FIX_3D and g.hdop == 1.3


def nmea(body: str) -> bytes:
    """A sentence with its correct checksum (the XOR of the characters between $ and *)."""
    checksum = 0
    for c in body.encode("ascii"):
        checksum ^= c
    return f"${body}*{checksum:02X}\r\n".encode("ascii")


def test_a_vtg_whose_two_speeds_disagree_is_refused_like_a_wrong_checksum() -> None:
    """5.5 knots is 10.19 km/h; '8.5' knots (bit 3 of the '0' flipped, which the XOR
    misses with a matching flip elsewhere) is not 10.2 km/h."""
    f = decode_nmea(nmea("GPVTG,054.7,T,034.4,M,008.5,N,010.2,K"))
    assert not f.checksum_ok and "VTG says" in f.inconsistent
    assert decode_nmea(VTG).checksum_ok


def test_gga_and_rmc_of_one_epoch_must_print_the_same_position_to_their_rounding() -> None:
    gga = decode_nmea(GGA)
    assert sentences_disagree([decode_nmea(RMC), gga]) == ""
    moved = decode_nmea(nmea("GPRMC,123519,A,4807.040,N,01131.000,E,022.4,084.4,230394,003.1,W"))
    assert sentences_disagree([moved, gga]).startswith("RMC and GGA disagree on latitude_deg")
    # 4807.0384 printed to 3 decimals is 4807.038: the same solution, rounded
    finer = decode_nmea(nmea("GPRMC,123519,A,4807.0384,N,01131.0004,E,022.4,084.4,230394,,W"))
    assert sentences_disagree([finer, gga]) == ""


def test_rmc_and_vtg_of_one_epoch_must_print_the_same_speed_and_course() -> None:
    rmc = decode_nmea(nmea("GPRMC,123519,A,4807.038,N,01131.000,E,005.5,054.7,230394,,W"))
    assert sentences_disagree([rmc, decode_nmea(VTG)]) == ""
    turned = decode_nmea(nmea("GPRMC,123519,A,4807.038,N,01131.000,E,005.5,058.7,230394,,W"))
    assert "course_deg" in sentences_disagree([turned, decode_nmea(VTG)])
    north = [decode_nmea(nmea(f"GPVTG,{c},T,,M,005.5,N,010.2,K")) for c in ("359.99", "000.00")]
    assert sentences_disagree(north) == ""  # across north, the short way


def test_a_wrong_checksum_is_reported_not_hidden() -> None:
    f = decode_nmea(GGA.replace(b"*47", b"*48"))
    assert not f.checksum_ok
    assert f.latitude_deg == pytest.approx(48.1173)  # still readable, but marked


@pytest.mark.parametrize("garbled", [b"$GPGGA,12\xff\xfe*00\r\n", b"$\r\n", b"$GPXYZ*1\r\n"])
def test_garbled_sentences_raise_a_decode_error(garbled: bytes) -> None:
    with pytest.raises(DecodeError):
        decode_nmea(garbled)


def nav_pvt_frame(*, lat_deg: float, lon_deg: float, h_msl_m: float, vel_ned_m_s: tuple,
                  fix: int, num_sv: int, h_acc_m: float, v_acc_m: float, s_acc_m_s: float,
                  valid: int = 0x07) -> bytes:
    """UBX-NAV-PVT packed from the protocol description (payload 92 bytes, little endian);
    ``valid``: the validity flags (bit 0 validDate, 1 validTime, 2 fullyResolved)."""
    payload = bytearray(92)
    struct.pack_into("<IHBBBBBB", payload, 0, 123_000, 2026, 6, 21, 11, 30, 5, valid)
    struct.pack_into("<I i B B B B", payload, 12, 20, 0, fix, 0x01 if fix >= 2 else 0, 0,
                     num_sv)
    struct.pack_into("<iiii", payload, 24, round(lon_deg * 1e7), round(lat_deg * 1e7),
                     round((h_msl_m + 48.0) * 1000), round(h_msl_m * 1000))
    struct.pack_into("<II", payload, 40, round(h_acc_m * 1000), round(v_acc_m * 1000))
    vn, ve, vd = (round(v * 1000) for v in vel_ned_m_s)
    struct.pack_into("<iiii i I I H", payload, 48, vn, ve, vd, round((vn**2 + ve**2) ** 0.5),
                     0, round(s_acc_m_s * 1000), 0, 150)
    return ubx_frame(0x01, 0x07, bytes(payload))


def ubx_frame(msg_class: int, msg_id: int, payload: bytes) -> bytes:
    """Sync, class, id, little-endian length, payload, 8-bit Fletcher checksum."""
    body = bytes((msg_class, msg_id)) + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes((a, b))


def test_nav_pvt_from_the_protocol_table_decodes_to_si() -> None:
    frame = nav_pvt_frame(lat_deg=46.5123456, lon_deg=-7.9876543, h_msl_m=1234.567,
                          vel_ned_m_s=(1.25, -0.5, 0.75), fix=3, num_sv=11, h_acc_m=2.1,
                          v_acc_m=3.4, s_acc_m_s=0.12)
    f = decode_ubx(frame)
    assert f.checksum_ok and f.kind == "NAV-PVT"
    assert f.latitude_deg == pytest.approx(46.5123456, abs=1e-7)
    assert f.longitude_deg == pytest.approx(-7.9876543, abs=1e-7)
    assert f.height_msl_m == pytest.approx(1234.567)
    assert f.velocity_ned_m_s == pytest.approx((1.25, -0.5, 0.75))
    assert (f.fix_type, f.satellites) == (FixType.FIX_3D, 11)
    assert (f.horizontal_accuracy_m, f.vertical_accuracy_m, f.speed_accuracy_m_s) == \
        pytest.approx((2.1, 3.4, 0.12))
    assert f.time_of_day_s == pytest.approx(11 * 3600 + 30 * 60 + 5)
    assert f.time_valid is True


@pytest.mark.parametrize("valid", [0x00, 0x01, 0x02, 0x03, 0x06, 0x05])
def test_nav_pvt_whose_utc_is_not_valid_and_fully_resolved_says_so(valid: int) -> None:
    """validDate, validTime and fullyResolved: the time is the receiver's to vouch for, and
    any one of them cleared leaves the epoch's UTC unconfirmed."""
    frame = nav_pvt_frame(lat_deg=46.5, lon_deg=8.0, h_msl_m=900.0, vel_ned_m_s=(0, 0, 0),
                          fix=3, num_sv=9, h_acc_m=2.5, v_acc_m=4.0, s_acc_m_s=0.15,
                          valid=valid)
    assert decode_ubx(frame).time_valid is False


def test_nav_pvt_without_gnss_fix_ok_is_no_fix() -> None:
    frame = nav_pvt_frame(lat_deg=0, lon_deg=0, h_msl_m=0, vel_ned_m_s=(0, 0, 0), fix=0,
                          num_sv=0, h_acc_m=9999, v_acc_m=9999, s_acc_m_s=99)
    assert decode_ubx(frame).fix_type is FixType.NO_FIX


def test_a_ubx_frame_with_a_bad_checksum_is_reported() -> None:
    frame = bytearray(nav_pvt_frame(lat_deg=1, lon_deg=2, h_msl_m=3, vel_ned_m_s=(0, 0, 0),
                                    fix=3, num_sv=5, h_acc_m=1, v_acc_m=1, s_acc_m_s=1))
    frame[30] ^= 0x10
    assert not decode_ubx(bytes(frame)).checksum_ok


def _pvt() -> bytes:
    return nav_pvt_frame(lat_deg=1, lon_deg=2, h_msl_m=3, vel_ned_m_s=(0, 0, 0), fix=3,
                         num_sv=5, h_acc_m=1, v_acc_m=1, s_acc_m_s=1)


def test_the_splitter_waits_for_a_frame_split_across_reads() -> None:
    frame = nav_pvt_frame(lat_deg=1, lon_deg=2, h_msl_m=3, vel_ned_m_s=(0, 0, 0), fix=3,
                          num_sv=5, h_acc_m=1, v_acc_m=1, s_acc_m_s=1)
    s = StreamSplitter()
    assert s.feed(GGA[:20] + frame[:0]) == []
    assert s.feed(GGA[20:] + frame[:50]) == [("nmea", GGA)]
    assert s.feed(frame[50:]) == [("ubx", frame)]
    assert s.garbage_bytes == 0


def test_a_frame_cut_in_half_costs_one_checksum_error_and_the_frames_it_covered_decode(
        ) -> None:
    frame = _pvt()
    s = StreamSplitter()
    items = s.feed(frame[:50] + frame + frame + GGA)
    decoded = [decode_ubx(i) if k == "ubx" else decode_nmea(i) for k, i in items]
    # the cut frame claimed the start of the next one; that one is found all the same
    assert [d.checksum_ok for d in decoded] == [False, True, True, True]
    assert decoded[-1].kind == "GGA"


def test_a_nav_pvt_announcing_another_length_is_dropped_at_its_header() -> None:
    """NAV-PVT is 92 bytes long: a length byte corrupted to announce 860 is not waited for
    (it would swallow the next frames); the search resumes after the sync characters."""
    bad = bytearray(_pvt())
    bad[5] ^= 0x03
    s = StreamSplitter()
    assert s.feed(bytes(bad) + _pvt() + GGA) == [("ubx", _pvt()), ("nmea", GGA)]
    assert s.resyncs == 1 and s.garbage_bytes == len(bad)


def test_a_frame_failing_its_checksum_is_handed_on_and_the_frames_its_length_covered_found(
        ) -> None:
    """A message of no fixed length (NAV-POSLLH here) whose length byte grew from 28 to 156:
    its checksum fails once its bytes are in; it goes to the decoder (counted, flagged),
    and the NAV-PVT and the sentence it covered are read."""
    bad = bytearray(ubx_frame(0x01, 0x02, bytes(range(28))))
    bad[4] ^= 0x80
    s = StreamSplitter()
    items = s.feed(bytes(bad) + _pvt() + GGA + bytes(64))
    assert [k for k, _ in items] == ["ubx", "ubx", "nmea"]
    assert not decode_ubx(items[0][1]).checksum_ok
    assert items[1:] == [("ubx", _pvt()), ("nmea", GGA)]


def test_a_byte_inside_a_failed_frame_that_looks_like_a_start_is_not_taken() -> None:
    """A payload holding ``$...\n`` or a UBX sync: inside the bytes a failed frame claimed,
    only an item with a good checksum is taken."""
    payload = b"$GPXXX,1*00\r\n" + b"\xb5\x62\x05\x01\x02\x00\x06\x01\x00\x00" + bytes(40)
    bad = bytearray(ubx_frame(0x01, 0x02, payload))
    bad[-1] ^= 0xFF
    s = StreamSplitter()
    items = s.feed(bytes(bad) + RMC)
    assert [k for k, _ in items] == ["ubx", "nmea"] and items[1][1] == RMC


def test_a_sentence_whose_line_feed_is_corrupted_costs_only_itself() -> None:
    """NMEA has no length to believe: a sentence ends at its line feed or the next start."""
    s = StreamSplitter()
    assert s.feed(GGA[:-1] + b"\x0b" + RMC + VTG) == [("nmea", RMC), ("nmea", VTG)]


def test_noise_between_sentences_is_counted_and_skipped() -> None:
    s = StreamSplitter()
    items = s.feed(b"\x01\x02garbage\xff" + GGA + b"\x7f\x80" + RMC)
    assert [i for _, i in items] == [GGA, RMC]
    assert s.garbage_bytes == 12  # 10 before the GGA, 2 between
