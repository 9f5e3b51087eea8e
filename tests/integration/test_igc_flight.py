"""The seed GPS vario's IGC log of an emulated `thermal` flight, read by an independent
strict reader (tests/support/igc_reader.py, from the FAI specification, not aerofiles):
every B record there, pressure altitude on the truth's ISA pressure altitude, position within
the receiver's error; the G record verifies, and a run killed with SIGKILL at random moments
leaves a file that verifies up to its last record.

The suite flies 60 s and kills 4 runs; `pytest -m long` flies the issue's 600 s and kills
30 runs (tests marked ``long``)."""

from __future__ import annotations

import math
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("aerofiles", reason="the igc extra (aerofiles) is not installed")
pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from tests.support.igc_reader import parse_igc
from tests.support.noise import noise_only_specs

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.flight.igc import IgcCheckError, IgcSink, verify_igc

EARTH_A_M = 6_378_137.0
EARTH_E2 = 6.694_379_990_14e-3
IGC_ROUNDING_M = 0.001 / 60 * math.pi / 180 * EARTH_A_M  # 0.001 minute of latitude: 1.85 m


def _fly(tmp_path: Path, duration_s: float) -> tuple[Path, list[tuple[float, float, float]],
                                                      float, float]:
    """Fly the profile with datasheet noise only (the MS5611's absolute error of up to
    1.5 hPa is the sensor's, not the log's); return the log, the truth (t_s, pressure
    altitude, NED north/east) per whole second, and the receiver's origin."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    path = tmp_path / "flight.igc"
    sink = IgcSink({"path": str(path), "device_drivers": {"gps": "gnss", "baro": "ms5611"}})
    with open_emulated(profile, registry, scenario="thermal", seed=1,
                       error_specs=noise_only_specs(profile, registry)) as pipeline:
        gps = pipeline.board.emulators["gps"]
        utc0 = gps.model.utc_start.timestamp()
        pipeline.run(duration_s, [sink])
        scenario = pipeline.board.scenario
        truth = {}
        for t in range(math.ceil(duration_s) + 1):
            state = scenario.truth(float(t))
            truth[t] = (altitude_m_from_pressure(state.pressure_pa),
                        float(state.position_ned_m[0]), float(state.position_ned_m[1]))
    return path, truth, utc0, (gps.model.origin_latitude_deg, gps.model.origin_longitude_deg,
                               gps.model.horizontal_accuracy_m)


def _check_flight(tmp_path: Path, duration_s: float) -> None:
    path, truth, utc0, (lat0, lon0, hacc) = _fly(tmp_path, duration_s)
    igc = parse_igc(path.read_bytes())
    assert verify_igc(path).b_records == len(igc.fixes)
    day0 = utc0 % 86400
    times = [f.seconds_of_day - day0 for f in igc.fixes]
    # the receiver's first fix comes after 1 s (time to first fix); one B record a second
    # from then on, none missing
    assert times == list(range(1, int(duration_s) + 1))
    s = math.sin(math.radians(lat0))
    w = math.sqrt(1 - EARTH_E2 * s * s)
    r_meridian, r_normal = EARTH_A_M * (1 - EARTH_E2) / w**3, EARTH_A_M / w
    worst_alt = worst_pos = 0.0
    for f, t in zip(igc.fixes, times, strict=True):
        pressure_alt, north, east = truth[t]
        assert f.valid and f.extensions["FXA"] == f"{math.ceil(hacc):03d}"
        worst_alt = max(worst_alt, abs(f.pressure_altitude_m - pressure_alt))
        dn = math.radians(f.latitude_deg - lat0) * r_meridian - north
        de = math.radians(f.longitude_deg - lon0) * r_normal * math.cos(math.radians(lat0)) \
            - east
        worst_pos = max(worst_pos, math.hypot(dn, de))
    # 0.5 m of rounding to whole metres, the MS5611's noise (~0.1 m at OSR 4096)
    assert worst_alt < 1.0
    # the receiver's error: 4 x hAcc (its 1-sigma horizontal error), plus the record's
    # rounding to 0.001 minute
    assert worst_pos < 4 * hacc + IGC_ROUNDING_M
    print(f"{duration_s:.0f} s: {len(igc.fixes)} B records; worst pressure altitude error "
          f"{worst_alt:.2f} m, worst horizontal error {worst_pos:.2f} m", file=sys.stderr)


@pytest.mark.slow
def test_a_60_s_thermal_flight_logs_every_second_on_the_truth(tmp_path: Path) -> None:
    _check_flight(tmp_path, 60.0)


@pytest.mark.long
def test_a_600_s_thermal_flight_logs_every_second_on_the_truth(tmp_path: Path) -> None:
    _check_flight(tmp_path, 600.0)


def _kill_runs(tmp_path: Path, kills: int, duration_s: int) -> list[int]:
    """Start `imuhal run --igc`, SIGKILL it at a random moment once its log exists, and
    verify what is left; returns the B records each killed file held. Without the emulated
    calibration a run makes first (seconds of CPU per run, before the log is opened; tested in
    tests/calibration/test_calibration_as_user.py): what is checked is the killed log."""
    rng = random.Random(28)
    held = []
    for k in range(kills):
        path = tmp_path / f"k{k}.igc"
        partial = tmp_path / f"k{k}.igc.partial"
        proc = subprocess.Popen(
            [sys.executable, "-m", "imuhal.cli.main", "run", "--quiet", "--emulate", "thermal",
             "--skip-calibration", str(bundled_profiles()["seed-gps-vario.yaml"]),
             "--duration", str(duration_s),
             "--igc", str(path)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 60
        while not partial.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 2.0))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        left = partial if partial.exists() else path  # a run that ended first committed
        if not left.read_bytes():
            # killed between the file's creation and its header's write (back to back; the
            # header is made before): nothing was logged, and verify says so
            with pytest.raises(IgcCheckError, match="is empty"):
                verify_igc(left)
            held.append(0)
            left.unlink()
            continue
        check = verify_igc(left)
        held.append(check.b_records)
        assert len(parse_igc(left.read_bytes()).fixes) == check.b_records
        for p in (path, partial):
            p.unlink(missing_ok=True)
    return held


@pytest.mark.slow
def test_a_run_killed_at_random_moments_leaves_a_log_that_verifies(tmp_path: Path) -> None:
    held = _kill_runs(tmp_path, 4, 60)
    assert len(set(held)) > 1  # killed at different points of the flight


@pytest.mark.long
def test_thirty_kills_leave_logs_that_verify(tmp_path: Path) -> None:
    held = _kill_runs(tmp_path, 30, 120)
    assert len(set(held)) > 10
    print(f"B records held by the 30 killed logs: {sorted(held)}", file=sys.stderr)
