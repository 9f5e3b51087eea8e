"""Typed registrars handed to hooks. They check what is registered and remember who did."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from imuhal.core.errors import PluginError

T = TypeVar("T")


@dataclass(frozen=True)
class Registration(Generic[T]):
    name: str
    obj: type[T]
    plugin: str
    """The plugin (entry point) name that registered it."""
    package: str
    """The distribution that provides that plugin ('' when registered by hand)."""


class Registrar(Generic[T]):
    """Registers classes of one kind under their ``name`` attribute (or the name
    ``name_of(cls)`` gives, for kinds named by something else)."""

    def __init__(self, kind: str, base: type[Any], name_attr: str = "name",
                 name_of: Callable[[type[T]], object] | None = None) -> None:
        # base: type[Any], not type[T]: the bases are abstract classes, which a type[T]
        # parameter would refuse (mypy's type-abstract)
        self.kind = kind
        self.base = base
        self.name_attr = name_attr
        self._name_of = name_of or (lambda cls: getattr(cls, name_attr, ""))
        self.entries: dict[str, Registration[T]] = {}
        self._plugin = ""
        self._package = ""

    @contextmanager
    def registering(self, plugin: str, package: str) -> Iterator[Registrar[T]]:
        """Registrations made inside are recorded as coming from ``plugin`` (the entry-point
        name) of distribution ``package``."""
        before = self._plugin, self._package
        self._plugin, self._package = plugin, package
        try:
            yield self
        finally:
            self._plugin, self._package = before

    def __call__(self, cls: type[T]) -> type[T]:
        if not (isinstance(cls, type) and issubclass(cls, self.base)):
            raise PluginError(
                f"plugin {self._plugin!r} registered {cls!r} as a {self.kind}, "
                f"but it is not a subclass of {self.base.__name__}"
            )
        name = self._name_of(cls)
        if not isinstance(name, str) or not name:
            raise PluginError(
                f"plugin {self._plugin!r}: {self.kind} {cls.__name__} has no "
                f"'{self.name_attr}' to register it under"
            )
        if name in self.entries:
            prior = self.entries[name]
            raise PluginError(
                f"{self.kind} {name!r} registered twice: by plugin {prior.plugin!r} "
                f"({prior.obj.__module__}) and by {self._plugin!r} ({cls.__module__})"
            )
        self.entries[name] = Registration(name, cls, self._plugin, self._package)
        return cls

    def get(self, name: str) -> type[T]:
        try:
            return self.entries[name].obj
        except KeyError:
            installed = ", ".join(sorted(self.entries)) or "none"
            raise PluginError(
                f"no {self.kind} named {name!r} is installed (installed: {installed})"
            ) from None

    def names(self) -> list[str]:
        return sorted(self.entries)
