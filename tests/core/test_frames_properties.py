"""Properties of the frame helpers over generated inputs (hypothesis)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imuhal.core.frames import (
    MountError,
    euler_deg_from_quat,
    parse_mount,
    quat_from_euler_deg,
    quat_rotate,
)

angles = st.floats(min_value=-179.0, max_value=179.0)
pitches = st.floats(min_value=-89.0, max_value=89.0)
vectors = st.lists(st.floats(min_value=-1e3, max_value=1e3), min_size=3, max_size=3)
SIGNED_AXES = ["".join(s + a for s, a in zip(signs, axes, strict=True))
               for axes in itertools.permutations("XYZ")
               for signs in itertools.product("+-", repeat=3)]


@settings(max_examples=300, deadline=None)
@given(roll=angles, pitch=pitches, yaw=angles)
def test_euler_angles_survive_a_round_trip(roll: float, pitch: float, yaw: float) -> None:
    got = euler_deg_from_quat(quat_from_euler_deg(roll, pitch, yaw))
    assert got == pytest.approx((roll, pitch, yaw), abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(roll=angles, pitch=pitches, yaw=angles, v=vectors)
def test_rotation_preserves_length(roll: float, pitch: float, yaw: float,
                                   v: list[float]) -> None:
    rotated = quat_rotate(quat_from_euler_deg(roll, pitch, yaw), v)
    assert np.linalg.norm(rotated) == pytest.approx(np.linalg.norm(v), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("spec", SIGNED_AXES)
def test_every_signed_axis_string_is_a_rotation_or_a_named_reflection(spec: str) -> None:
    signs = spec.count("-")
    permutation_parity = {"XYZ": 1, "YZX": 1, "ZXY": 1}.get(spec.replace("+", "")
                                                              .replace("-", ""), -1)
    proper = permutation_parity * (-1) ** signs > 0
    if proper:
        m = parse_mount(spec)
        assert np.linalg.det(m) == pytest.approx(1.0)
    else:
        with pytest.raises(MountError, match="reflection"):
            parse_mount(spec)
