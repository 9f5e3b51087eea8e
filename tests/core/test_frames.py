"""Quaternions, Euler angles and mounts follow the seed's NED conventions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.core.frames import (
    MountError,
    euler_deg_from_quat,
    parse_mount,
    parse_signed_axes,
    quat_from_euler_deg,
    quat_from_matrix,
    quat_multiply,
    quat_rotate,
    quat_to_matrix,
)


def test_euler_round_trip_over_the_whole_range() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        roll, yaw = rng.uniform(-179, 179, 2)
        pitch = rng.uniform(-89, 89)
        got = euler_deg_from_quat(quat_from_euler_deg(roll, pitch, yaw))
        assert got == pytest.approx((roll, pitch, yaw), abs=1e-9)


def test_pitch_up_raises_the_nose() -> None:
    q = quat_from_euler_deg(0, 30, 0)
    nose_ned = quat_rotate(q, [1, 0, 0])
    assert nose_ned[2] < 0  # NED: up is negative down


def test_roll_right_lowers_the_right_wing() -> None:
    q = quat_from_euler_deg(30, 0, 0)
    right_wing_ned = quat_rotate(q, [0, 1, 0])
    assert right_wing_ned[2] > 0


def test_positive_yaw_is_clockwise_from_north_seen_from_above() -> None:
    q = quat_from_euler_deg(0, 0, 90)
    assert quat_rotate(q, [1, 0, 0]) == pytest.approx([0, 1, 0], abs=1e-12)  # nose east


def test_yaw_stays_within_plus_minus_180() -> None:
    assert euler_deg_from_quat(quat_from_euler_deg(0, 0, 190))[2] == pytest.approx(-170)


def test_matrix_and_quaternion_agree() -> None:
    q = quat_from_euler_deg(10, -20, 130)
    assert quat_from_matrix(quat_to_matrix(q)) == pytest.approx(q * np.sign(q[0]), abs=1e-12)


def test_quaternion_product_composes_rotations() -> None:
    a, b = quat_from_euler_deg(0, 0, 30), quat_from_euler_deg(0, 0, 60)
    assert euler_deg_from_quat(quat_multiply(a, b))[2] == pytest.approx(90)


def test_signed_axes_string_names_the_sensor_axis_along_each_body_axis() -> None:
    m = parse_signed_axes("-Y-X-Z")
    sensor = np.array([1.0, 2.0, 3.0])
    assert m @ sensor == pytest.approx([-2.0, -1.0, -3.0])  # the seed's gyro/mag map


def test_reflection_is_rejected_with_its_name() -> None:
    with pytest.raises(MountError, match="reflection"):
        parse_mount("+Y+X+Z")


def test_repeated_axis_is_rejected() -> None:
    with pytest.raises(MountError, match="exactly once"):
        parse_mount("+X+X+Z")


def test_non_orthonormal_matrix_is_rejected() -> None:
    with pytest.raises(MountError, match="orthonormal"):
        parse_mount([[1, 0, 0], [0, 2, 0], [0, 0, 1]])


def test_seed_accel_map_is_the_gyro_rotation_plus_gravity_positive_sign() -> None:
    """design.md: the seed maps the raw accelerometer (specific force, chip frame) with
    (y, x, z) into gravity-positive NED; imuhal's one mount rotation "-Y-X-Z" gives the
    negation of that, i.e. specific force in NED."""
    mount = parse_mount("-Y-X-Z")
    rng = np.random.default_rng(7)
    for _ in range(20):
        raw = rng.normal(size=3)
        seed_gravity_positive_ned = np.array([raw[1], raw[0], raw[2]])
        assert mount @ raw == pytest.approx(-seed_gravity_positive_ned)


def test_a_level_board_at_rest_reads_minus_g_on_body_z() -> None:
    # chip z points up through the board (datasheet); mounted "-Y-X-Z" on the seed board
    chip_reading = np.array([0.0, 0.0, 9.80665])
    assert parse_mount("-Y-X-Z") @ chip_reading == pytest.approx([0, 0, -9.80665])


def test_quaternion_rotation_matches_matrix_for_random_vectors() -> None:
    q = quat_from_euler_deg(33, 12, -77)
    v = np.array([0.3, -1.2, 2.0])
    conj = np.array([q[0], -q[1], -q[2], -q[3]])
    rotated = quat_multiply(quat_multiply(q, [0, *v]), conj)[1:]
    assert quat_rotate(q, v) == pytest.approx(rotated)
    assert math.isclose(np.linalg.norm(rotated), np.linalg.norm(v))
