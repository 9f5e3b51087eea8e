"""Files are never lost: a stopped logger finalizes its log under its own name, a failed run
keeps the previous log (and its own rows beside it), calibration follows links and never
edits a bundled profile, and its prompts name the position being recorded."""

from __future__ import annotations

import csv
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from tests.support.disk_full import file_size_limit

from imuhal.cli import main as cli_main
from imuhal.emulation import open_emulated
from imuhal.pipeline import CallbackSink, CsvSink
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.sinks.builtin import CSV_COLUMNS

DATA = Path(__file__).resolve().parent.parent / "data"
# Most runs here pass --skip-calibration: what they check is what happens to files, and the
# calibration an emulated run makes first (seconds of CPU each; tests/calibration/
# test_calibration_as_user.py checks it) happens before any output is opened. Not the one
# that compares the simulated time a stopped run reports with its wall time: without the
# calibrated records, the start-up phase adds simulated time that is not paced.
SEED_BOARD = DATA / "calibration" / "seed-board.yaml"


def _complete_log(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV log that is whole: header, every row full, last line terminated."""
    text = path.read_text()
    assert text.endswith("\n")
    rows = list(csv.reader(text.splitlines()))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert all(len(r) == len(CSV_COLUMNS) for r in rows[1:])
    return list(csv.DictReader(text.splitlines()))


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_stop_signal_finalizes_the_log_under_its_own_name(signum: int, tmp_path: Path) -> None:
    """Issue 9 item 13."""
    out = tmp_path / "flight.csv"
    partial = tmp_path / "flight.csv.partial"
    proc = subprocess.Popen(
        [sys.executable, "-m", "imuhal.cli.main", "run", "--emulate", "static", "--realtime",
         "--skip-calibration", "--duration", "120", "--quiet", "--output", str(out)],
        stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (partial.exists() and partial.stat().st_size > 4096):
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "the log never reached the disk"
            time.sleep(0.05)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "the files are complete up to here" in err
    rows = _complete_log(out)
    assert len(rows) > 20
    assert not partial.exists()


def test_run_output_through_a_symlink_writes_the_target_and_keeps_the_link(
        tmp_path: Path) -> None:
    """Issue 9 item 14."""
    real = tmp_path / "logs" / "flight.csv"
    real.parent.mkdir()
    real.write_text("old\n")
    link = tmp_path / "latest.csv"
    link.symlink_to(real)
    assert cli_main.main(["run", "--emulate", "static", "--skip-calibration", "--duration",
                          "1", "--quiet", "--output", str(link)]) == 0
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert len(_complete_log(real)) > 20


def test_run_output_to_a_fifo_streams_into_it(tmp_path: Path) -> None:
    """Issue 9 item 14."""
    fifo = tmp_path / "live"
    os.mkfifo(fifo)
    received: list[str] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_text()))
    reader.start()
    assert cli_main.main(["run", "--emulate", "static", "--skip-calibration", "--duration",
                          "1", "--quiet", "--output", str(fifo)]) == 0
    reader.join(timeout=30)
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    rows = list(csv.reader(received[0].splitlines()))
    assert tuple(rows[0]) == CSV_COLUMNS and len(rows) > 20


def test_a_failed_run_keeps_the_previous_log_and_leaves_its_rows_beside_it(
        tmp_path: Path) -> None:
    """Issue 9 item 12: the log's disk fills up mid-run (a file size limit)."""
    out = tmp_path / "flight.csv"
    out.write_text("the good flight\n")
    proc = subprocess.run(
        [sys.executable, "-m", "imuhal.cli.main", "run", "--emulate", "static",
         "--skip-calibration", "--duration", "20", "--quiet", "--samples", "--output", str(out)],
        capture_output=True, text=True, timeout=300, check=False,
        preexec_fn=lambda: file_size_limit(300_000))
    assert proc.returncode == 2, proc.stderr
    assert out.read_text() == "the good flight\n"
    partial = tmp_path / "flight.csv.partial"
    assert partial.stat().st_size <= 300_000
    error = proc.stderr.strip().splitlines()[-1]
    assert error.startswith("imuhal: error: the log failed")
    assert f"{out} was left as it was" in error and str(partial) in error
    assert "sink 'CsvSink'" in proc.stderr and "File too large" in proc.stderr


def test_a_failing_sink_is_left_out_and_the_log_is_still_committed(tmp_path: Path) -> None:
    """Issue 26 item 3: a sink that raises is contained; the other outputs go on."""
    registry = load_registry()
    out = tmp_path / "flight.csv"
    out.write_text("the good flight\n")
    log = CsvSink(out)

    def disk_full(event: object) -> None:
        if getattr(event, "t_ns", 0) > 500_000_000:
            raise OSError(28, "No space left on device")

    with open_emulated(load_profile(default_profile_path(), registry), registry,
                       scenario="static") as pipeline:
        summary = pipeline.run(2.0, [log, CallbackSink(disk_full)])
    rows = _complete_log(out)
    assert float(rows[-1]["t_s"]) > 1.9
    assert summary.contained["sink 'CallbackSink'"] == {"exceptions": 1, "disabled": 1}
    assert any(w.startswith("sink 'CallbackSink' (module imuhal.sinks.builtin) disabled "
                            "after it raised OSError: [Errno 28] No space left on device")
               for w in summary.warnings)


# --------------------------------------------------------------------------- calibrate
@pytest.fixture
def board(tmp_path: Path) -> Path:
    path = tmp_path / "boards" / "board.yaml"
    path.parent.mkdir()
    shutil.copy(SEED_BOARD, path)
    return path


@pytest.fixture(scope="module")
def chips() -> Registry:
    return load_registry()


def test_calibrating_through_a_symlink_updates_the_real_profile_and_keeps_the_link(
        board: Path, tmp_path: Path, chips: Registry) -> None:
    """Issue 9 item 14."""
    link = tmp_path / "link.yaml"
    link.symlink_to(board)
    assert cli_main.main(["calibrate", "gyro", str(link), "--emulate", "calibration"]) == 0
    assert link.is_symlink()
    assert load_profile(board, chips).devices["imu"].calibration.gyro is not None  # type: ignore[union-attr]
    assert (board.parent / "board.yaml.bak").read_text() == SEED_BOARD.read_text()
    assert not (tmp_path / "link.yaml.bak").exists()


def test_calibrate_output_writes_a_calibrated_copy_and_leaves_the_profile(
        board: Path, tmp_path: Path, chips: Registry) -> None:
    copy = tmp_path / "calibrated.yaml"
    assert cli_main.main(["calibrate", "gyro", str(board), "--emulate", "calibration",
                          "--output", str(copy)]) == 0
    assert board.read_text() == SEED_BOARD.read_text()
    assert load_profile(copy, chips).devices["imu"].calibration.gyro is not None  # type: ignore[union-attr]
    assert "# chip select 0" in copy.read_text()


def test_a_bundled_profile_is_never_calibrated_in_place(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bundled = default_profile_path()
    before = bundled.read_bytes()
    assert cli_main.main(["calibrate", "gyro", str(bundled), "--emulate", "calibration"]) == 2
    assert "Copy it first" in capsys.readouterr().err
    assert bundled.read_bytes() == before
    copy = tmp_path / "mine.yaml"
    assert cli_main.main(["calibrate", "gyro", str(bundled), "--emulate", "calibration",
                          "-o", str(copy)]) == 0
    assert bundled.read_bytes() == before and copy.exists()


def test_emulated_accel_prompts_name_the_position_being_recorded(
        board: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main.main(["calibrate", "accel", str(board), "--emulate", "calibration",
                          "--dry-run"]) == 0
    err = capsys.readouterr().err
    asked = re.findall(r">> position \d/6: (.*), and hold it still", err)
    recorded = re.findall(r"   recorded (.*)", err)
    assert len(asked) == 6 and asked == recorded


def test_a_second_run_writing_the_same_output_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 26 item 6: the second run exits 2 naming the output; the first run's rows
    stay whole (no NUL bytes, no rows of the second)."""
    from imuhal.cli import main as cli_main
    from imuhal.core.atomic import AtomicFile

    target = tmp_path / "log.csv"
    first = AtomicFile(target, partial=True)
    first.write("the first run's rows\n")
    first.sync()
    code = cli_main.main(["run", "--skip-calibration", "--duration", "0.3", "--quiet", "--output",
                          str(target)])
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert code == 2
    assert len(err) == 1 and "another run is writing it" in err[0] and str(target) in err[0]
    first.commit()
    assert target.read_text() == "the first run's rows\n"


def test_a_stopped_run_reports_how_long_it_ran(tmp_path: Path) -> None:
    """Issue 26 item 8: after SIGTERM the summary said "ran 0.0 s in 0.00 s wall time"."""
    out = tmp_path / "flight.csv"
    partial = tmp_path / "flight.csv.partial"
    proc = subprocess.Popen(
        [sys.executable, "-m", "imuhal.cli.main", "run", "--emulate", "static", "--realtime",
         "--duration", "120", "--output", str(out)],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (partial.exists() and partial.stat().st_size > 4096):
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "the log never reached the disk"
            time.sleep(0.05)
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    ran = re.search(r"ran (\d+\.\d) s in (\d+\.\d+) s wall time", err)
    assert ran is not None, err
    simulated, wall = float(ran[1]), float(ran[2])
    assert simulated >= 1.0 and wall >= 1.0 and abs(simulated - wall) < 1.0
