"""The profile's ``outputs.mavlink`` section: who the board is on a MAVLink network and how
often it speaks. Free of third-party imports: the profile schema includes it without the extra."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class MavlinkSettings(BaseModel):
    """Identity and rates of the MAVLink output (docs/outputs.md, "MAVLink").

    Rates are in the run's time (Hz); 0 sends with every new value.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    system_id: int = Field(1, ge=1, le=255)
    """MAVLink system id of the board (the same every run: ground stations key on it)."""
    component_id: int = Field(1, ge=1, le=255)
    """MAVLink component id (1: MAV_COMP_ID_AUTOPILOT1, the component ground stations show
    as a vehicle; 200: MAV_COMP_ID_IMU)."""
    mav_type: int = Field(0, ge=0, le=255)
    """HEARTBEAT ``type`` (MAV_TYPE; 0: generic)."""
    highres_imu_hz: float = Field(50.0, ge=0)
    attitude_hz: float = Field(50.0, ge=0)
    pressure_hz: float = Field(10.0, ge=0)
