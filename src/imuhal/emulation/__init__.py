"""Register-level chip emulation infrastructure (chip-agnostic)."""

from imuhal.emulation.base import ChipEmulator, PhysicalInputs
from imuhal.emulation.bus import EmulatedBus

__all__ = ["ChipEmulator", "EmulatedBus", "PhysicalInputs"]
