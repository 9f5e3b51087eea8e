"""A sweep of every command's options with wrong input, as a hostile new user would try them:
each mistake is one line on stderr naming the input and the fix (exit 2), never a traceback or
"internal error"; a failed command never touches its inputs nor replaces an existing output
(issue 9, items 11-17, beyond the cases listed there: tests/cli/test_user_mistakes.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from imuhal import __version__
from imuhal.cli import main as cli_main

DATA = Path(__file__).resolve().parent.parent / "data"
SEED_BOARD = DATA / "calibration" / "seed-board.yaml"
IMU_HEADER = "t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Files a user has: a run log with samples, its truth, its bus recording, a wide CSV,
    a profile, and some that are no imuhal file at all."""
    d = tmp_path_factory.mktemp("made")
    assert cli_main.main(["run", "--duration", "1.5", "--quiet", "--output", str(d / "log.csv"),
                          "--samples", "--truth", str(d / "truth.csv"),
                          "--record", str(d / "rec.imr")]) == 0
    (d / "imu.csv").write_text(IMU_HEADER + "".join(f"{i * 0.01:.2f},0,0,0,0,0,-9.81\n"
                                                    for i in range(50)))
    (d / "notime.csv").write_text(IMU_HEADER.partition(",")[2] + "0,0,0,0,0,-9.81\n" * 50)
    (d / "garbage.bin").write_bytes(bytes(range(256)) * 8)
    shutil.copy(SEED_BOARD, d / "board.yaml")
    shutil.copy(d / "truth.csv", d / "flight.csv.partial")  # a truth recovered after a cut
    return d


@pytest.fixture
def work(made: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A scratch copy of ``made`` as the working folder, with a link to imu.csv and a folder."""
    for f in made.iterdir():
        shutil.copy(f, tmp_path / f.name)
    (tmp_path / "link.csv").symlink_to(tmp_path / "imu.csv")
    (tmp_path / "folder").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


@dataclass
class Mistake:
    argv: list[str]
    names: str
    """Text the one-line error must contain (the input or option it is about)."""


def m(line: str, names: str) -> Mistake:
    return Mistake(line.split(), names)


MISTAKES: dict[str, Mistake] = {
    # estimate
    "estimate: --rate for an input that has t_s": m(
        "estimate madgwick imu.csv -o o.csv --rate 100", "--rate"),
    "estimate: --rate for a run log": m("estimate madgwick log.csv -o o.csv --rate 100",
                                        "--rate"),
    "estimate: --rate beyond any sensor": m(
        "estimate madgwick notime.csv -o o.csv --rate 1e300", "--rate"),
    "estimate: a column named twice": m(
        "estimate madgwick imu.csv -o o.csv --columns t_s,qw,t_s", "t_s named twice"),
    "estimate: output through a link to the input": m(
        "estimate madgwick imu.csv -o link.csv", "link.csv"),
    "estimate: input through a link to the output": m(
        "estimate madgwick link.csv -o imu.csv", "imu.csv"),
    "estimate: output is a folder": m("estimate madgwick imu.csv -o folder", "folder"),
    "estimate: input is a folder": m("estimate madgwick folder -o o.csv", "folder"),
    "estimate: binary input": m("estimate madgwick garbage.bin -o o.csv", "garbage.bin"),
    "estimate: a profile as input": m("estimate madgwick board.yaml -o o.csv", "board.yaml"),
    "estimate: unknown --ahrs": m("estimate vario-kf3 imu.csv -o o.csv --ahrs nosuch",
                                  "nosuch"),
    "estimate: unknown --ahrs-set key": m(
        "estimate vario-kf3 imu.csv -o o.csv --ahrs-set nosuch=1", "--ahrs-set nosuch"),
    "estimate: --ahrs for an attitude estimator": m(
        "estimate madgwick imu.csv -o o.csv --ahrs mahony", "--ahrs"),
    "estimate: --ahrs-set for an attitude estimator": m(
        "estimate madgwick imu.csv -o o.csv --ahrs-set beta=0.1", "--ahrs-set"),
    "estimate: a setting given twice": m(
        "estimate madgwick imu.csv -o o.csv --set beta=1 --set beta=2", "beta"),
    "estimate: unknown preset": m("estimate madgwick imu.csv -o o.csv --set preset=nosuch",
                                  "nosuch"),
    "estimate: setting without a value": m("estimate madgwick imu.csv -o o.csv --set beta",
                                           "beta"),
    # kernels (the compiled-kernel plugin command)
    "kernels: no action": m("kernels", "ACTION"),
    "kernels: an unknown action": m("kernels compile", "compile"),
    # replay
    "replay: output over its recording": m("replay rec.imr --output rec.imr --quiet",
                                           "rec.imr"),
    "replay: output over its profile": m(
        "replay rec.imr --profile board.yaml --output board.yaml --quiet", "board.yaml"),
    "replay: output in a missing folder": m("replay rec.imr --output nodir/o.csv --quiet",
                                            "nodir"),
    "replay: --samples without --output": m("replay rec.imr --samples --quiet", "--output"),
    "replay: a CSV is no recording": m("replay imu.csv", "imu.csv"),
    "replay: a sink setting for no sink": m("replay rec.imr --quiet --sink-set mqtt.x=1",
                                            "--sink-set"),
    "replay: a sink no plugin registered": m("replay rec.imr --quiet --sink kafka", "kafka"),
    "estimate: a sink setting for no sink": m(
        "estimate madgwick log.csv -o o.csv --sink-set mqtt.x=1", "--sink-set"),
    "estimate: publishing a wide CSV": m("estimate madgwick imu.csv -o o.csv --sink mqtt",
                                         "--sink mqtt"),
    "replay: binary garbage": m("replay garbage.bin", "garbage.bin"),
    # run
    "run: recording over the log": m("run --duration 0.2 --quiet --output o.csv --record o.csv",
                                     "--record"),
    "run: recording over the profile": m(
        "run board.yaml --emulate static --duration 0.2 --quiet --record board.yaml",
        "board.yaml"),
    "run: the log's scratch file is the replayed truth": m(
        "run --emulate replay --quiet --replay-truth flight.csv.partial --output flight.csv",
        "flight.csv.partial"),
    "run: one output is the other's scratch file": m(
        "run --duration 0.2 --quiet --output a.csv --trace a.csv.partial", "a.csv"),
    "run: a pty link in a missing folder": m(
        "run --duration 0.2 --quiet --nmea pty:nodir/vario", "pty:nodir/vario"),
    "run: --nmea-sentences without --nmea": m(
        "run --duration 0.2 --quiet --nmea-sentences LK8EX1", "--nmea"),
    "run: an empty --nmea-sentences": m(
        "run --duration 0.2 --quiet --nmea pty --nmea-sentences ,", "--nmea-sentences"),
    "run: WAV over the log": m("run --duration 0.2 --quiet --output o.csv --audio-wav o.csv",
                               "--audio-wav"),
    "run: a sink setting for no sink": m("run --duration 0.2 --quiet --sink-set nmea.x=1",
                                         "--sink-set"),
    "run: a CSV as profile": m("run imu.csv --emulate static --duration 0.2", "imu.csv"),
    "run: a binary profile": m("run garbage.bin --emulate static --duration 0.2",
                               "garbage.bin"),
    "run: a folder as profile": m("run folder --emulate static --duration 0.2", "folder"),
    # plot
    "plot: a sample CSV as truth": m("plot log.csv -o f.png --truth imu.csv", "imu.csv"),
    "plot: a run log as truth": m("plot log.csv -o f.png --truth log.csv", "log.csv"),
    "plot: figure through a link to the truth": m("plot log.csv -o link.csv --truth imu.csv",
                                                  "link.csv"),
    "plot: figure over the log": m("plot log.csv -o log.csv", "log.csv"),
    # evaluate
    "evaluate: binary truth": m("evaluate log.csv --truth garbage.bin -e madgwick -q",
                                "garbage.bin"),
    "evaluate: two outputs one file": m(
        "evaluate log.csv --truth truth.csv -e madgwick -q --output o.csv --json o.csv",
        "o.csv"),
    "evaluate: output over the truth": m(
        "evaluate log.csv --truth truth.csv -e madgwick -q --output truth.csv", "truth.csv"),
    "evaluate: a grid value that is no number": m(
        "evaluate log.csv --truth truth.csv -e madgwick --grid madgwick.beta=x", "beta"),
    "evaluate: a grid key the estimator lacks": m(
        "evaluate log.csv --truth truth.csv -e madgwick --grid madgwick.nosuch=1,2", "nosuch"),
    "evaluate: a grid for an estimator not evaluated": m(
        "evaluate log.csv --truth truth.csv -e madgwick --grid mahony.kp=1,2", "mahony"),
    "evaluate: --workers without --dask": m(
        "evaluate log.csv --truth truth.csv -e madgwick --workers 2", "--workers"),
    "evaluate: --cache without --broad": m(
        "evaluate log.csv --truth truth.csv -e madgwick --cache folder", "--cache"),
    "evaluate: unknown --group": m(
        "evaluate log.csv --truth truth.csv -e madgwick -q --group nosuch", "nosuch"),
    # calibrate
    "calibrate: --field for the gyro": m(
        "calibrate gyro board.yaml --emulate calibration --field 48", "--field"),
    "calibrate: --method for the gyro": m(
        "calibrate gyro board.yaml --emulate calibration --method minmax", "--method"),
    "calibrate: --misalignment for the mag": m(
        "calibrate mag board.yaml --emulate calibration --misalignment", "--misalignment"),
    "calibrate: --at-startup for the accel": m(
        "calibrate accel board.yaml --emulate calibration --at-startup", "--at-startup"),
    "calibrate: --quantity for the gyro": m(
        "calibrate gyro board.yaml --emulate calibration --quantity accel", "--quantity"),
    "calibrate: --seed on hardware": m("calibrate gyro board.yaml --seed 3", "--seed"),
    "calibrate: --ideal on hardware": m("calibrate gyro board.yaml --ideal", "--ideal"),
    "calibrate: --dry-run with --output": m(
        "calibrate gyro board.yaml --emulate calibration --dry-run --output x.yaml",
        "--dry-run"),
    "calibrate: --show with a procedure": m("calibrate gyro --show board.yaml", "--show"),
    "calibrate: --show with --output": m("calibrate --show board.yaml --output x.yaml",
                                         "--show"),
    "calibrate: an absurd --field": m(
        "calibrate mag board.yaml --emulate calibration --field 1e300", "--field"),
    "calibrate: output through a link to an input": m(
        "calibrate gyro link.csv --emulate calibration --output imu.csv", "imu.csv"),
    # check-mounts
    "check-mounts: unknown scenario": m("check-mounts --emulate nosuch", "nosuch"),
    "check-mounts: --window for an emulated board": m("check-mounts --window 5", "--window"),
    "check-mounts: an endless --window": m("check-mounts board.yaml --window 1e300",
                                           "--window"),
    "run: --seed on hardware": m("run board.yaml --seed 3", "--seed"),
}
# `--output "$LOG"` with LOG unset: an empty path, for every option that names a file
MISTAKES.update({f"empty path: {' '.join(argv)}": Mistake(argv, "empty path") for argv in (
    ["run", "--duration", "0.2", "--quiet", "--output", ""],
    ["run", "--duration", "0.2", "--quiet", "--trace", ""],
    ["run", "--duration", "0.2", "--quiet", "--record", ""],
    ["run", "--duration", "0.2", "--quiet", "--audio-wav", ""],
    ["estimate", "madgwick", "imu.csv", "-o", ""],
    ["estimate", "madgwick", "", "-o", "o.csv"],
    ["replay", "rec.imr", "--output", ""],
    ["plot", "log.csv", "-o", ""],
    ["evaluate", "log.csv", "--truth", "truth.csv", "-e", "madgwick", "--json", ""],
    ["calibrate", "gyro", "board.yaml", "--emulate", "calibration", "--output", ""],
)})


@pytest.mark.parametrize("case", sorted(MISTAKES))
def test_a_wrong_option_value_is_one_line_naming_it(
        case: str, work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mistake = MISTAKES[case]
    before = {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()}
    try:
        code = cli_main.main(mistake.argv)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    err = capsys.readouterr().err
    lines = [li for li in err.strip().splitlines()
             if not li.startswith((f"imuhal {__version__}:", "replaying ", "checking "))]
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert len(lines) == 1, err
    assert "error:" in lines[0] and mistake.names in lines[0], lines[0]
    after = {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()}
    assert {n: b for n, b in after.items() if n in before} == before  # inputs untouched


FAILING_WRITERS: dict[str, list[str]] = {  # each fails after its output checks passed
    # --skip-calibration (here and in the two WAV tests below): the emulated calibration a
    # run makes first costs seconds of CPU and is tested in tests/calibration
    "run": ["run", "--skip-calibration", "--duration", "0.2", "--quiet", "--output", "OUT",
            "--nmea", "tcp:99999"],
    "estimate": ["estimate", "madgwick", "imu.csv", "-o", "OUT", "--set", "beta=nope"],
    "estimate (a bad row)": ["estimate", "madgwick", "garbage.bin", "-o", "OUT"],
    "replay": ["replay", "rec.imr", "--profile", "board.yaml", "--output", "OUT", "--quiet"],
    "plot": ["plot", "log.csv", "--truth", "imu.csv", "-o", "OUT.png"],
    "evaluate": ["evaluate", "log.csv", "--truth", "garbage.bin", "-e", "madgwick", "-q",
                 "--output", "OUT"],
    "calibrate": ["calibrate", "gyro", "board.yaml", "--emulate", "calibration", "--timeout",
                  "0.001", "--output", "OUT"],
}


@pytest.mark.parametrize("command", sorted(FAILING_WRITERS))
def test_a_failed_command_keeps_the_existing_output_and_its_inputs(
        command: str, work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = FAILING_WRITERS[command]
    out = "OUT.png" if "OUT.png" in argv else "OUT"
    (work / out).write_text("a good file from an earlier run\n")
    before = {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()}
    code = cli_main.main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "internal error" not in err
    after = {p.name: p.read_bytes() for p in work.iterdir() if p.is_file()}
    assert {n: b for n, b in after.items() if n in before} == before


def test_a_full_disk_is_a_one_line_error_and_keeps_the_old_output(work: Path) -> None:
    """EFBIG (the file size limit) stands in for ENOSPC: the same write error, no root needed,
    and nothing outside the scratch folder at risk."""
    big = work / "big.csv"
    big.write_text(IMU_HEADER + "".join(f"{i * 0.01:.2f},0,0,0,0,0,-9.81\n"
                                        for i in range(3000)))
    out = work / "o.csv"
    out.write_text("a good file from an earlier run\n")

    def limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))

    proc = subprocess.run([sys.executable, "-m", "imuhal.cli.main", "estimate", "madgwick",
                           str(big), "-o", str(out)], capture_output=True, text=True,
                          preexec_fn=limit, timeout=120, cwd=work,
                          env={**os.environ, "IMUHAL_DEBUG": ""})
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "o.csv: cannot be written" in lines[0], proc.stderr
    assert out.read_text() == "a good file from an earlier run\n"
    assert not list(work.glob(".o.csv.*"))  # no hidden temporary file left behind


def test_a_wav_through_a_link_writes_the_target_and_keeps_the_link(work: Path) -> None:
    real = work / "folder" / "tones.wav"
    real.write_bytes(b"old")
    link = work / "tones.wav"
    link.symlink_to(real)
    assert cli_main.main(["run", "--skip-calibration", "--duration", "1", "--quiet",
                          "--audio-wav", str(link)]) == 0
    assert link.is_symlink()
    assert real.read_bytes()[:4] == b"RIFF"


def test_a_wav_into_a_pipe_is_refused(work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = work / "tones.fifo"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # so the writer's open does not block
    try:
        code = cli_main.main(["run", "--skip-calibration", "--duration", "0.2", "--quiet",
                              "--audio-wav", str(fifo)])
    finally:
        os.close(reader)
    assert code == 2
    assert "--audio-wav" in capsys.readouterr().err
    assert fifo.is_fifo()


def test_a_run_log_in_another_frame_is_read_with_input_frame(work: Path) -> None:
    """A run log without frame suffixes takes --input-frame as the frame of its columns."""
    assert cli_main.main(["estimate", "madgwick", "log.csv", "-o", "o.csv",
                          "--input-frame", "enu"]) == 0
    assert len((work / "o.csv").read_text().splitlines()) > 10
