"""`imuhal run` with flight-app outputs and audio; `imuhal plugins` lists the sinks."""

from __future__ import annotations

import csv
import math
import wave
from pathlib import Path

import pytest

from imuhal.cli.main import main
from imuhal.profile.bundled import bundled_profiles

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")

GPS_VARIO = str(bundled_profiles()["seed-gps-vario.yaml"])


def test_plugins_lists_the_flight_sinks(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    sinks = out[out.index("sinks:"):]
    assert "nmea" in sinks and "vario-audio" in sinks
    assert "gnss" in out[:out.index("emulators:")]


def test_the_gps_vario_runs_emulated_with_nmea_audio_and_gps_rows_in_the_csv(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, wav = tmp_path / "run.csv", tmp_path / "run.wav"
    assert main(["run", GPS_VARIO, "--emulate", "thermal", "--duration", "6", "--quiet",
                 "--samples", "--output", str(out), "--nmea", "tcp:0", "--nmea",
                 f"pty:{tmp_path / 'vario'}", "--audio-wav", str(wav)]) == 0
    err = capsys.readouterr().err
    assert "nmea: TCP server 127.0.0.1:" in err
    assert f"open {tmp_path / 'vario'} in the flight app" in err
    rows = list(csv.DictReader(out.open()))
    fixes = [r for r in rows if r["kind"] == "position" and r["flags"] == "0"]
    vels = [r for r in rows if r["kind"] == "velocity"]
    assert len(fixes) > 15 and len(vels) > 15
    assert all(46 < float(r["latitude_deg"]) < 47.2 and r["fix_type"] == "3" for r in fixes)
    assert all(math.isfinite(float(r["vn_m_s"])) for r in vels)
    with wave.open(str(wav), "rb") as w:
        assert w.getnframes() > 4 * w.getframerate()
    assert not (tmp_path / "vario").exists()


@pytest.mark.parametrize(("option", "message"), [
    ("udp:9", "unknown output"),
    ("serial:/dev/imuhal-missing@9600", "cannot open /dev/imuhal-missing"),
    ("tcp:99999", "0-65535"),
])
def test_a_wrong_nmea_output_is_one_line_and_exit_2(option: str, message: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    # --skip-calibration here and below: the mistake is found after the calibration an
    # emulated run makes first (seconds of CPU; tests/calibration tests it)
    assert main(["run", GPS_VARIO, "--emulate", "thermal", "--skip-calibration", "--duration",
                 "1", "--quiet", "--nmea", option]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("imuhal: error: --nmea") and message in err[-1]


def test_unknown_sentences_are_named(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", GPS_VARIO, "--emulate", "thermal", "--skip-calibration", "--duration",
                 "1", "--quiet", "--nmea", "tcp:0", "--nmea-sentences", "LK8EX1,FOO"]) == 2
    assert "FOO" in capsys.readouterr().err


def _has_sound_device() -> bool:
    try:
        import sounddevice
    except (ImportError, OSError):
        return False
    try:
        return any(d["max_output_channels"] > 0 for d in sounddevice.query_devices())
    except Exception:
        return False


@pytest.mark.skipif(_has_sound_device(), reason="a sound device exists: --audio would play")
def test_live_audio_without_a_sound_device_is_one_line_and_exit_2(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", GPS_VARIO, "--emulate", "thermal", "--skip-calibration", "--duration",
                 "1", "--quiet", "--audio"]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("imuhal: error: --audio") and "--audio-wav" in last
