"""The CSV log: documented header, one row per event, written atomically."""

from __future__ import annotations

import csv
from pathlib import Path

from imuhal.core.samples import PressureSample, SampleFlag
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.sinks import CSV_COLUMNS, CsvSink

DOCUMENTED = Path(__file__).resolve().parents[2] / "docs" / "output-csv.md"


def test_every_column_is_documented() -> None:
    text = DOCUMENTED.read_text()
    missing = [c for c in CSV_COLUMNS if f"`{c}`" not in text]
    assert missing == []


def test_rows_fill_the_columns_of_their_kind(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    sink = CsvSink(path, include_samples=True)
    sink.handle(PressureSample(t_ns=1_500_000_000, device="baro", pressure_pa=90000.0,
                               flags=SampleFlag.STALE))
    sink.handle(VerticalEstimate(t_ns=2_000_000_000, source="vario", altitude_m=10.0,
                                 climb_m_s=-1.5))
    sink.handle(AttitudeEstimate(t_ns=3_000_000_000, source="ahrs",
                                 q_body_to_ned=(1.0, 0.0, 0.0, 0.0)))
    sink.close()
    rows = list(csv.DictReader(path.open()))
    assert [r["kind"] for r in rows] == ["pressure", "vertical", "attitude"]
    assert rows[0]["t_s"] == "1.500000" and rows[0]["flags"] == str(int(SampleFlag.STALE))
    assert float(rows[1]["climb_m_s"]) == -1.5 and rows[1]["pressure_pa"] == ""
    assert float(rows[2]["yaw_deg"]) == 0.0


def test_samples_are_left_out_unless_asked_for(tmp_path: Path) -> None:
    sink = CsvSink(tmp_path / "log.csv")
    sink.handle(PressureSample(t_ns=0, device="baro", pressure_pa=1.0))
    sink.close()
    assert sink.rows == 0


def test_nothing_appears_under_the_final_name_until_close(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    sink = CsvSink(path)
    sink.handle(VerticalEstimate(t_ns=0, source="v", altitude_m=1.0, climb_m_s=0.0))
    assert not path.exists()
    sink.close()
    assert path.exists()
    assert list(tmp_path.iterdir()) == [path]


def test_an_aborted_run_leaves_the_previous_log_intact_and_its_rows_beside_it(
        tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text("previous\n")
    sink = CsvSink(path)
    sink.handle(VerticalEstimate(t_ns=0, source="v", altitude_m=1.0, climb_m_s=0.0))
    partial = sink.abort()
    assert path.read_text() == "previous\n"
    assert partial == tmp_path / "log.csv.partial"
    assert [r["kind"] for r in csv.DictReader(partial.open())] == ["vertical"]


def test_an_aborted_run_without_rows_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text("previous\n")
    sink = CsvSink(path)
    assert sink.abort() is None
    assert list(tmp_path.iterdir()) == [path]


def test_the_log_is_on_disk_under_its_partial_name_from_the_start(tmp_path: Path) -> None:
    # A power cut loses at most sync_every_s of rows: they are in log.csv.partial.
    path = tmp_path / "log.csv"
    sink = CsvSink(path, sync_every_s=0.0)
    sink.handle(VerticalEstimate(t_ns=0, source="v", altitude_m=1.0, climb_m_s=0.0))
    rows = list(csv.DictReader((tmp_path / "log.csv.partial").open()))
    assert [r["kind"] for r in rows] == ["vertical"]
    sink.close()
