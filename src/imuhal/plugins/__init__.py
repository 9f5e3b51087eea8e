"""The plugin system: one pluggy project, one entry-point group, typed registrars."""

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import Registry, load_registry

__all__ = ["Registry", "hookimpl", "load_registry"]
