"""The profile's ``outputs.mcap`` section: frame id and the measurement noise ROS messages
carry.

Kept free of third-party imports: the profile schema includes it whether or not the ``ros``
extra is installed.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class RosSettings(BaseModel):
    """How the board appears in ROS 2 messages (docs/outputs.md, "ROS 2 / MCAP").

    Standard deviations are 1-sigma, per axis, in the units of their names; a value left out
    is unknown and its covariance is written as all zeros (sensor_msgs: "covariance
    unknown"). A quantity a message does not carry at all gets -1 in the first element
    (REP-145: ``orientation_covariance[0] = -1`` on ``imu/data_raw``).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    frame_id: str | None = Field(None, min_length=1)
    """``header.frame_id`` of every message (the FLU body frame of the board); default: the
    profile's ``name``."""
    angular_velocity_stddev_rad_s: float | None = Field(None, ge=0)
    linear_acceleration_stddev_m_s2: float | None = Field(None, ge=0)
    magnetic_field_stddev_ut: float | None = Field(None, ge=0)
    pressure_stddev_pa: float | None = Field(None, ge=0)
    temperature_stddev_degc: float | None = Field(None, ge=0)
    orientation_stddev_rad: float | None = Field(None, ge=0)
    """Of the attitude estimate on ``imu/data`` (roll, pitch and yaw alike)."""
