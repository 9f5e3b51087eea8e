"""The Aerospace/NED, Android and Windows 8 formulations of the Freescale filters.

The estimators always take body-NED samples and return body -> NED quaternions; the
coordinate system only picks which of the reference's formulations runs inside (axes, the
accelerometer's sign, where gravity and north point). Noise-free synthetic data; tolerances
are round-off unless stated.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import quat_from_euler_deg, quat_multiply, quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, Sample
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal_filters.freescale.coords import (
    CoordinateSystem,
    accel_reading_g,
    ecompass,
    quat_body_to_ned,
    quat_from_matrix_fsl,
    to_sensor_vector,
)
from imuhal_filters.freescale.estimator import Freescale6DofEstimator, Freescale9DofEstimator

DATA = Path(__file__).parent.parent / "data" / "filters"
SYSTEMS = list(CoordinateSystem)
INCLINATION_DEG = 60.0
FIELD_NED_UT = 50.0 * np.array([math.cos(math.radians(INCLINATION_DEG)), 0.0,
                                math.sin(math.radians(INCLINATION_DEG))])


def _static_ticks(q_body_to_ned: np.ndarray, n: int,
                  inclination_deg: float = 0.0) -> list[list[Sample]]:
    """n noise-free 200 Hz ticks of a board held still at ``q_body_to_ned``, in a 50 uT field
    dipping by ``inclination_deg`` (0 by default: what the 9DOF filter assumes at start-up,
    so no inclination has to be learnt)."""
    r = quat_to_matrix(q_body_to_ned)
    force = tuple(r.T @ [0.0, 0.0, -STANDARD_GRAVITY_M_S2])
    dip = math.radians(inclination_deg)
    field = tuple(r.T @ (50.0 * np.array([math.cos(dip), 0.0, math.sin(dip)])))
    ticks = []
    for i in range(n):
        t = i * 5_000_000
        ticks.append([
            AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED, accel_m_s2=force),
            MagSample(t_ns=t, device="imu", frame=Frame.BODY_NED, mag_ut=field),
            GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED, gyro_rad_s=(0.0, 0.0, 0.0)),
        ])
    return ticks


def _run(est: Freescale9DofEstimator | Freescale6DofEstimator,
         ticks: list[list[Sample]]) -> list[AttitudeEstimate]:
    out: list[AttitudeEstimate] = []
    for tick in ticks:
        for s in tick:
            out += [e for e in est.process(s) if isinstance(e, AttitudeEstimate)]
    return out


def _angle_deg(a: tuple[float, ...] | np.ndarray, b: tuple[float, ...] | np.ndarray) -> float:
    d = quat_multiply(np.asarray(a) * [1, -1, -1, -1], np.asarray(b))
    return math.degrees(2.0 * math.atan2(float(np.linalg.norm(d[1:])), abs(float(d[0]))))


@pytest.mark.parametrize("cs", SYSTEMS)
@pytest.mark.parametrize("cls", [Freescale9DofEstimator, Freescale6DofEstimator])
def test_level_static_board_reads_zero_tilt_in_every_coordinate_system(
        cls: type[Freescale9DofEstimator], cs: CoordinateSystem) -> None:
    est = cls({"coordinate_system": cs})
    for step in _run(est, _static_ticks(quat_from_euler_deg(0.0, 0.0, 30.0), 400)):
        native = step.diagnostics["euler_deg"]
        assert native["phi"] == pytest.approx(0.0, abs=1e-6)
        assert native["theta"] == pytest.approx(0.0, abs=1e-6)
        assert native["chi"] == pytest.approx(0.0, abs=1e-4)  # acos near 1 loses digits
        roll, pitch, _ = step.roll_pitch_yaw_deg
        assert roll == pytest.approx(0.0, abs=1e-6) and pitch == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(("cs", "psi", "rho"), [(CoordinateSystem.NED, 30.0, 30.0),
                                                (CoordinateSystem.ANDROID, 30.0, 30.0),
                                                (CoordinateSystem.WIN8, 330.0, 30.0)])
def test_level_board_heading_in_each_systems_own_yaw_convention(
        cs: CoordinateSystem, psi: float, rho: float) -> None:
    """NED and Android yaw run clockwise from north; Windows 8 yaw anticlockwise, with the
    compass heading rho clockwise in all three."""
    last = _run(Freescale9DofEstimator({"coordinate_system": cs}),
                _static_ticks(quat_from_euler_deg(0.0, 0.0, 30.0), 400))[-1]
    assert last.diagnostics["euler_deg"]["psi"] == pytest.approx(psi, abs=1e-6)
    assert last.diagnostics["euler_deg"]["rho"] == pytest.approx(rho, abs=1e-6)
    assert last.roll_pitch_yaw_deg[2] == pytest.approx(30.0, abs=1e-6)


@pytest.mark.parametrize("cs", SYSTEMS)
def test_ecompass_recovers_a_known_attitude_and_the_inclination(cs: CoordinateSystem) -> None:
    q_true = quat_from_euler_deg(-3.0, 5.0, 20.0)
    r = quat_to_matrix(q_true)
    accel = accel_reading_g(cs, r.T @ [0.0, 0.0, -1.0])
    field = to_sensor_vector(cs, r.T @ FIELD_NED_UT)
    r_fsl, inclination = ecompass(cs, accel, field)
    q = quat_body_to_ned(cs, quat_from_matrix_fsl(r_fsl))
    assert _angle_deg(q, q_true) < 1e-9
    assert inclination == pytest.approx(INCLINATION_DEG, abs=1e-9)


def _dataset_a_ticks(n: int) -> list[list[Sample]]:
    c = np.loadtxt(DATA / "fsl_imu_A_counts.csv", delimiter=",", skiprows=2)[:n]
    ticks = []
    for row in c:
        t = int(row[0]) * 5_000_000
        ticks.append([
            AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                        accel_m_s2=tuple(-row[1:4] / 2048.0 * STANDARD_GRAVITY_M_S2)),
            MagSample(t_ns=t, device="imu", frame=Frame.BODY_NED, mag_ut=tuple(row[7:10] / 16)),
            GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                       gyro_rad_s=tuple(np.radians(row[4:7] / 128.0))),
        ])
    return ticks


def test_9dof_gives_the_same_body_to_ned_attitude_in_all_three_systems() -> None:
    """The formulations are the same filter in swapped axes: identical up to round-off."""
    ticks = _dataset_a_ticks(2000)
    runs = {cs: _run(Freescale9DofEstimator({"coordinate_system": cs}), ticks)
            for cs in SYSTEMS}
    for cs in (CoordinateSystem.ANDROID, CoordinateSystem.WIN8):
        worst = max(_angle_deg(a.q_body_to_ned, b.q_body_to_ned)
                    for a, b in zip(runs[cs], runs[CoordinateSystem.NED], strict=True))
        assert worst < 1e-6, cs
        incl = [e.diagnostics["inclination_deg"] for e in runs[cs]]
        ref = [e.diagnostics["inclination_deg"] for e in runs[CoordinateSystem.NED]]
        np.testing.assert_allclose(incl, ref, atol=1e-6)


def test_6dof_tilt_is_the_same_in_all_three_systems() -> None:
    """Only the arbitrary start-up heading differs (Android fixes a different axis)."""
    ticks = _dataset_a_ticks(2000)
    runs = {cs: _run(Freescale6DofEstimator({"coordinate_system": cs}), ticks)
            for cs in SYSTEMS}
    for cs in (CoordinateSystem.ANDROID, CoordinateSystem.WIN8):
        for a, b in zip(runs[cs], runs[CoordinateSystem.NED], strict=True):
            down_a = quat_to_matrix(a.q_body_to_ned)[2]
            down_b = quat_to_matrix(b.q_body_to_ned)[2]
            assert np.linalg.norm(down_a - down_b) < 1e-8  # rad: the gravity direction
    # Windows 8 also fixes the forward axis' heading at start-up, as NED does
    worst = max(_angle_deg(a.q_body_to_ned, b.q_body_to_ned)
                for a, b in zip(runs[CoordinateSystem.WIN8], runs[CoordinateSystem.NED],
                                strict=True))
    assert worst < 1e-6


@pytest.mark.parametrize("cs", list(CoordinateSystem))
def test_the_array_form_of_body_to_ned_equals_the_row_form(cs: CoordinateSystem) -> None:
    from imuhal_filters.freescale.batch import quats_body_to_ned

    q = np.random.default_rng(5).normal(size=(50, 4))
    q[3] = 0.0  # corrupt: identity, as the row form gives
    rows = np.array([quat_body_to_ned(cs, r) for r in q])
    assert np.allclose(quats_body_to_ned(cs, q), rows, rtol=0, atol=1e-15)
