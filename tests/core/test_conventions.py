"""Named coordinate conventions: their definitions and exact conversions between them.

The Freescale note's systems are checked against the note itself (level readings, the HAL
axis maps of the reference library as the conformance README tabulates them); the rest are
properties over generated orientations and vectors (hypothesis): round trips, composition
A -> B -> C == A -> C, agreement of the quaternion, vector and Euler conversions.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from imuhal.core import conventions as cv
from imuhal.core.conventions import (
    CONVENTIONS,
    AccelSign,
    Convention,
    EulerStyle,
    UnknownConvention,
    VectorKind,
    compass_heading_deg,
    convert_earth_vector,
    convert_euler_deg,
    convert_quat,
    convert_vector,
    euler_deg_from_quat,
    get_convention,
    quat_from_euler_deg,
)
from imuhal.core.frames import quat_from_euler_deg as ned_quat_from_euler
from imuhal.core.frames import quat_to_matrix

NAMES = list(CONVENTIONS)
KINDS = list(VectorKind)
names = st.sampled_from(NAMES)
kinds = st.sampled_from(KINDS)
components = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False)
vectors = st.tuples(components, components, components).map(np.array)
unit_quats = (st.tuples(*[st.floats(min_value=-1.0, max_value=1.0)] * 4)
              .map(np.array).filter(lambda q: np.linalg.norm(q) > 0.1)
              .map(lambda q: q / np.linalg.norm(q)))


def _same_rotation(p: np.ndarray, q: np.ndarray) -> bool:
    return bool(np.allclose(quat_to_matrix(p), quat_to_matrix(q), atol=1e-12))


# -- the definitions ---------------------------------------------------------------------------

@pytest.mark.parametrize("name, reading_g", [
    ("ned", (0.0, 0.0, -1.0)),        # specific force, z down: the table pushes up
    ("aerospace", (0.0, 0.0, 1.0)),   # Freescale Aerospace: gravity positive, z down
    ("enu", (0.0, 0.0, 1.0)),         # ROS: specific force, z up
    ("android", (0.0, 0.0, 1.0)),     # Freescale Android: acceleration positive, z up
    ("win8", (0.0, 0.0, -1.0)),       # Freescale Windows 8: gravity positive, z up
])
def test_a_level_board_at_rest_reads_what_each_convention_defines(
        name: str, reading_g: tuple[float, float, float]) -> None:
    np.testing.assert_array_equal(get_convention(name).level_accel_reading_g, reading_g)


@pytest.mark.parametrize("name", NAMES)
def test_every_named_convention_is_a_proper_rotation_of_ned_frd(name: str) -> None:
    c = get_convention(name)
    assert np.linalg.det(c.earth_from_ned) == pytest.approx(1.0)
    assert np.linalg.det(c.body_from_frd) == pytest.approx(1.0)


def test_a_mirror_image_frame_is_rejected_when_the_convention_is_built() -> None:
    with pytest.raises(ValueError, match="not a right-handed frame"):
        Convention("mirror", ("north", "east", "up"), ("forward", "right", "down"),
                   AccelSign.SPECIFIC_FORCE, EulerStyle.ZYX)


def test_freescale_android_and_win8_see_the_aerospace_board_as_the_reference_hal_does() -> None:
    """The conformance README's exact maps from the NED build's inputs (gravity-positive g,
    deg/s, uT): Android accel (-ay, -ax, az), Win8 accel (ay, ax, -az), gyro and mag of
    both (y, x, -z)."""
    ax, ay, az = 0.1, -0.2, 0.97
    np.testing.assert_array_equal(
        convert_vector((ax, ay, az), "aerospace", "android", VectorKind.SPECIFIC_FORCE),
        (-ay, -ax, az))
    np.testing.assert_array_equal(
        convert_vector((ax, ay, az), "aerospace", "win8", VectorKind.SPECIFIC_FORCE),
        (ay, ax, -az))
    for kind in (VectorKind.ANGULAR_RATE, VectorKind.MAGNETIC_FIELD):
        for dst in ("android", "win8"):
            np.testing.assert_array_equal(convert_vector((1.0, 2.0, 3.0), "aerospace", dst, kind),
                                          (2.0, 1.0, -3.0))


# No deadline: hypothesis's default 200 ms trips on a loaded CI machine, not on a slow conversion.
@settings(deadline=None)
@given(q=unit_quats)
def test_freescale_enu_quaternion_is_q0_q2_q1_minus_q3_of_the_ned_one(q: np.ndarray) -> None:
    for dst in ("android", "win8"):
        np.testing.assert_allclose(convert_quat(q, "aerospace", dst),
                                   (q[0], q[2], q[1], -q[3]), atol=1e-14)


def test_ros_output_of_a_board_pitched_nose_up_30_deg_heading_east() -> None:
    """By hand: ENU earth, FLU body. Forward points east (the ENU x axis) and 30 deg up, so the
    body is the earth frame turned about y (north, = body left) by -30 deg (a positive
    rotation about left would push the nose down): q = (cos 15, 0, -sin 15, 0); ROS RPY
    (0, -30, 0); forward = (cos 30, 0, sin 30) in ENU."""
    q_ned = ned_quat_from_euler(0.0, 30.0, 90.0)
    q_ros = convert_quat(q_ned, "ned", "ros")
    c15, s15 = math.cos(math.radians(15.0)), math.sin(math.radians(15.0))
    np.testing.assert_allclose(q_ros, (c15, 0.0, -s15, 0.0), atol=1e-15)
    assert euler_deg_from_quat("enu", q_ros) == pytest.approx((0.0, -30.0, 0.0), abs=1e-12)
    np.testing.assert_allclose(quat_to_matrix(q_ros)[:, 0], (math.sqrt(3) / 2, 0.0, 0.5),
                               atol=1e-15)


def test_earth_axes_are_renamed_not_rotated_away() -> None:
    np.testing.assert_array_equal(convert_earth_vector((1.0, 2.0, 3.0), "ned", "enu"),
                                  (2.0, 1.0, -3.0))


def test_an_unknown_name_is_an_error_listing_the_choices() -> None:
    with pytest.raises(UnknownConvention, match="ned, aerospace, enu, android, win8"):
        get_convention("nwu")
    assert get_convention("ROS") is cv.ENU and get_convention("flu") is cv.ENU


# -- properties --------------------------------------------------------------------------------

@settings(max_examples=200, deadline=None)
@given(v=vectors, a=names, b=names, kind=kinds)
def test_vector_round_trip_is_exact(v: np.ndarray, a: str, b: str, kind: VectorKind) -> None:
    np.testing.assert_array_equal(convert_vector(convert_vector(v, a, b, kind), b, a, kind), v)


@settings(max_examples=200, deadline=None)
@given(v=vectors, a=names, b=names, c=names, kind=kinds)
def test_vector_conversions_compose(v: np.ndarray, a: str, b: str, c: str,
                                    kind: VectorKind) -> None:
    np.testing.assert_array_equal(convert_vector(convert_vector(v, a, b, kind), b, c, kind),
                                  convert_vector(v, a, c, kind))


@settings(max_examples=200, deadline=None)
@given(q=unit_quats, a=names, b=names)
def test_quaternion_round_trip_returns_the_same_quaternion(q: np.ndarray, a: str,
                                                           b: str) -> None:
    np.testing.assert_allclose(convert_quat(convert_quat(q, a, b), b, a), q, atol=1e-14)


@settings(max_examples=200, deadline=None)
@given(q=unit_quats, a=names, b=names, c=names)
def test_quaternion_conversions_compose(q: np.ndarray, a: str, b: str, c: str) -> None:
    assert _same_rotation(convert_quat(convert_quat(q, a, b), b, c), convert_quat(q, a, c))


@settings(max_examples=200, deadline=None)
@given(q=unit_quats, v=vectors, dst=names)
def test_converted_quaternion_rotates_converted_body_vectors_onto_converted_earth_vectors(
        q: np.ndarray, v: np.ndarray, dst: str) -> None:
    earth_ned = quat_to_matrix(q) @ v
    body_dst = convert_vector(v, "ned", dst, VectorKind.MAGNETIC_FIELD)
    np.testing.assert_allclose(quat_to_matrix(convert_quat(q, "ned", dst)) @ body_dst,
                               convert_earth_vector(earth_ned, "ned", dst), atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(q=unit_quats, dst=names)
def test_gravity_is_read_consistently_with_the_attitude(q: np.ndarray, dst: str) -> None:
    """A board at rest in any attitude reads, in any convention, the level reading rotated:
    the accelerometer sign and the axes travel together."""
    reading_ned = quat_to_matrix(q).T @ np.array([0.0, 0.0, -1.0])  # specific force, g
    c = get_convention(dst)
    q_dst = convert_quat(q, "ned", dst)
    up_dst = convert_earth_vector((0.0, 0.0, -1.0), "ned", dst)
    expected = c.accel_sign.factor * (quat_to_matrix(q_dst).T @ up_dst)
    np.testing.assert_allclose(convert_vector(reading_ned, "ned", dst,
                                              VectorKind.SPECIFIC_FORCE), expected, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(q=unit_quats, a=names, b=names)
def test_compass_heading_does_not_depend_on_the_convention(q: np.ndarray, a: str,
                                                           b: str) -> None:
    forward_ned = quat_to_matrix(q)[:, 0]
    assume(math.hypot(forward_ned[0], forward_ned[1]) > 1e-3)  # nose vertical: no heading
    h_a = compass_heading_deg(a, convert_quat(q, "ned", a))
    h_b = compass_heading_deg(b, convert_quat(q, "ned", b))
    assert abs((h_a - h_b + 180.0) % 360.0 - 180.0) < 1e-9


# Euler angles: each style's non-singular ranges
_EULER_RANGES = {
    EulerStyle.ZYX: ((-179.0, 179.0), (-89.0, 89.0), (-179.0, 179.0)),
    EulerStyle.FREESCALE_NED: ((-179.0, 179.0), (-89.0, 89.0), (0.5, 359.5)),
    EulerStyle.FREESCALE_ANDROID: ((-89.0, 89.0), (-179.0, 179.0), (0.5, 359.5)),
    EulerStyle.FREESCALE_WIN8: ((-89.0, 89.0), (-179.0, 179.0), (0.5, 359.5)),
}


@st.composite
def named_euler(draw: st.DrawFn) -> tuple[str, tuple[float, float, float]]:
    name = draw(names)
    ranges = _EULER_RANGES[get_convention(name).euler]
    angles = tuple(draw(st.floats(min_value=lo, max_value=hi)) for lo, hi in ranges)
    if get_convention(name).euler is EulerStyle.FREESCALE_WIN8:
        # pitch +-90 is Windows 8's gimbal lock (yaw and roll mix there)
        assume(abs(abs(angles[1]) - 90.0) > 1.0)
    return name, angles  # type: ignore[return-value]


@settings(max_examples=300, deadline=None)
@given(case=named_euler())
def test_euler_angles_survive_a_round_trip_in_every_convention(
        case: tuple[str, tuple[float, float, float]]) -> None:
    name, angles = case
    got = euler_deg_from_quat(name, quat_from_euler_deg(name, *angles))
    assert got == pytest.approx(angles, abs=1e-6)


def _gimbal_angle(style: EulerStyle, angles: tuple[float, float, float]) -> float:
    """The angle whose +-90 deg is the style's gimbal lock."""
    return angles[0] if style is EulerStyle.FREESCALE_ANDROID else angles[1]


@settings(max_examples=200, deadline=None)
@given(case=named_euler(), dst=names)
def test_euler_conversion_is_the_quaternion_conversion(
        case: tuple[str, tuple[float, float, float]], dst: str) -> None:
    src, angles = case
    via_quat = convert_quat(quat_from_euler_deg(src, *angles), src, dst)
    # near the destination's gimbal lock its angles cannot hold the attitude precisely
    dst_angles = euler_deg_from_quat(dst, via_quat)
    assume(abs(abs(_gimbal_angle(get_convention(dst).euler, dst_angles)) - 90.0) > 1.0)
    assert _same_rotation(quat_from_euler_deg(dst, *convert_euler_deg(angles, src, dst)),
                          via_quat / np.linalg.norm(via_quat))


def test_freescale_android_yaw_is_the_compass_and_win8_yaw_its_complement() -> None:
    q_ned = ned_quat_from_euler(0.0, 0.0, 30.0)  # level, heading 030
    assert euler_deg_from_quat("aerospace", q_ned).yaw == pytest.approx(30.0)
    assert euler_deg_from_quat("android", convert_quat(q_ned, "ned", "android")).yaw == \
        pytest.approx(30.0)
    assert euler_deg_from_quat("win8", convert_quat(q_ned, "ned", "win8")).yaw == \
        pytest.approx(330.0)
    assert euler_deg_from_quat("enu", convert_quat(q_ned, "ned", "enu")).yaw == \
        pytest.approx(60.0)


def test_the_worked_example_of_units_and_frames_md() -> None:
    """Nose 30 deg up, facing east, at rest: the numbers docs/units-and-frames.md prints."""
    q_ned = ned_quat_from_euler(0.0, 30.0, 90.0)
    force_ned = quat_to_matrix(q_ned).T @ [0.0, 0.0, -1.0]  # g
    np.testing.assert_allclose(force_ned * 9.80665, (4.903, 0.0, -8.493), atol=1e-3)
    np.testing.assert_allclose(convert_vector(force_ned * 9.80665, "ned", "enu",
                                              VectorKind.SPECIFIC_FORCE), (4.903, 0.0, 8.493),
                               atol=1e-3)
    np.testing.assert_allclose(q_ned, (0.6830, -0.1830, 0.1830, 0.6830), atol=1e-4)
    for name, reading in (("aerospace", (-0.5, 0.0, 0.866)), ("android", (0.0, 0.5, 0.866)),
                          ("win8", (0.0, -0.5, -0.866))):
        np.testing.assert_allclose(
            convert_vector(force_ned, "ned", name, VectorKind.SPECIFIC_FORCE), reading,
            atol=1e-3)


def test_ros_roll_has_the_sense_of_ned_roll_while_pitch_and_yaw_flip() -> None:
    """Right wing 20 deg down, facing north: ROS roll +20 (both turn about the forward axis);
    nose 20 deg up: ROS pitch -20; facing north: ROS yaw +90 (anticlockwise from east)."""
    rolled = convert_quat(ned_quat_from_euler(20.0, 0.0, 0.0), "ned", "ros")
    pitched = convert_quat(ned_quat_from_euler(0.0, 20.0, 0.0), "ned", "ros")
    assert euler_deg_from_quat("ros", rolled) == pytest.approx((20.0, 0.0, 90.0))
    assert euler_deg_from_quat("ros", pitched) == pytest.approx((0.0, -20.0, 90.0))
