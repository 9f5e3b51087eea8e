"""The IGC log sink on hand-made events: B records at whole UTC seconds with the barometer's
ISA pressure altitude at the fix epoch, validity, the I record's extensions, the FAI file
name, and a G record that verifies after every record and fails after any change."""

from __future__ import annotations

import os
from datetime import datetime, timezone
from pathlib import Path

import pytest

pytest.importorskip("aerofiles", reason="the igc extra (aerofiles) is not installed")

from tests.support.igc_reader import parse_igc

from imuhal.core.atmosphere import altitude_m_from_pressure, pressure_pa_at_altitude
from imuhal.core.samples import FixType, PositionSample, PressureSample, SampleFlag
from imuhal.sinks.flight.igc import IgcCheckError, IgcSink, check_igc_bytes, verify_igc

UTC0 = datetime(2026, 6, 21, 11, 0, 0, tzinfo=timezone.utc).timestamp()


def _fix(t_s: float, *, lat: float = 46.6, lon: float = 8.0, h: float = 920.0,
         fix: FixType = FixType.FIX_3D, acc: float | None = 2.5, sats: int = 12,
         flags: SampleFlag = SampleFlag.OK) -> PositionSample:
    return PositionSample(t_ns=round(t_s * 1e9), device="gps", flags=flags, latitude_deg=lat,
                          longitude_deg=lon, height_m=h, horizontal_accuracy_m=acc,
                          fix_type=fix, satellites=sats, utc_s=UTC0 + t_s)


def _pressure(t_s: float, altitude_m: float) -> PressureSample:
    return PressureSample(t_ns=round(t_s * 1e9), device="baro",
                          pressure_pa=pressure_pa_at_altitude(altitude_m))


def _fly(sink: IgcSink, seconds: int, *, climb_m_s: float = 2.0, gps_hz: int = 5,
         lose_fix: tuple[float, float] | None = None) -> None:
    """Pressure at 50 Hz of a steady climb from 900 m, fixes at ``gps_hz``, in time order."""
    events = []
    for k in range(seconds * 50):
        t = k / 50
        events.append(_pressure(t, 900.0 + climb_m_s * t))
    for k in range(seconds * gps_hz):
        t = k / gps_hz
        lost = lose_fix is not None and lose_fix[0] <= t < lose_fix[1]
        events.append(_fix(t, lat=46.6 + t * 1e-5, h=920 + climb_m_s * t,
                           fix=FixType.NO_FIX if lost else FixType.FIX_3D,
                           flags=SampleFlag.STALE if lost else SampleFlag.OK))
    for e in sorted(events, key=lambda e: e.t_ns):
        sink.handle(e)


def test_b_records_come_at_whole_seconds_with_the_isa_pressure_altitude_at_the_epoch(
        tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    _fly(sink, 20)
    sink.close()
    igc = parse_igc((tmp_path / "f.igc").read_bytes())
    assert [f.seconds_of_day for f in igc.fixes] == [11 * 3600 + s for s in range(20)]
    for f in igc.fixes:
        t = f.seconds_of_day - 11 * 3600
        assert abs(f.pressure_altitude_m - (900.0 + 2.0 * t)) <= 0.5  # rounded to 1 m
        assert f.gnss_altitude_m == round(920 + 2.0 * t) and f.valid
        assert abs(f.latitude_deg - (46.6 + t * 1e-5)) < 1e-3 / 60 / 2 + 1e-12
        assert f.extensions == {"FXA": "003", "SIU": "12"}
    assert igc.headers["DTE"] == "210626" and igc.headers["ALP"] == "ISA"
    assert "not an approved logger" in igc.headers["FRS"]
    assert sink.b_records == 20


def test_the_interval_setting_spaces_the_b_records(tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc"), "log": {"interval_s": 5}})
    _fly(sink, 21)
    sink.close()
    igc = parse_igc((tmp_path / "f.igc").read_bytes())
    assert [f.seconds_of_day - 11 * 3600 for f in igc.fixes] == [0, 5, 10, 15, 20]


def test_a_lost_fix_logs_v_records_at_the_last_position_and_no_gnss_altitude(
        tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    _fly(sink, 12, lose_fix=(4.0, 8.0))
    sink.close()
    fixes = parse_igc((tmp_path / "f.igc").read_bytes()).fixes
    lost = [f for f in fixes if 4 <= f.seconds_of_day - 11 * 3600 < 8]
    assert len(lost) == 4 and not any(f.valid for f in lost)
    assert all(f.gnss_altitude_m == 0 and f.extensions == {"FXA": "999", "SIU": "00"}
               for f in lost)
    last_known = round((46.6 + 3.8e-5) * 60000) / 60000  # the fix at 3.8 s, in 0.001'
    assert all(abs(f.latitude_deg - last_known) < 1e-9 for f in lost)
    assert all(f.pressure_altitude_m > 900 for f in lost)  # the barometer carries on
    assert all(f.valid for f in fixes if f not in lost)


def test_a_receiver_without_accuracy_declares_satellites_only(tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    for k in range(3):
        sink.handle(_pressure(k, 500.0))
        sink.handle(_fix(k, acc=None, sats=7))
    sink.close()
    igc = parse_igc((tmp_path / "f.igc").read_bytes())
    assert [f.extensions for f in igc.fixes] == [{"SIU": "07"}] * 3
    assert "FXA" not in igc.headers


def test_nothing_is_written_before_the_first_fix(tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    sink.handle(_pressure(0.0, 500.0))
    sink.handle(_fix(0.0, fix=FixType.NO_FIX, flags=SampleFlag.STALE))
    sink.close()
    assert sink.path is None and not list(tmp_path.iterdir())


def test_a_folder_gets_the_fai_long_name_and_the_next_free_flight_number(
        tmp_path: Path) -> None:
    names = []
    for _ in range(2):
        sink = IgcSink({"path": str(tmp_path), "log": {"logger_id": "AB1"}})
        _fly(sink, 2)
        sink.close()
        names.append(sink.path.name if sink.path else None)
    assert names == ["2026-06-21-XXX-AB1-01.IGC", "2026-06-21-XXX-AB1-02.IGC"]
    assert parse_igc((tmp_path / names[1]).read_bytes()).a_record == "AXXXAB1"


def test_the_file_verifies_after_every_record_while_it_is_written(tmp_path: Path) -> None:
    """The log in FILE.partial is a valid file at every moment: each B record and its new G
    record replace the old G record together."""
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    partial = tmp_path / "f.igc.partial"
    seen = 0
    for k in range(10):
        sink.handle(_pressure(k, 900.0))
        sink.handle(_fix(k))
        check = verify_igc(partial)
        assert check.b_records == sink.b_records == k + 1
        seen += 1
    sink.close()
    assert not partial.exists() and verify_igc(tmp_path / "f.igc").b_records == seen


def test_verify_fails_after_any_single_byte_is_changed_or_the_file_is_cut(
        tmp_path: Path) -> None:
    path = tmp_path / "f.igc"
    sink = IgcSink({"path": str(path)})
    _fly(sink, 8)
    sink.close()
    good = path.read_bytes()
    assert verify_igc(path).b_records == 8
    for i in range(len(good)):
        for delta in (1, 0x20, 0x80):
            changed = bytearray(good)
            changed[i] ^= delta
            with pytest.raises(IgcCheckError):
                check_igc_bytes(bytes(changed))
    for cut in range(len(good)):
        with pytest.raises(IgcCheckError):
            check_igc_bytes(good[:cut])


def test_an_empty_file_is_reported_as_a_run_stopped_before_it_logged_anything(
        tmp_path: Path) -> None:
    path = tmp_path / "f.igc.partial"
    path.write_bytes(b"")
    with pytest.raises(IgcCheckError, match="is empty: its run was stopped before it logged"):
        verify_igc(path)


def test_an_aborted_run_keeps_a_verifying_partial_file_and_the_old_file(
        tmp_path: Path) -> None:
    path = tmp_path / "f.igc"
    path.write_bytes(b"an older flight")
    sink = IgcSink({"path": str(path)})
    _fly(sink, 3)
    kept = sink.abort()
    assert kept == tmp_path / "f.igc.partial" and verify_igc(kept).b_records == 3
    assert path.read_bytes() == b"an older flight"


def test_pressure_altitude_is_zero_when_the_barometer_is_silent(tmp_path: Path) -> None:
    sink = IgcSink({"path": str(tmp_path / "f.igc")})
    sink.handle(_pressure(0.0, 700.0))
    for k in range(4):
        sink.handle(_fix(k))
    sink.close()
    alts = [f.pressure_altitude_m for f in parse_igc((tmp_path / "f.igc").read_bytes()).fixes]
    assert alts == [700, 700, 0, 0]  # the last pressure is > 1 s older than the fix
    assert altitude_m_from_pressure(pressure_pa_at_altitude(700.0)) == pytest.approx(700.0)


def test_a_folder_that_does_not_exist_is_refused_before_the_run(tmp_path: Path) -> None:
    from imuhal.core.errors import ImuhalError

    with pytest.raises(ImuhalError, match="does not exist"):
        IgcSink({"path": str(tmp_path / "no" / "f.igc")})
    with pytest.raises(ImuhalError, match="mkdir -p"):  # a folder meant, not a file
        IgcSink({"path": str(tmp_path / "flights") + "/"})
    assert os.listdir(tmp_path) == []


def test_igc_verify_exits_0_for_a_good_file_and_2_with_one_line_for_a_changed_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from imuhal.cli.main import main

    path = tmp_path / "f.igc"
    sink = IgcSink({"path": str(path)})
    _fly(sink, 3)
    sink.close()
    assert main(["igc", "verify", str(path)]) == 0
    assert "ok (" in capsys.readouterr().out
    data = bytearray(path.read_bytes())
    data[60] ^= 1
    path.write_bytes(bytes(data))
    assert main(["igc", "verify", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "does not match" in err


def test_igc_pilot_without_igc_is_a_one_line_error(capsys: pytest.CaptureFixture[str]
                                                   ) -> None:
    from imuhal.cli.main import main

    assert main(["run", "--emulate", "thermal", "--igc-pilot", "Jane"]) == 2
    assert "add --igc" in capsys.readouterr().err
