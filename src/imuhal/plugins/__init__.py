"""The plugin system: one pluggy project, one entry-point group, typed registrars."""

from imuhal.plugins.commands import Command
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import Registry, load_registry
from imuhal.plugins.registrars import Registrar

__all__ = ["Command", "Registrar", "Registry", "hookimpl", "load_registry"]
