"""Emulated boards: a profile's buses and chips as register-level emulators flying a
simulated scenario, behind the same pipeline as real hardware.

``open_emulated(profile, registry, scenario=...)`` is the entry point for emulated runs.
Emulator plugins import the chip-emulator interface from here (``ChipEmulator``,
``PhysicalInputs``, ``PlannedInputs``, ``EmulatedBus``, ``DisturbedLowPass``,
``world_counts``; defined in :mod:`imuhal.sim`).
"""

from imuhal.emulation.board import EmulatedBoard
from imuhal.emulation.open import calibrated_as_user, error_models_for, open_emulated
from imuhal.emulation.truth import TruthSink
from imuhal.sim.chip import ChipEmulator, HangsBetweenTransfers
from imuhal.sim.emulated_bus import EmulatedBus
from imuhal.sim.inputs import PhysicalInputs, PlannedInputs
from imuhal.sim.lowpass import DisturbedLowPass, world_counts

__all__ = ["ChipEmulator", "DisturbedLowPass", "EmulatedBoard", "EmulatedBus",
           "HangsBetweenTransfers", "PhysicalInputs", "PlannedInputs", "TruthSink",
           "calibrated_as_user", "error_models_for", "open_emulated", "world_counts"]
