"""imuhal events as ROS 2 messages: REP-103 frames, REP-145 topics and covariances, units.

The expected values are written from the ROS conventions themselves (ENU earth, FLU body,
tesla, x y z w quaternions), not through imuhal.core.conventions.
"""

from __future__ import annotations

import math

import pytest

from imuhal.core.frames import quat_from_euler_deg
from imuhal.core.samples import (
    AccelSample,
    FixType,
    Frame,
    GyroSample,
    HeightDatum,
    MagSample,
    PositionSample,
    PressureSample,
    SampleFlag,
    TemperatureSample,
    VelocitySample,
)
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.sinks.ros.messages import MSGDEFS, RosMessages, RosRecord, stamp
from imuhal.sinks.ros.settings import RosSettings

G = 9.80665


def _ros(**settings: float) -> RosMessages:
    return RosMessages(RosSettings(**settings), "board")


def _all(conv: RosMessages, *events: object) -> list[RosRecord]:
    out = [r for e in events for r in conv.convert(e)]  # type: ignore[arg-type]
    return out + list(conv.finish())


def _accel(t_ns: int, v: tuple[float, float, float], device: str = "imu") -> AccelSample:
    return AccelSample(t_ns=t_ns, device=device, frame=Frame.BODY_NED, accel_m_s2=v)


def _gyro(t_ns: int, v: tuple[float, float, float], device: str = "imu") -> GyroSample:
    return GyroSample(t_ns=t_ns, device=device, frame=Frame.BODY_NED, gyro_rad_s=v)


def _yaw_enu_deg(q: dict[str, float]) -> float:
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def test_a_level_board_at_rest_reads_plus_g_on_flu_z_and_its_raw_message_has_no_orientation(
        ) -> None:
    (rec,) = _all(_ros(), _accel(5, (0.0, 0.0, -G)), _gyro(5, (0.1, 0.2, 0.3)))
    assert (rec.topic, rec.type) == ("imu/data_raw", "sensor_msgs/msg/Imu")
    m = rec.message
    assert m["linear_acceleration"] == {"x": 0.0, "y": 0.0, "z": G}
    # FRD rates (p, q, r) are (p, -q, -r) about forward, left, up
    assert m["angular_velocity"] == {"x": 0.1, "y": -0.2, "z": -0.3}
    assert m["orientation_covariance"][0] == -1.0
    assert m["angular_velocity_covariance"] == [0.0] * 9  # present, noise unknown
    assert m["header"] == {"stamp": {"sec": 0, "nanosec": 5}, "frame_id": "board"}


def test_a_level_board_facing_north_has_enu_yaw_90_and_one_facing_east_yaw_0() -> None:
    conv = _ros()
    north = AttitudeEstimate(t_ns=1, source="ahrs", q_body_to_ned=(1.0, 0.0, 0.0, 0.0))
    q_east = tuple(float(c) for c in quat_from_euler_deg(0.0, 0.0, 90.0))
    east = AttitudeEstimate(t_ns=2, source="ahrs", q_body_to_ned=q_east)  # type: ignore[arg-type]
    a, b = _all(conv, north, east)
    assert a.topic == b.topic == "imu/data"
    assert _yaw_enu_deg(a.message["orientation"]) == pytest.approx(90.0, abs=1e-9)
    assert _yaw_enu_deg(b.message["orientation"]) == pytest.approx(0.0, abs=1e-9)
    assert a.message["orientation_covariance"] == [0.0] * 9


def test_the_estimate_carries_the_latest_raw_rates_of_the_first_imu() -> None:
    conv = _ros(angular_velocity_stddev_rad_s=0.01)
    recs = _all(conv, _accel(1, (0.0, 0.0, -G)), _gyro(1, (0.0, 0.0, 0.5)),
                AttitudeEstimate(t_ns=1, source="ahrs", q_body_to_ned=(1.0, 0.0, 0.0, 0.0)))
    est = recs[-1].message
    assert est["angular_velocity"]["z"] == -0.5
    assert est["angular_velocity_covariance"][0] == pytest.approx(1e-4)
    assert est["angular_velocity_covariance"][4] == pytest.approx(1e-4)


def test_a_gyro_without_its_accelerometer_half_marks_linear_acceleration_absent() -> None:
    recs = _all(_ros(), _gyro(1, (0.0, 0.0, 0.1)), _accel(2, (0.0, 0.0, -G)))
    assert [r.t_ns for r in recs] == [1, 2]
    assert recs[0].message["linear_acceleration_covariance"][0] == -1.0
    assert recs[1].message["angular_velocity_covariance"][0] == -1.0


def test_flagged_and_sensor_frame_samples_are_counted_not_written() -> None:
    conv = _ros()
    bad = AccelSample(t_ns=1, device="imu", frame=Frame.BODY_NED, accel_m_s2=(0.0, 0.0, -G),
                      flags=SampleFlag.SATURATED)
    raw = MagSample(t_ns=1, device="mag", mag_ut=(20.0, 0.0, 40.0))
    assert _all(conv, bad, raw, VerticalEstimate(t_ns=1, source="v", altitude_m=1.0,
                                                 climb_m_s=0.0)) == []
    assert conv.skipped == {"flagged": 1, "sensor frame": 1}


def test_magnetic_field_is_in_tesla_in_flu_pressure_in_pa_temperature_per_device() -> None:
    recs = _all(_ros(magnetic_field_stddev_ut=0.5, pressure_stddev_pa=2.0),
                MagSample(t_ns=1, device="mag", frame=Frame.BODY_NED,
                          mag_ut=(20.0, 1.0, 40.0)),
                PressureSample(t_ns=2, device="baro", pressure_pa=95000.5),
                TemperatureSample(t_ns=2, device="baro", temperature_degc=21.5))
    mag, pressure, temp = recs
    assert mag.topic == "imu/mag"
    assert mag.message["magnetic_field"] == pytest.approx({"x": 20e-6, "y": -1e-6, "z": -40e-6})
    assert mag.message["magnetic_field_covariance"][8] == pytest.approx(0.25e-12)
    assert (pressure.topic, pressure.message["fluid_pressure"]) == ("pressure", 95000.5)
    assert pressure.message["variance"] == 4.0
    assert (temp.topic, temp.message["temperature"]) == ("baro/temperature", 21.5)


def test_a_second_device_of_a_kind_gets_its_own_namespace() -> None:
    recs = _all(_ros(), PressureSample(t_ns=1, device="baro", pressure_pa=1.0),
                PressureSample(t_ns=1, device="baro2", pressure_pa=2.0))
    assert [r.topic for r in recs] == ["pressure", "baro2/pressure"]


def test_a_gnss_fix_has_diagonal_covariance_and_no_altitude_above_msl() -> None:
    fix = PositionSample(t_ns=3, device="gps", latitude_deg=46.5, longitude_deg=7.9,
                         height_m=1500.0, height_datum=HeightDatum.MSL,
                         horizontal_accuracy_m=2.0, vertical_accuracy_m=3.0,
                         fix_type=FixType.FIX_3D, satellites=9)
    ell = PositionSample(t_ns=4, device="gps", latitude_deg=46.5, longitude_deg=7.9,
                         height_m=1550.0, height_datum=HeightDatum.ELLIPSOID,
                         fix_type=FixType.FIX_3D)
    a, b = _all(_ros(), fix, ell)
    assert a.topic == "gps/fix" and a.type == "sensor_msgs/msg/NavSatFix"
    m = a.message
    assert (m["latitude"], m["longitude"]) == (46.5, 7.9)
    assert math.isnan(m["altitude"])  # NavSatFix altitude is above the ellipsoid
    assert m["position_covariance"] == [4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0]
    assert m["position_covariance_type"] == 2
    assert m["status"] == {"status": 0, "service": 1}
    assert b.message["altitude"] == 1550.0 and b.message["position_covariance_type"] == 0


def test_gnss_velocity_is_east_north_up() -> None:
    (rec,) = _all(_ros(), VelocitySample(t_ns=1, device="gps", velocity_ned_m_s=(3.0, 4.0, 1.0),
                                         accuracy_m_s=0.5))
    twist = rec.message["twist"]
    assert twist["twist"]["linear"] == {"x": 4.0, "y": 3.0, "z": -1.0}
    assert twist["covariance"][0] == twist["covariance"][14] == 0.25


@pytest.mark.parametrize("t_ns", [0, 999_999_999, 1_000_000_000, 123_456_789_012])
def test_a_stamp_splits_nanoseconds_into_seconds_and_a_remainder(t_ns: int) -> None:
    s = stamp(t_ns)
    assert 0 <= s["nanosec"] < 1_000_000_000
    assert s["sec"] * 1_000_000_000 + s["nanosec"] == t_ns


def test_every_message_type_has_its_dependencies_defined() -> None:
    for name, text in MSGDEFS.items():
        defined = {line[5:] for line in text.splitlines() if line.startswith("MSG: ")}
        used = {line.split()[0].removesuffix("[9]") for line in text.splitlines()
                if "/" in line.split(" ")[0] and not line.startswith("MSG: ")}
        assert used <= defined, name
