"""The driver interface. Chip drivers live in plugins, never in core."""

from imuhal.drivers.base import DeviceHealth, DeviceIdentity, Driver, DriverSettings, PollResult

__all__ = ["DeviceHealth", "DeviceIdentity", "Driver", "DriverSettings", "PollResult"]
