"""The chip-emulator interface, as emulator plugins import it.

Defined in :mod:`imuhal.sim.chip` and :mod:`imuhal.sim.inputs` (below the plugin registry, so
the registry can check what is registered); this module is the stable name plugins use.
"""

from imuhal.sim.chip import ChipEmulator
from imuhal.sim.inputs import PhysicalInputs

__all__ = ["ChipEmulator", "PhysicalInputs"]
