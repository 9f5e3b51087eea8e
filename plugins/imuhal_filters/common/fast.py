"""Optional compiled kernels (the ``fast`` extra: numba). Pure Python stays the reference.

``jit`` compiles a kernel with numba when it is installed (and ``IMUHAL_NO_JIT`` is not set),
else returns None: callers then run the pure-Python path, which gives the same results (the
conformance tests compare the two to 1e-12 whenever numba is installed). No fast-math: the
compiled kernels do the same IEEE operations in the same order as the Python code.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

try:  # an optional dependency
    import numba
except ImportError:  # pragma: no cover - depends on the installation
    numba = None


def available() -> bool:
    """True when compiled kernels are used."""
    return numba is not None and os.environ.get("IMUHAL_NO_JIT") != "1"


def jit(fn: Callable[..., Any]) -> Callable[..., Any] | None:
    """``fn`` compiled (no Python objects, cached on disk), or None without numba."""
    if numba is None:
        return None
    return numba.njit(cache=True, nogil=True)(fn)
