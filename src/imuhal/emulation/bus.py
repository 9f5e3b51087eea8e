"""The emulated bus, as emulator plugins import it (defined in :mod:`imuhal.sim.emulated_bus`)."""

from imuhal.sim.emulated_bus import EmulatedBus

__all__ = ["EmulatedBus"]
