"""How procedures talk to whoever runs them (a terminal, a GUI, a log), without doing I/O.

A procedure calls its ``progress`` callback with :class:`Progress` events; the CLI prints
them, a test may collect them, a library user may ignore them (the default).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum


class ProgressKind(str, Enum):
    INSTRUCTION = "instruction"
    """Tell the user to do something (keep still, turn the board)."""
    PROGRESS = "progress"
    """How far the current step is (``fraction`` in [0, 1])."""
    RETRY = "retry"
    """A measurement was discarded (board moved, reading too large) and will be repeated."""
    STEP_DONE = "step-done"
    """A step finished (a position recorded)."""


@dataclass(frozen=True, slots=True)
class Progress:
    procedure: str
    kind: ProgressKind
    message: str
    fraction: float | None = None
    step: str = ""


ProgressCallback = Callable[[Progress], None]


def ignore(_: Progress) -> None:
    """The default callback: say nothing."""
