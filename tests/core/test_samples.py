"""Samples carry units in their names, frames and quality flags."""

from __future__ import annotations

import copy
import pickle

import pytest

from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    SAMPLE_TYPES,
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    PressureSample,
    SampleFlag,
    VelocitySample,
)


def test_a_new_sample_is_valid_and_in_the_sensor_frame() -> None:
    s = AccelSample(t_ns=5, device="imu", accel_m_s2=(0.0, 0.0, -9.8))
    assert s.valid and s.frame is Frame.SENSOR and s.channel is Quantity.ACCEL


def test_flagging_returns_an_invalid_copy() -> None:
    s = PressureSample(t_ns=1, device="baro", pressure_pa=101325.0)
    bad = s.flagged(SampleFlag.CRC_ERROR)
    assert s.valid and not bad.valid and SampleFlag.CRC_ERROR in bad.flags


def test_builtin_quantities_document_their_units_and_shapes() -> None:
    assert {(q.name, q.unit, q.shape) for q in SAMPLE_TYPES} == {
        ("accel", "m/s^2", (3,)), ("gyro", "rad/s", (3,)), ("mag", "uT", (3,)),
        ("pressure", "Pa", ()), ("temperature", "degC", ()), ("velocity", "m/s", (3,)),
        ("airspeed", "m/s", ()),
        ("position", "deg, deg, m", (3,))}


def test_a_quantity_must_be_a_scalar_or_a_three_axis_vector() -> None:
    with pytest.raises(ValueError, match="shape"):
        Quantity("strain", "1", (2, 2))


def test_a_quantity_made_again_copied_or_unpickled_is_the_same_object() -> None:
    wind = Quantity("wind", "m/s", (3,), "Air velocity.")
    assert Quantity("wind", "m/s", (3,), "Air velocity.") is wind
    assert copy.deepcopy(wind) is wind and pickle.loads(pickle.dumps(wind)) is wind
    assert pickle.loads(pickle.dumps(Quantity.GYRO)) is Quantity.GYRO
    assert {wind: 1}[Quantity("wind", "m/s", (3,), "Air velocity.")] == 1


def test_quantities_that_differ_in_any_field_are_not_equal() -> None:
    wind = Quantity("wind", "m/s", (3,))
    assert wind != Quantity("wind", "km/h", (3,))
    assert wind != Quantity("wind", "m/s", (3,), "Air velocity relative to the board.")
    assert wind == Quantity("wind", "m/s", (3,))


def test_a_velocity_sample_is_earth_frame_and_carries_its_accuracy() -> None:
    v = VelocitySample(t_ns=3, device="gps", velocity_ned_m_s=(9.0, 2.0, -1.5),
                       accuracy_m_s=0.1)
    assert v.channel is Quantity.VELOCITY and v.valid
    assert not hasattr(v, "frame")  # NED by definition: no mount rotation applies to it
    assert (v.velocity_ned_m_s, v.accuracy_m_s) == ((9.0, 2.0, -1.5), 0.1)


@pytest.mark.parametrize(("cls", "value_field"), [
    (AccelSample, "accel_m_s2"), (GyroSample, "gyro_rad_s"), (MagSample, "mag_ut")])
def test_build_makes_the_same_sample_as_the_keyword_constructor(cls: type,
                                                                value_field: str) -> None:
    value = (1.5, -0.0, 3.25)
    built = cls.build(7, "imu", SampleFlag.STALE, Frame.BODY_NED, value)
    kw = cls(t_ns=7, device="imu", flags=SampleFlag.STALE, frame=Frame.BODY_NED,
             **{value_field: value})
    assert type(built) is cls and built == kw and repr(built) == repr(kw)
    assert hash(built) == hash(kw)
    with pytest.raises(AttributeError):
        built.t_ns = 8  # still frozen


def test_with_vector_changes_value_and_frame_only() -> None:
    s = AccelSample(t_ns=9, device="imu", accel_m_s2=(1.0, 2.0, 3.0))
    moved = s.with_vector((3.0, 2.0, 1.0), Frame.BODY_NED)
    assert moved.accel_m_s2 == (3.0, 2.0, 1.0) and moved.frame is Frame.BODY_NED
    assert (moved.t_ns, moved.device) == (9, "imu")


def test_a_position_sample_states_its_height_datum_and_fix() -> None:
    from imuhal.core.samples import FixType, HeightDatum, PositionSample

    p = PositionSample(t_ns=5, device="gps", latitude_deg=46.5, longitude_deg=7.9,
                       height_m=1200.0, height_datum=HeightDatum.MSL, fix_type=FixType.FIX_3D,
                       satellites=9, horizontal_accuracy_m=2.5, vertical_accuracy_m=4.0)
    assert p.channel is Quantity.POSITION and p.valid
    assert not hasattr(p, "frame")
    assert (p.height_datum, p.fix_type, p.satellites) == (HeightDatum.MSL, FixType.FIX_3D, 9)
