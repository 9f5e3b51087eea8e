"""What the emulated board hands each chip at a poll: its truth, light for a barometer."""

from __future__ import annotations

from pathlib import Path

from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

SEED = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"


def test_a_barometer_gets_pressure_and_temperature_without_the_attitude() -> None:
    registry = load_registry()
    pipeline = open_emulated(load_profile(SEED, registry), registry, sensor_errors=False)
    board = EmulatedBoard.of(pipeline)
    board.update(1_234_567_000, "baro")  # polled alone at this instant
    board.update(1_234_567_000, "imu")
    truth = board.truth_at(1_234_567_000)
    baro, imu = board.emulators["baro"].physics, board.emulators["imu"].physics
    assert baro.specific_force_m_s2 is None and baro.magnetic_field_ut is None
    assert (baro.pressure_pa, baro.temperature_degc) == (truth.pressure_pa,
                                                         truth.temperature_degc)
    assert baro.position_ned_m == tuple(truth.position_ned_m.tolist())
    # The IMU, mounted -Y-X-Z, sees the full truth in its own axes.
    fx, fy, fz = truth.specific_force_body_m_s2.tolist()
    assert imu.specific_force_m_s2 == (-fy, -fx, -fz)
    assert board.truth is not None and board.truth.t_s == truth.t_s
