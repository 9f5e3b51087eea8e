"""``imuhal estimate`` streams: a log read, run and written in chunks gives the same file as in
one piece, ``--columns`` chooses the output columns, and a bad row late in the log leaves no
output behind."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from tests.support.disk_full import file_size_limit

from imuhal.cli.main import main
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.offline import csv_input
from imuhal.offline.csv_input import InputError, iter_sample_chunks, read_sample_csv
from imuhal.offline.csv_output import EstimateCsvWriter

HEADER = ["t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
          "mx_ut", "my_ut", "mz_ut"]


def _log(path: Path, rows: int, *, bad_line: int | None = None) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for i in range(rows):
            mag = ["20.5", "1.25", "44"] if i % 3 == 0 else ["", "", ""]
            gx = "x" if bad_line == i + 2 else f"{0.01 * (i % 7):.3f}"
            w.writerow([f"{i * 0.004:.3f}", gx, "-0.02", "0.1", "0.3", "-0.2", "-9.7", *mag])


def test_chunks_carry_the_whole_file_and_check_time_across_chunk_edges(tmp_path: Path) -> None:
    src = tmp_path / "imu.csv"
    _log(src, 25)
    chunks = list(iter_sample_chunks(src, chunk_rows=10))
    assert [len(c) for c in chunks] == [10, 10, 5]
    assert chunks[1].lines[0] == 12
    rows = src.read_text().splitlines()
    rows[12], rows[11] = rows[11], rows[12]  # lines 12 and 13 swap: time goes back at an edge
    src.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"line 13, column 't_s'.*does not increase"):
        list(iter_sample_chunks(src, chunk_rows=11))


def test_estimate_in_small_chunks_writes_the_same_file_as_in_one(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch
                                                                 ) -> None:
    src = tmp_path / "imu.csv"
    _log(src, 300)
    whole, chunked = tmp_path / "whole.csv", tmp_path / "chunked.csv"
    assert main(["estimate", "madgwick", str(src), "-o", str(whole)]) == 0
    monkeypatch.setattr(csv_input, "CHUNK_ROWS", 7)
    assert len(list(iter_sample_chunks(src))) > 40
    assert main(["estimate", "madgwick", str(src), "-o", str(chunked)]) == 0
    assert chunked.read_text() == whole.read_text()


def test_columns_option_writes_only_the_named_columns_in_that_order(tmp_path: Path) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "q.csv"
    _log(src, 50)
    assert main(["estimate", "madgwick", str(src), "-o", str(out),
                 "--columns", "t_s,qw,qx,qy,qz"]) == 0
    with out.open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["t_s", "qw", "qx", "qy", "qz"]
    assert len(rows) == 51 and all(len(r) == 5 for r in rows)


def test_unknown_column_is_a_one_line_error_and_no_file(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "q.csv"
    _log(src, 20)
    assert main(["estimate", "madgwick", str(src), "-o", str(out),
                 "--columns", "t_s,quaternion"]) == 2
    err = capsys.readouterr().err
    assert "--columns: quaternion not written by this estimator" in err and "qw" in err
    assert not out.exists()


def test_bad_row_late_in_a_long_log_keeps_the_previous_output(tmp_path: Path) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    _log(src, 20_000, bad_line=19_000)
    out.write_text("previous result\n")
    assert main(["estimate", "madgwick", str(src), "-o", str(out)]) == 2
    assert out.read_text() == "previous result\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.csv", "out.csv"]


def test_a_column_first_seen_late_is_added_and_earlier_rows_padded(tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    writer = EstimateCsvWriter(out)
    q = (1.0, 0.0, 0.0, 0.0)
    writer.write([AttitudeEstimate(t_ns=1, source="a", q_body_to_ned=q,
                                   diagnostics={"steps": 1})])
    writer.write([AttitudeEstimate(t_ns=2, source="a", q_body_to_ned=q,
                                   diagnostics={"steps": 2, "late": 0.5})])
    assert writer.commit() == 2
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[-2:] == ["steps", "late"]
    assert rows[0]["late"] == "" and rows[1]["late"] == "0.5"
    assert rows[0]["steps"] == "1"


def test_whole_file_reader_is_the_chunks_joined(tmp_path: Path) -> None:
    src = tmp_path / "imu.csv"
    _log(src, 30)
    table = read_sample_csv(src)
    assert len(table) == 30 and table.lines[-1] == 31


def _cells(path: Path, estimates: list[AttitudeEstimate]) -> list[list[str]]:
    writer = EstimateCsvWriter(path)
    writer.write(estimates)
    writer.commit()
    with path.open(newline="") as f:
        return list(csv.reader(f))


def _attitude(t_ns: int, diagnostics: dict) -> AttitudeEstimate:
    return AttitudeEstimate(t_ns=t_ns, source="a", q_body_to_ned=(1.0, 0.0, 0.0, 0.0),
                            diagnostics=diagnostics)


def test_uniform_diagnostics_are_written_column_by_column_as_row_by_row(
        tmp_path: Path) -> None:
    """A chunk whose estimates carry diagnostics of one form (the common case, written
    column by column) gives the cells that rows of mixed forms (written row by row) give:
    booleans as 0/1, floats by repr (NaN and inf as nan), vectors as ``name_i``, text and
    None left out."""
    diags = [{"dt_s": 0.005, "gate_open": True, "steps": 3, "bias": (0.25, -1e-9, 3.0),
              "source": "none", "nothing": None, "w": float("inf")},
             {"dt_s": 0.004, "gate_open": False, "steps": 4, "bias": (0.5, 2.0, float("nan")),
              "source": "none", "nothing": None, "w": 0.1}]
    uniform = _cells(tmp_path / "u.csv", [_attitude(i, d) for i, d in enumerate(diags)])
    # a third row of another form makes the whole chunk go row by row
    mixed = _cells(tmp_path / "m.csv", [_attitude(i, d) for i, d in enumerate(diags)]
                   + [_attitude(2, {"dt_s": 1})])
    assert uniform[0][-7:] == ["dt_s", "gate_open", "steps", "bias_0", "bias_1", "bias_2",
                               "w"]
    assert uniform[0] == mixed[0]
    assert uniform[1:] == mixed[1:3]
    head = uniform[0]
    row = dict(zip(head, uniform[2], strict=True))
    assert (row["gate_open"], row["steps"], row["bias_2"], row["w"]) == ("0", "4", "nan", "0.1")
    assert "source" not in head and "nothing" not in head


def test_estimate_into_a_fifo_streams_the_file_it_would_write(tmp_path: Path) -> None:
    """A FIFO gets the whole output at the end (header first), as a file would hold it."""
    src, out, fifo = tmp_path / "imu.csv", tmp_path / "out.csv", tmp_path / "pipe"
    _log(src, 400)
    assert main(["estimate", "madgwick", str(src), "-o", str(out)]) == 0
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    assert main(["estimate", "madgwick", str(src), "-o", str(fifo)]) == 0
    reader.join(timeout=30)
    assert received == [out.read_bytes()]


def test_a_full_disk_mid_estimate_keeps_the_previous_output_and_leaves_nothing(
        tmp_path: Path) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    _log(src, 20_000)  # about 3.7 MB of output
    out.write_text("previous result\n")
    proc = subprocess.run(
        [sys.executable, "-m", "imuhal.cli.main", "estimate", "madgwick", str(src), "-o",
         str(out)], capture_output=True, text=True, timeout=300, check=False,
        preexec_fn=lambda: file_size_limit(2_000_000))
    assert proc.returncode == 2, proc.stderr
    assert "cannot be written" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert out.read_text() == "previous result\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.csv", "out.csv"]
