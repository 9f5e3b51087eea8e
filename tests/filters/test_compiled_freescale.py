"""The compiled Freescale Kalman steps (``fast`` extra) give what the Python steps give.

On conformance data set A in the three coordinate systems, 9 and 6 DOF, in the reference
(build 422) and the default configuration (rest detection included), with a magnetic
disturbance that jams the magnetometer and a hard manoeuvre for the soft gate, every output
of ``run_9dof`` and ``run_6dof`` equals the pure-Python run (the reference) to 1e-12, on
numba's JIT and on the AOT extension; so do a board with still phases (rest detection's
offset measurement) and the magnetometer gate's reacquire. A settings class with a field the
kernel does not know runs in Python.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imuhal_filters.freescale import batch
from imuhal_filters.freescale.batch import BatchResult, run_6dof, run_9dof
from imuhal_filters.freescale.settings import Freescale6DofSettings, Freescale9DofSettings

# every test runs on numba's JIT and on the AOT extension (each skipped where unavailable)
pytestmark = pytest.mark.usefixtures("compiled_backend")

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"


def _inputs(system: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    name = "fsl_imu_A_counts.csv" if system == "ned" else f"fsl_imu_A_{system}_counts.csv"
    c = np.loadtxt(DATA / name, delimiter=",", skiprows=2)
    acc, gyr, mag = c[:, 1:4] / 2048.0, c[:, 4:7] / 128.0, c[:, 7:10] / 16.0
    mag[1200:1400] += 400.0   # a magnet next to the board: the 9DOF filter flags jamming
    acc[2000:2040] *= 2.5      # a pull-up: the soft gate's noise factor
    return acc, gyr, mag


def _run(system: str, dof: str, preset: str | None, monkeypatch: pytest.MonkeyPatch,
         no_jit: bool) -> BatchResult:
    acc, gyr, mag = _inputs(system)
    extra: dict[str, object] = {} if preset is None else {"preset": preset}
    if no_jit:
        monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    try:
        if dof == "9dof":
            return run_9dof(acc, gyr, mag, Freescale9DofSettings(coordinate_system=system,
                                                                 **extra))
        return run_6dof(acc, gyr, Freescale6DofSettings(coordinate_system=system, **extra))
    finally:
        monkeypatch.delenv("IMUHAL_NO_JIT", raising=False)


def _same(a: BatchResult, b: BatchResult) -> None:
    assert np.array_equal(a.row, b.row)
    assert np.array_equal(a.valid, b.valid)
    assert np.array_equal(a.mag_jamming, b.mag_jamming)
    for name in ("q_sensor_to_global", "q_body_to_ned", "euler_deg", "gyro_offset_dps",
                 "inclination_deg"):
        assert np.allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-12), name


@pytest.mark.parametrize("system", ["ned", "android", "win8"])
@pytest.mark.parametrize("dof", ["9dof", "6dof"])
@pytest.mark.parametrize("preset", ["reference", None], ids=["reference", "defaults"])
def test_compiled_freescale_batch_equals_pure_python_on_data_set_a(
        system: str, dof: str, preset: str | None, monkeypatch: pytest.MonkeyPatch) -> None:
    compiled = _run(system, dof, preset, monkeypatch, no_jit=False)
    _same(compiled, _run(system, dof, preset, monkeypatch, no_jit=True))
    if dof == "9dof" and system == "ned":
        assert compiled.mag_jamming.any()  # the disturbance was seen, not missed


def test_the_full_innovation_inverse_runs_compiled_like_python(
        monkeypatch: pytest.MonkeyPatch) -> None:
    acc, gyr, mag = _inputs("ned")
    s = Freescale9DofSettings(full_innovation_inverse=True)
    compiled = run_9dof(acc, gyr, mag, s)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    _same(compiled, run_9dof(acc, gyr, mag, s))


def test_settings_the_kernel_does_not_know_stay_in_python(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A behaviour added to the filter with its own setting is never wrongly compiled."""
    real, calls = batch._compiled_steps, []

    def spy(*args: object) -> object:
        calls.append(1)
        return real(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(batch, "_compiled_steps", spy)

    class Extended(Freescale6DofSettings):
        new_behaviour: bool = True

    acc, gyr, _ = _inputs("ned")
    run_6dof(acc[:400], gyr[:400], Extended())
    assert not calls
    run_6dof(acc[:400], gyr[:400], Freescale6DofSettings())
    assert calls  # the settings it knows (rest detection, the default, included) run compiled


def _still_then_turning_inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A level board heading north at 200 Hz (seeded noise) with a gyro offset of 1.5, -1,
    0.5 deg/s: still for 6 s, turning about the vertical at 40 deg/s for 3 s, still again
    for 6 s. The still phases are where rest detection measures the offset."""
    n = 15 * 200
    rng = np.random.default_rng(5)
    acc = np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.002, (n, 3))
    gyr = np.array([1.5, -1.0, 0.5]) + rng.normal(0.0, 0.1, (n, 3))
    gyr[1200:1800, 2] += 40.0
    yaw = np.radians(np.cumsum(np.where(np.arange(n) >= 1200, 1.0, 0.0)
                               * np.where(np.arange(n) < 1800, 40.0, 0.0)) / 200.0)
    field = np.array([20.0, 0.0, 44.0])
    mag = np.stack([field[0] * np.cos(yaw), -field[0] * np.sin(yaw),
                    np.full(n, field[2])], axis=1) + rng.normal(0.0, 0.3, (n, 3))
    return acc, gyr, mag


@pytest.mark.parametrize("dof", ["9dof", "6dof"])
def test_rest_detection_runs_compiled_like_python(
        dof: str, monkeypatch: pytest.MonkeyPatch) -> None:
    acc, gyr, mag = _still_then_turning_inputs()

    def run(**extra: object) -> BatchResult:
        if dof == "9dof":
            return run_9dof(acc, gyr, mag, Freescale9DofSettings(field_strength_ut=48.4,
                                                                 **extra))
        return run_6dof(acc, gyr, Freescale6DofSettings(**extra))

    compiled = run()
    without_rest = run(rest_detection=False)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    _same(compiled, run())
    # the still phases were fused as rests: the offset estimate is the gyro's own offset
    assert np.allclose(compiled.gyro_offset_dps[-1], [1.5, -1.0, 0.5], atol=0.05)
    assert not np.allclose(compiled.gyro_offset_dps, without_rest.gyro_offset_dps, atol=0.05)


def _heading_glitch_inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A level board heading north at 200 Hz (seeded noise) whose gyro reads 60 deg/s about
    the vertical for 1 s at 3 s that did not happen: the heading ends 60 deg off, beyond the
    magnetometer gate, until its reacquire rule turns it back."""
    n = 16 * 200
    rng = np.random.default_rng(3)
    acc = np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.002, (n, 3))
    gyr = rng.normal(0.0, 0.1, (n, 3))
    gyr[600:800, 2] += 60.0
    mag = np.array([20.0, 0.0, 44.0]) + rng.normal(0.0, 0.3, (n, 3))
    return acc, gyr, mag


def test_the_magnetometer_gates_reacquire_runs_compiled_like_python(
        monkeypatch: pytest.MonkeyPatch) -> None:
    acc, gyr, mag = _heading_glitch_inputs()
    s = Freescale9DofSettings(rest_detection=False, field_strength_ut=48.4)
    compiled = run_9dof(acc, gyr, mag, s)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    python = run_9dof(acc, gyr, mag, s)
    _same(compiled, python)
    yaw = np.minimum(compiled.euler_deg[:, 2], 360.0 - compiled.euler_deg[:, 2])
    t_s = compiled.row / 200.0
    assert yaw[(t_s > 4.0) & (t_s < 6.0)].min() > 45.0  # the glitch's heading error held
    assert yaw[t_s > 10.0].max() < 2.0  # and reacquired
