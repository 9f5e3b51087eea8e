"""The emulated bus, as emulator plugins import it (defined in :mod:`imuhal.sim.chip`)."""

from imuhal.sim.chip import EmulatedBus

__all__ = ["EmulatedBus"]
