"""Repeating one step of a multi-transfer sequence after a transient host bus error.

A chip behind another chip's I2C master costs several host transfers per slave byte (four
on the MAX21100's one-shot master, three or more on the MPU-9250's slave 4). Without a retry
per step, the slave's driver would see the host's error rate multiplied by that count
(26 of 75 Hz delivered at 1 % host errors, issue 9). Each such step must be idempotent.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from imuhal.core.errors import BusError, NackError

_R = TypeVar("_R")


def retried(step: Callable[..., _R], *args: int, attempts: int) -> _R:
    """``step(*args)``, repeated up to ``attempts`` times in all after a ``BusError``; a NACK
    (no device answered) is evidence, not a glitch, and is raised at once."""
    for _ in range(attempts - 1):
        try:
            return step(*args)
        except NackError:
            raise
        except BusError:
            continue
    return step(*args)
