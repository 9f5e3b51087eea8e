"""``imuhal run --web`` and ``imuhal check-mounts`` from the command line."""

from __future__ import annotations

import pytest

from imuhal.cli.main import EXIT_ERROR, main


def test_run_with_web_serves_on_the_loopback_while_the_run_lasts(capsys):
    assert main(["run", "--web", "0", "--duration", "0.6", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "live view: http://127.0.0.1:" in err
    assert "reachable from the network" not in err


@pytest.mark.parametrize("spec", ["eighty", "localhost:99999"])
def test_run_with_a_bad_web_address_is_a_one_line_error(capsys, spec):
    assert main(["run", "--web", spec, "--duration", "0.1"]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--web" in err[0] and "PORT" in err[0]


def test_check_mounts_finds_a_chip_mounted_otherwise_than_its_profile_says(capsys):
    code = main(["check-mounts", "--physical-mount", "imu=-X+Y-Z"])
    out = capsys.readouterr().out
    assert code == 1
    assert "FAIL imu gyro: saw roll left" in out
    assert "ok   mag mag: saw nose up" in out
    assert "mounts WRONG" in out and "fix the mount of imu" in out


@pytest.mark.parametrize(("args", "words"), [
    (["--physical-mount", "imu"], "DEVICE=MOUNT"),
    (["--physical-mount", "imu=-X-Y-Z"], "reflection"),
    (["--physical-mount", "gps=+X+Y+Z"], "no enabled device"),
    (["--emulate", "thermal", "profiles/seed-paraglider-vario.yaml"], "--emulate bringup"),
])
def test_check_mounts_mistakes_are_one_line_errors(capsys, args, words):
    assert main(["check-mounts", *args]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert words in err[-1] and err[-1].startswith("imuhal: error:")
