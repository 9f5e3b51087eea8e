"""What a plugin's command-line subcommand is (``imuhal_register_commands``).

A registered :class:`Command` becomes ``imuhal NAME``: it adds its own arguments to its
subparser and runs with the parsed arguments and the loaded registry. Its errors follow the
CLI's rule: raise an :class:`~imuhal.core.errors.ImuhalError` naming the input and the fix,
and ``imuhal`` prints it on one line and exits 2.
"""

from __future__ import annotations

import argparse
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from imuhal.plugins.manager import Registry


class Command(ABC):
    """Base of a plugin's ``imuhal`` subcommand."""

    name: ClassVar[str] = ""
    """The subcommand (``imuhal NAME``); must not clash with a built-in one."""
    help: ClassVar[str] = ""
    """One line for ``imuhal --help``."""
    description: ClassVar[str] = ""

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:  # noqa: B027 - optional
        """Add the command's arguments to its subparser (default: none)."""

    @abstractmethod
    def run(self, args: argparse.Namespace, registry: Registry) -> int:
        """Do the work; return the exit status (0: success)."""
