"""Every bundled profile, turned about each body axis, reads the truth in the right frames.

The expected chip-to-body rotations are written here from the documents, never read from the
profiles or from imuhal's mount parser, so a wrong mount, a wrong rotation in the pipeline or
a wrong composition with ``board_to_body`` cannot cancel between the emulated board (which
rotates the truth into each chip's frame) and the pipeline (which rotates samples back):

- raw samples (``calibrated=False``, the chip's own frame) must equal the truth rotated into
  the chip by the matrices below: this pins what the emulated board feeds each chip;
- body samples (the pipeline's output) must equal the truth in the NED body frame: this pins
  the pipeline's rotation.

Bound: RMS vector error at most 10 % of the RMS true magnitude over the whole flight (ideal
chips; what remains is quantisation and the up-to-one-sample lag between a chip's
measurement and the time stamp it is compared at). Any axis swap or sign error gives 50 % or
more, since the flight turns a full circle about each axis.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np
import pytest
from tests.support.noise import noise_only_specs

from imuhal.core.samples import Quantity, VectorSample
from imuhal.emulation import open_emulated
from imuhal.emulation.mounting import chip_rotations
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

# --- chip-to-body rotations from the documents (v_body = M @ v_chip) -------------------------

# Seed document (Nair 2016-09-20, "Sensor Axis Mapping for AHRS"), MAX2110x and HMC5883L with
# parallel axes, Z up out of the board:
#   gyro[x]NED = -gyro[y], gyro[y]NED = -gyro[x], gyro[z]NED = -gyro[z]; same for mag.
SEED_GYRO_MAG = np.array([[0, -1, 0],
                          [-1, 0, 0],
                          [0, 0, -1]], dtype=float)
#   acc[x]NED = acc[y], acc[y]NED = acc[x], acc[z]NED = acc[z], where the seed's accelerometer
#   value is +1 g along the axis that points *down* (the seed: "board D axis points straight
#   down and the accelerometer Z axis value is +1g"). imuhal's accelerometer truth is
#   specific force, +1 g along the axis that points *up*: the opposite sign.
SEED_ACCEL_GRAVITY_CONVENTION = np.array([[0, 1, 0],
                                          [1, 0, 0],
                                          [0, 0, 1]], dtype=float)
SEED_ACCEL = -SEED_ACCEL_GRAVITY_CONVENTION

# GY-91 module: printed axes X forward, Y left, Z up are the MPU-9250's axes, so NED body
# (x forward, y right, z down) = (x, -y, -z) of the MPU-9250.
GY91_MPU = np.diag([1.0, -1.0, -1.0])
# AK8963 inside the MPU-9250 (MPU-9250 register map / Linux inv_mpu_magn.c): in MPU axes a
# magnetometer reading m is (m_y, m_x, -m_z).
AK8963_TO_MPU = np.array([[0, 1, 0],
                          [1, 0, 0],
                          [0, 0, -1]], dtype=float)
GY91_MAG = GY91_MPU @ AK8963_TO_MPU

# Seed author's GPS vario (profiles/seed-gps-vario.yaml states the assumption): the IMU module
# lies flat, printed X forward, Y left, Z up; body (forward, right, down) is (x, -y, -z) of
# the MPU-9250, and its AK8963 reads (m_y, m_x, -m_z) in MPU axes as above.
GPS_VARIO_MPU = np.array([[1, 0, 0],
                          [0, -1, 0],
                          [0, 0, -1]], dtype=float)
GPS_VARIO_MAG = GPS_VARIO_MPU @ AK8963_TO_MPU

EXPECTED: dict[str, dict[tuple[str, Quantity], np.ndarray]] = {
    "seed-paraglider-vario.yaml": {
        ("imu", Quantity.GYRO): SEED_GYRO_MAG, ("imu", Quantity.ACCEL): SEED_ACCEL,
        ("mag", Quantity.MAG): SEED_GYRO_MAG},
    "seed-rc-vario.yaml": {
        ("imu", Quantity.GYRO): SEED_GYRO_MAG, ("imu", Quantity.ACCEL): SEED_ACCEL,
        ("mag", Quantity.MAG): SEED_GYRO_MAG},
    "seed-gps-vario.yaml": {
        ("imu", Quantity.GYRO): GPS_VARIO_MPU, ("imu", Quantity.ACCEL): GPS_VARIO_MPU,
        ("mag", Quantity.MAG): GPS_VARIO_MAG},
    "gy91.yaml": {
        ("imu", Quantity.GYRO): GY91_MPU, ("imu", Quantity.ACCEL): GY91_MPU,
        ("mag", Quantity.MAG): GY91_MAG},
}

# A board mounted in the airframe turned 90 degrees right (yaw): board x points along body y
# (right), board y along body -x (back), board z along body z. Written as columns: the
# body-frame direction of each board axis.
BOARD_YAWED = np.column_stack([(0, 1, 0), (-1, 0, 0), (0, 0, 1)]).astype(float)
BOARD_YAWED_SPEC = "-Y+X+Z"
"""The same rotation as a profile writes it: body x = board -Y, y = board +X, z = +Z."""

TUMBLE = {"axes": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "rotation_s": 1.5,
          "ramp_s": 0.4, "hold_s": 1.2, "free_tumble_s": 0.0}
"""One full turn about body x, then y, then z (the ``tumble`` scenario, shortened); the first
hold is long enough for the profiles' startup gyro-offset measurement (100 samples), also
after a GNSS receiver's probe and configuration (about 0.4 s of the hold)."""
FLIGHT_S = 1.2 + 3 * (1.5 + 1.2)
BOUND = 0.10
TRUTH_CHANNEL = {Quantity.ACCEL: "specific_force_body_m_s2",
                 Quantity.GYRO: "angular_rate_body_rad_s",
                 Quantity.MAG: "magnetic_field_body_ut"}


@pytest.fixture(scope="module")
def installed() -> Registry:
    return load_registry()


def _fly(profile: BoardProfile, registry: Registry, *, calibrated: bool
         ) -> dict[tuple[str, Quantity], list[VectorSample]]:
    out: dict[tuple[str, Quantity], list[VectorSample]] = defaultdict(list)
    # chips with their datasheet white noise only (no bias, scale or iron errors): an ideal
    # chip holding still repeats one raw frame, which its driver flags FROZEN
    with open_emulated(profile, registry, scenario="tumble", scenario_params=TUMBLE, seed=3,
                       calibrated=calibrated,
                       error_specs=noise_only_specs(profile, registry)) as p:
        for e in p.events(FLIGHT_S):
            if isinstance(e, VectorSample) and e.valid:
                out[(e.device, e.channel)].append(e)
    return out


def _relative_rms_error(samples: list[VectorSample], registry: Registry,
                        body_to_frame: np.ndarray, channel: Quantity) -> float:
    scenario = registry.scenarios.get("tumble")(TUMBLE, seed=3)
    got = np.array([s.vector for s in samples], dtype=float)
    truth = np.array([getattr(scenario.truth(s.t_ns / 1e9), TRUTH_CHANNEL[channel])
                      for s in samples], dtype=float)
    want = truth @ body_to_frame.T
    err = np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1)))
    return float(err / np.sqrt(np.mean(np.sum(want ** 2, axis=1))))


def _check(profile: BoardProfile, registry: Registry, expected: dict[Any, np.ndarray],
           board_to_body: np.ndarray) -> None:
    raw = _fly(profile, registry, calibrated=False)
    body = _fly(profile, registry, calibrated=True)
    for (device, channel), chip_to_body in expected.items():
        m = board_to_body @ chip_to_body
        assert len(raw[(device, channel)]) > 50 and len(body[(device, channel)]) > 50
        in_chip = _relative_rms_error(raw[(device, channel)], registry, m.T, channel)
        assert in_chip <= BOUND, f"{device} {channel.value} in its chip frame: {in_chip:.2f}"
        in_body = _relative_rms_error(body[(device, channel)], registry, np.eye(3), channel)
        assert in_body <= BOUND, f"{device} {channel.value} in the body frame: {in_body:.2f}"


def test_the_documents_maps_are_proper_rotations() -> None:
    for m in (SEED_GYRO_MAG, SEED_ACCEL, GY91_MPU, GY91_MAG, BOARD_YAWED):
        assert np.allclose(m @ m.T, np.eye(3)) and np.isclose(np.linalg.det(m), 1.0)
    # The seed's accelerometer map, turned into specific force, is its gyro/mag map.
    assert np.array_equal(SEED_ACCEL, SEED_GYRO_MAG)


def test_every_bundled_profile_has_documented_frames() -> None:
    assert set(EXPECTED) == set(bundled_profiles())


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bundled_profile_reads_the_truth_in_chip_and_body_frames(
        installed: Registry, name: str) -> None:
    profile = load_profile(bundled_profiles()[name], installed)
    _check(profile, installed, EXPECTED[name], np.eye(3))


def test_board_to_body_is_applied_after_the_mount(installed: Registry) -> None:
    """The seed RC board mounted yawed 90 degrees in the airframe: each chip's rotation is
    board_to_body @ mount, which differs from mount @ board_to_body for this board."""
    name = "seed-rc-vario.yaml"
    assert not np.allclose(BOARD_YAWED @ SEED_GYRO_MAG,
                           SEED_GYRO_MAG @ BOARD_YAWED)
    profile = load_profile(bundled_profiles()[name], installed)
    profile = profile.model_copy(update={"board_to_body": BOARD_YAWED_SPEC})
    _check(profile, installed, EXPECTED[name], BOARD_YAWED)


def test_the_emulated_board_reads_a_matrix_mount_like_its_string(installed: Registry) -> None:
    """The emulation's own mount reading (imuhal.emulation.mounting) for both spellings a
    profile may use: the signed-axis string and the 3x3 matrix (v_body = M v_sensor)."""
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], installed)
    devices = dict(profile.devices)
    devices["imu"] = devices["imu"].model_copy(update={"mount": SEED_GYRO_MAG.tolist()})
    as_matrix = profile.model_copy(update={"devices": devices,
                                           "board_to_body": BOARD_YAWED.tolist()})
    as_string = profile.model_copy(update={"board_to_body": BOARD_YAWED_SPEC})
    want = BOARD_YAWED @ SEED_GYRO_MAG
    assert np.array_equal(chip_rotations(as_matrix)["imu"], want)
    assert np.array_equal(chip_rotations(as_string)["imu"], want)
