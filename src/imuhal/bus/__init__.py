"""Buses: one transfer primitive, a register view on top, real and emulated backends."""

from imuhal.bus.base import Bus, BusKind, Link
from imuhal.bus.registers import RegisterConvention, RegisterView

__all__ = ["Bus", "BusKind", "Link", "RegisterConvention", "RegisterView"]
