"""Optional compiled kernels (the ``fast`` extra: numba). Pure Python stays the reference.

``jit`` wraps a kernel that numba compiles on its first call, when numba is installed and
``IMUHAL_NO_JIT`` is not 1; callers check :func:`available` first and otherwise run the
pure-Python path, which gives the same results (the tests compare the two to 1e-12 whenever
numba is installed). numba is imported only then: it costs about 60 MB and a second, which a
run that never calls a batch function should not pay. No fast-math: the compiled kernels do
the same IEEE operations in the same order as the Python code.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from functools import cache
from typing import Any

_INSTALLED = importlib.util.find_spec("numba") is not None


def available() -> bool:
    """True when compiled kernels are used."""
    return _INSTALLED and os.environ.get("IMUHAL_NO_JIT") != "1"


class Kernel:
    """``fn``, compiled by numba (no Python objects, cached on disk) on the first call."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn

    def __call__(self, *args: Any) -> Any:
        return _compiled(self.fn)(*args)


@cache
def _compiled(fn: Callable[..., Any]) -> Callable[..., Any]:
    import numba

    # a kernel may call helpers that are kernels themselves (shared quaternion arithmetic):
    # numba needs them compiled before it types the caller, so they are, and the module's
    # name for each is pointed at the compiled one
    for name in fn.__code__.co_names:
        helper = fn.__globals__.get(name)
        if isinstance(helper, Kernel):
            fn.__globals__[name] = _compiled(helper.fn)
    return numba.njit(cache=True, nogil=True)(fn)


def jit(fn: Callable[..., Any]) -> Kernel:
    """A lazily compiled kernel of ``fn`` (call it only when :func:`available`)."""
    return Kernel(fn)
