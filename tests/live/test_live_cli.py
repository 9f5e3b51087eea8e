"""``imuhal run --web`` and ``imuhal check-mounts`` from the command line."""

from __future__ import annotations

import json
import subprocess
import sys
import time
import urllib.request

import pytest

from imuhal.cli.main import EXIT_ERROR, main


def test_run_with_web_serves_the_running_board_on_the_loopback():
    """``imuhal run --web 0`` as a user starts it: the printed address answers with the
    live state of the default emulated board while the run lasts."""
    proc = subprocess.Popen([sys.executable, "-m", "imuhal.cli.main", "run", "--web", "0",
                             "--duration", "2", "--quiet"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        url = None
        for line in proc.stderr:
            if line.startswith("live view: "):
                url = line.split()[2]
                break
        assert url is not None and url.startswith("http://127.0.0.1:")
        assert "reachable from the network" not in line
        time.sleep(1.0)
        with urllib.request.urlopen(url + "state.json", timeout=5) as resp:
            state = json.load(resp)
    finally:
        proc.communicate(timeout=30)
    assert proc.returncode == 0
    assert state["board"] == {"profile": "seed-paraglider-vario", "scenario": "thermal",
                              "emulated": True}
    assert state["t_s"] > 0.5 and "ahrs" in state["attitude"]


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
    assert 'imu: its gyro moved as a chip mounted "-X+Y-Z" would' in out


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


def test_the_guided_check_records_each_motion_after_its_prompt(plugins, seed_board, capsys):
    """The interactive path of ``imuhal check-mounts`` on hardware, run against an emulated
    board paced in real time whose user (the bringup scenario, compressed) performs each
    motion right after its prompt is answered."""
    from imuhal.cli.check_mounts_cmd import guided_check
    from imuhal.emulation import open_emulated

    params = {"settle_s": 0.6, "window_s": 1.0, "move_s": 0.4, "return_s": 0.5}
    with open_emulated(seed_board, plugins, scenario="bringup", scenario_params=params,
                       realtime=True, seed=6) as pipeline:
        phases = {p.name: p for p in pipeline.board.scenario.phases()}
        prompts = []

        def user(prompt: str) -> str:
            prompts.append(prompt)
            for key, phase in phases.items():
                if key in ("nose-up", "roll-right", "turn-right") and \
                        phase.name.replace("-", " ") in prompt.replace("tilt ", ""):
                    while pipeline.clock.now_ns() < phase.start_s * 1e9:
                        time.sleep(0.005)
            return ""

        verdicts = guided_check(pipeline, window_s=1.0, ask=user)
    assert len(prompts) == 6  # level; each motion, and back to level after the first two
    for key in ("nose-up", "roll-right", "turn-right"):
        gyro = next(v for v in verdicts[key] if v.channel.value == "gyro")
        assert gyro.ok is True, (key, gyro.message)
    assert "ok   imu gyro: saw turn right" in capsys.readouterr().out
