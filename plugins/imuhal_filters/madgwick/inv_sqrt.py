"""Reciprocal square roots for the Madgwick kernels: exact, or the original 32-bit bit trick.

The x-io release normalises with the 0x5f3759df approximation and one Newton step. Its result
is up to about 0.18 % off, so the release's quaternion is not unit length (about 0.9983); the
``fast32`` reference mode reproduces that on purpose. The trick reinterprets a float32 as a
32-bit integer: the release declares that integer ``long``, which is wrong wherever long is
64 bits, so this port uses an explicit 32-bit layout.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import TypeAlias

import numpy as np

InvSqrt: TypeAlias = Callable[[float], float]

_F32 = struct.Struct("<f")
_I32 = struct.Struct("<i")
_MAGIC = 0x5F3759DF
_HALF = np.float32(0.5)
_THREE_HALVES = np.float32(1.5)


def exact_inv_sqrt(x: float) -> float:
    """1 / sqrt(x) in float64."""
    return 1.0 / math.sqrt(x)


def fast_inv_sqrt32(x: float) -> float:
    """The release's fast inverse square root, evaluated in float32 as the C code does."""
    x32 = np.float32(x)
    half_x = _HALF * x32
    i = _I32.unpack(_F32.pack(x32))[0]
    i = _MAGIC - (i >> 1)
    y = np.float32(_F32.unpack(_I32.pack(i))[0])
    y = y * (_THREE_HALVES - half_x * y * y)  # one Newton-Raphson step, float32
    return float(y)


INV_SQRT: dict[str, InvSqrt] = {"exact": exact_inv_sqrt, "fast32": fast_inv_sqrt32}
