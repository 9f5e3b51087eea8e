"""The plugin system: one pluggy project, one entry-point group, typed registrars."""

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry
from imuhal.plugins.registrars import Registrar
from imuhal.plugins.registry import Command, Registry

__all__ = ["Command", "Registrar", "Registry", "hookimpl", "load_registry"]
