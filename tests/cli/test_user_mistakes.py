"""Every user mistake is one line on stderr naming the input and the fix, exit 2: never a
traceback, never "internal error" (issue 9, item 17, and more found by trying the CLI as a new
user would)."""

from __future__ import annotations

import os
import shutil
import types
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.support import testchip

from imuhal import __version__
from imuhal.cli import main as cli_main
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry

DATA = Path(__file__).resolve().parent.parent / "data"
SEED_BOARD = DATA / "calibration" / "seed-board.yaml"
IMU_HEADER = "t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"
TRUTH_HEADER = "t_s,qw,qx,qy,qz,pn_m,pe_m,pd_m\n"


def imu_csv(path: Path, last_t: str | None = None, sep: str = ",") -> Path:
    rows = [f"{i * 0.01:.2f},0,0,0,0,0,-9.81\n" for i in range(20)]
    if last_t is not None:
        rows[-1] = f"{last_t},0,0,0,0,0,-9.81\n"
    path.write_text((IMU_HEADER + "".join(rows)).replace(",", sep))
    return path


def truth_csv(path: Path, last_t: str) -> Path:
    path.write_text(TRUTH_HEADER + "0.5,1,0,0,0,0,0,0\n1.0,1,0,0,0,0,0,0\n"
                    f"{last_t},1,0,0,0,0,0,0\n")
    return path


def board(tmp: Path) -> Path:
    copy = tmp / "board.yaml"
    shutil.copy(SEED_BOARD, copy)
    return copy


@dataclass
class Mistake:
    """argv built in a scratch folder, and the text the one-line error must contain."""

    build: Callable[[Path], list[str]]
    names: str


def _unwritable(tmp: Path) -> list[str]:
    folder = tmp / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    return ["run", "--duration", "1", "--quiet", "--output", str(folder / "x.csv")]


MISTAKES: dict[str, Mistake] = {
    "output folder missing": Mistake(
        lambda t: ["run", "--duration", "1", "--output", str(t / "nodir" / "x.csv")], "nodir"),
    "output folder not writable": Mistake(_unwritable, "locked"),
    "output on a file system that takes no files": Mistake(
        lambda t: ["run", "--duration", "1", "--output", "/sys/imuhal-log.csv"],
        "not writable"),
    "output is a directory": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv")), "-o", str(t)],
        "is a directory"),
    "duration nan": Mistake(lambda t: ["run", "--duration", "nan"], "--duration"),
    "duration inf": Mistake(lambda t: ["run", "--duration", "inf"], "--duration"),
    "duration negative": Mistake(lambda t: ["run", "--duration", "-5"], "--duration"),
    "duration 1e300": Mistake(lambda t: ["run", "--duration", "1e300"], "--duration"),
    "seed negative": Mistake(lambda t: ["run", "--duration", "1", "--seed", "-1"], "--seed"),
    "check-mounts seed negative": Mistake(lambda t: ["check-mounts", "--seed", "-1"], "--seed"),
    "rate 0": Mistake(lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv")), "-o",
                                 str(t / "o.csv"), "--rate", "0"], "--rate"),
    "rate nan": Mistake(lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv")), "-o",
                                   str(t / "o.csv"), "--rate", "nan"], "--rate"),
    "gate bounds reversed": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv")), "-o", str(t / "o.csv"),
                   "--set", "accel_gate_g=1.4,0.6"], "accel_gate_g"),
    "setting given a bool": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv")), "-o", str(t / "o.csv"),
                   "--set", "beta=true"], "beta"),
    "samples negative": Mistake(
        lambda t: ["calibrate", "gyro", str(board(t)), "--emulate", "calibration",
                   "--samples", "-3"], "--samples"),
    "field negative": Mistake(
        lambda t: ["calibrate", "mag", str(board(t)), "--emulate", "calibration",
                   "--field", "-5"], "--field"),
    "replay without a file": Mistake(
        lambda t: ["run", "--emulate", "replay", "--duration", "1"], "--replay-truth"),
    "replay truth ending at 1e300 s": Mistake(
        lambda t: ["run", "--emulate", "replay", "--replay-truth",
                   str(truth_csv(t / "truth.csv", "1e300"))], "truth.csv"),
    "replay of a sample log": Mistake(
        lambda t: ["run", "--emulate", "replay", "--replay-truth", str(imu_csv(t / "in.csv"))],
        "in.csv"),
    "input time of 1e300 s": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv", "1e300")), "-o",
                   str(t / "o.csv")], "in.csv"),
    "semicolon-separated input": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "in.csv", sep=";")), "-o",
                   str(t / "o.csv")], "semicolons"),
    "estimate over its own input": Mistake(
        lambda t: ["estimate", "madgwick", str(imu_csv(t / "same.csv")), "-o",
                   str(t / "same.csv")], "same.csv"),
    "run output over the profile": Mistake(
        lambda t: ["run", str(board(t)), "--emulate", "static", "--output", str(t / "board.yaml")],
        "board.yaml"),
    "two outputs one file": Mistake(
        lambda t: ["run", "--output", str(t / "a.csv"), "--truth", str(t / "a.csv")], "a.csv"),
    "samples without an output": Mistake(lambda t: ["run", "--samples"], "--output"),
    "calibrating a bundled profile": Mistake(
        lambda t: ["calibrate", "gyro", str(_bundled()), "--emulate", "calibration"],
        "Copy it first"),
    "unknown scenario": Mistake(lambda t: ["run", "--emulate", "nosuch"], "nosuch"),
    "missing profile": Mistake(lambda t: ["run", str(t / "nosuch.yaml")], "nosuch.yaml"),
    "missing input": Mistake(
        lambda t: ["estimate", "madgwick", str(t / "nosuch.csv"), "-o", str(t / "o.csv")],
        "nosuch.csv"),
    "emulator without clock": Mistake(
        lambda t: ["run", str(_tc3_board(t)), "--emulate", "static", "--duration", "1"],
        "noclock"),
}


def _bundled() -> Path:
    from imuhal.profile.bundled import default_profile_path

    return default_profile_path()


def _tc3_board(tmp: Path) -> Path:
    path = tmp / "tc3.yaml"
    path.write_text("schema_version: 1\nname: tc3-board\nbuses:\n"
                    "  i2c1: {kind: i2c, device: /dev/i2c-1}\n"
                    "devices:\n  acc: {driver: tc3, bus: i2c1, address: 0x19}\n")
    return path


class _NoClockEmulator(testchip.TC3Emulator):
    def __init__(self) -> None:  # an old plugin's constructor, without the clock keyword
        super().__init__(None)


_noclock_plugin = types.SimpleNamespace(
    imuhal_register_drivers=hookimpl(lambda register: register(testchip.TC3Driver)),
    imuhal_register_emulators=hookimpl(lambda register: register(_NoClockEmulator)),
)


@pytest.fixture
def with_noclock_plugin(monkeypatch: pytest.MonkeyPatch) -> None:
    """The installed plugins plus one whose emulator lacks the ``clock`` keyword."""
    monkeypatch.setattr(cli_main, "load_registry",
                        lambda: load_registry(extra=[("noclock", _noclock_plugin)]))


@pytest.mark.parametrize("case", sorted(MISTAKES))
def test_a_user_mistake_is_one_line_naming_the_input(
        case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        request: pytest.FixtureRequest) -> None:
    if case == "output folder not writable" and os.geteuid() == 0:
        pytest.skip("root writes into any folder")
    if case == "output on a file system that takes no files" and not Path("/sys/kernel").is_dir():
        pytest.skip("needs Linux sysfs")
    if case == "emulator without clock":
        request.getfixturevalue("with_noclock_plugin")
    mistake = MISTAKES[case]
    argv = mistake.build(tmp_path)
    try:
        code = cli_main.main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    err = capsys.readouterr().err
    # A run that got as far as opening its board announces it first; that line is no error.
    lines = [li for li in err.strip().splitlines() if not li.startswith(f"imuhal {__version__}:")]
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert len(lines) == 1, err
    assert "error:" in lines[0] and mistake.names in lines[0], lines[0]


def test_a_csv_with_a_byte_order_mark_is_read(tmp_path: Path) -> None:
    src = imu_csv(tmp_path / "plain.csv")
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + src.read_bytes())
    assert cli_main.main(["estimate", "madgwick", str(bom), "-o", str(tmp_path / "o.csv")]) == 0
    assert len((tmp_path / "o.csv").read_text().splitlines()) == 21


def test_a_truth_file_written_by_run_is_replayed(tmp_path: Path) -> None:
    truth = tmp_path / "truth.csv"
    # --skip-calibration: the calibration an emulated run makes first (seconds of CPU each,
    # tested in tests/calibration) is not what is checked here
    assert cli_main.main(["run", "--skip-calibration", "--duration", "2", "--quiet", "--output",
                          str(tmp_path / "log.csv"), "--truth", str(truth)]) == 0
    assert float(truth.read_text().splitlines()[-1].split(",")[0]) > 1.5
    out = tmp_path / "replayed.csv"
    assert cli_main.main(["run", "--emulate", "replay", "--replay-truth", str(truth),
                          "--skip-calibration", "--quiet", "--output", str(out)]) == 0
    rows = out.read_text().splitlines()
    assert len(rows) > 100
    # the replay runs to the end of the record, not past it
    assert float(rows[-1].split(",")[0]) <= float(truth.read_text().splitlines()[-1]
                                                  .split(",")[0])


def test_a_replay_asked_to_run_past_its_record_stops_at_its_end(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth = truth_csv(tmp_path / "truth.csv", "1.5")
    assert cli_main.main(["run", "--emulate", "replay", "--replay-truth", str(truth),
                          "--duration", "100", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "ends after" in err and "ran 1.5 s" in err


def test_a_profile_that_is_a_fifo_is_refused_without_waiting_for_a_writer(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``imuhal profile check`` on a FIFO used to block for ever opening it."""
    import threading

    fifo = tmp_path / "board.yaml"
    os.mkfifo(fifo)
    codes: list[int] = []
    worker = threading.Thread(target=lambda: codes.append(
        cli_main.main(["profile", "check", str(fifo)])), daemon=True)
    worker.start()
    worker.join(timeout=20)
    if worker.is_alive():  # unblock the reader so the thread ends, then fail
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        worker.join(timeout=5)
        pytest.fail("profile check blocked on a FIFO")
    out = capsys.readouterr().out
    assert codes == [2]
    assert "board.yaml: INVALID" in out and "not a regular file" in out
