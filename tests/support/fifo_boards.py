"""Bundled boards with their IMU read from its FIFO, for the FIFO tests."""

from __future__ import annotations

from typing import Any

from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

QUICK_ROLL = {"axes": [[1.0, 0.0, 0.0]], "rotation_s": 0.8, "ramp_s": 0.2, "hold_s": 2.0,
              "free_tumble_s": 0.0}
"""``tumble`` parameters: one full roll in 0.8 s after 2 s still, up to about 10 rad/s
(beyond +-250 deg/s)."""


def imu_read_from_fifo(registry: Registry, board: str, fifo_frames: int,
                       **settings: Any) -> BoardProfile:
    """The bundled ``board`` (a file name in profiles/) with its device ``imu`` set to
    ``read: fifo`` every ``fifo_frames`` periods, and ``settings`` on top."""
    profile = load_profile(bundled_profiles()[board], registry)
    device = profile.devices["imu"]
    merged = {**device.settings, "read": "fifo", "fifo_frames": fifo_frames, **settings}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": merged})}})
