"""Optional compiled kernels. Pure Python stays the reference.

A kernel (``jit(fn, returns=..., **argument_types)``) is one function of plain loops in a
``*/fast.py`` module, with its argument types declared next to it. Each kernel runs on the
first backend of these that it can use:

1. **aot**: the ahead-of-time compiled extension that ``imuhal kernels build`` made
   (:mod:`imuhal_filters.common.aot`), when its fingerprint matches this kernel's source,
   this Python, numpy and numba. Loading it does not import numba (about 120 MB less).
2. **jit**: numba (the ``fast`` extra) compiles the same function on its first call, with the
   same declared signature, cached on disk.
3. **python**: the caller's own pure-Python path (callers ask :meth:`Kernel.available`).

``IMUHAL_KERNELS=aot|jit|python|auto`` (default ``auto``) forces a backend for benchmarks and
tests: a forced backend that a kernel cannot use is an error, never a silent fallback.
``IMUHAL_NO_JIT=1`` (older name) is ``IMUHAL_KERNELS=python``. The compiled backends give the
same results as the Python path (the tests compare them to 1e-12): no fast-math, the same IEEE
operations in the same order.

Both compiled backends check each call's arguments against the declared types (dtype, number
of dimensions, C order, writable; bool, int and float scalars): an AOT extension reads memory
as its signature says, so a caller passing anything else is a bug to report, not to run.
"""

from __future__ import annotations

import importlib.util
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

from imuhal.core.errors import ImuhalError

_INSTALLED = importlib.util.find_spec("numba") is not None

BACKENDS = ("aot", "jit", "python")
MODES = ("auto", *BACKENDS)


class KernelUnavailable(ImuhalError):
    """A backend forced by ``IMUHAL_KERNELS`` cannot run this kernel (the message says why
    and how to fix it)."""


def mode() -> str:
    """The backend choice from the environment: auto, aot, jit or python."""
    if os.environ.get("IMUHAL_NO_JIT") == "1":
        return "python"
    value = os.environ.get("IMUHAL_KERNELS", "auto").strip().lower() or "auto"
    if value not in MODES:
        raise KernelUnavailable(
            f"IMUHAL_KERNELS={value!r} is not a kernel backend: use one of {', '.join(MODES)}")
    return value


def numba_installed() -> bool:
    """numba can be imported (the ``fast`` extra)."""
    return _INSTALLED


def available() -> bool:
    """True when some kernel may run compiled (an AOT extension or numba, not forced off).
    Callers ask their own kernel (:meth:`Kernel.available`)."""
    return any(k.available() for k in KERNELS if k.exported)


# ---------------------------------------------------------------------------- signatures
_SCALARS = {"f8": (float, np.floating), "i8": (int, np.integer), "b1": (bool, np.bool_)}
_DTYPES = {"f8": np.dtype(np.float64), "i8": np.dtype(np.int64), "b1": np.dtype(np.bool_)}


@dataclass(frozen=True)
class ArgType:
    """One declared argument type: ``f8``, ``i8`` or ``b1``, a scalar or a C-ordered array
    (``f8[::1]``, ``f8[:, ::1]``, ``f8[:, :, ::1]``, ``b1[::1]``)."""

    text: str
    kind: str
    ndim: int

    @classmethod
    def parse(cls, text: str) -> ArgType:
        m = re.fullmatch(r"(f8|i8|b1)(?:\[((?::,\s*)*)::1\])?", text.strip())
        if m is None:
            raise ValueError(f"kernel argument type {text!r}: use f8, i8, b1 or a C-ordered "
                             "array of them such as f8[:, ::1]")
        ndim = 0 if m.group(2) is None else m.group(2).count(":") + 1
        return cls(text.strip(), m.group(1), ndim)

    def problem(self, value: Any) -> str | None:
        """Why ``value`` does not have this type (None: it has)."""
        if self.ndim == 0:
            ok = isinstance(value, _SCALARS[self.kind])
            if self.kind != "b1" and isinstance(value, (bool, np.bool_)):
                ok = False
            return None if ok else f"{type(value).__name__} {value!r}"
        if not isinstance(value, np.ndarray):
            return type(value).__name__
        if value.dtype != _DTYPES[self.kind] or value.ndim != self.ndim:
            return f"{value.dtype} array of {value.ndim} dimensions"
        if not value.flags.c_contiguous:
            return "an array not in C order"
        if not value.flags.writeable:
            return "a read-only array"
        return None


class Kernel:
    """``fn`` with its declared signature, run on the backend :func:`backend` picks."""

    def __init__(self, fn: Callable[..., Any], returns: str | None = None,
                 args: dict[str, str] | None = None) -> None:
        self.fn = fn
        self.name = fn.__name__.lstrip("_")
        self.module = fn.__module__
        self.returns = returns
        self.per_sample_step = False
        """Called once per sample (:meth:`per_sample`): compiled only from the extension in
        ``auto`` mode (set by :func:`per_sample_kernel`)."""
        self._modules: list[str] | None = None
        self.args: dict[str, ArgType] | None = None
        if args is not None:
            names = fn.__code__.co_varnames[:fn.__code__.co_argcount]
            if tuple(args) != names:
                raise TypeError(f"kernel {self.name}: declared arguments {tuple(args)} are not "
                                f"its parameters {names}")
            self.args = {n: ArgType.parse(t) for n, t in args.items()}

    def modules(self) -> list[str]:
        """The modules whose source this kernel's compiled code comes from: its own and
        those of the helper kernels it calls, transitively (what its fingerprint covers).
        Worked out once, before a compilation points the helpers' names elsewhere."""
        if self._modules is None:
            found = [self.module]
            for name in self.fn.__code__.co_names:
                helper = self.fn.__globals__.get(name)
                if isinstance(helper, Kernel):
                    found += [m for m in helper.modules() if m not in found]
            self._modules = found
        return self._modules

    @property
    def exported(self) -> bool:
        """Called from Python (declared signature), so built into the AOT extension; a
        helper kernel without one is compiled into the kernels that call it."""
        return self.args is not None

    def signature(self) -> str:
        """The numba signature string, e.g. ``Tuple((f8[::1], f8))(f8[::1], b1)``."""
        assert self.args is not None and self.returns is not None
        return f"{self.returns}({', '.join(a.text for a in self.args.values())})"

    def available(self) -> bool:
        """True when this kernel runs compiled; False: the caller runs its Python path."""
        return self.choice().backend != "python"

    def backend(self) -> str:
        """``aot``, ``jit`` or ``python``, for the current environment."""
        return self.choice().backend

    def choice(self) -> Choice:
        """The backend for the current environment and why (raises KernelUnavailable when
        ``IMUHAL_KERNELS`` forces one this kernel cannot use)."""
        return _choose(self, mode(), _kernel_dir_key())

    def per_sample(self) -> Callable[..., Any] | None:
        """The compiled function for a caller that runs it once per sample, or None: run
        the Python step. Only the AOT extension's function is worth calling per sample in
        ``auto`` mode: a call to it costs about 0.1-0.2 us, while numba's dispatcher costs
        about 1.7 us per call, more than a Python step saves (docs/performance.md, "The
        compiled per-sample step"). ``IMUHAL_KERNELS=jit`` forces the JIT here too (for
        tests and benchmarks). The function is returned unchecked: the caller passes only
        the declared scalars (Python floats and bools it built itself), since a check per
        call would cost more than the call."""
        choice = self.choice()
        if choice.backend == "aot":
            return choice.function
        if choice.backend == "jit" and mode() == "jit":
            return _jitted(self)
        return None

    def check(self, args: tuple[Any, ...]) -> None:
        """Raise TypeError naming the argument when ``args`` do not match the signature."""
        assert self.args is not None
        if len(args) != len(self.args):
            raise TypeError(f"kernel {self.name}: {len(args)} arguments for {len(self.args)}")
        for (name, t), value in zip(self.args.items(), args, strict=True):
            problem = t.problem(value)
            if problem is not None:
                raise TypeError(f"kernel {self.name}: argument {name} must be {t.text}, "
                                f"got {problem}")

    def __call__(self, *args: Any) -> Any:
        choice = self.choice()
        if choice.backend == "python":
            raise RuntimeError(f"kernel {self.name} called without a compiled backend: the "
                               "caller must check available() first")
        if self.args is not None:
            self.check(args)
        fn = choice.function if choice.backend == "aot" else _jitted(self)
        return fn(*args)  # type: ignore[misc]  # an 'aot' choice always carries its loaded function


@dataclass(frozen=True)
class Choice:
    """A kernel's backend and why it was chosen (what ``imuhal kernels status`` shows)."""

    backend: str
    reason: str
    function: Callable[..., Any] | None = None
    """The extension's function (aot only; the JIT compiles on the first call)."""


KERNELS: list[Kernel] = []
"""Every kernel defined so far (its module imported), in definition order."""


def jit(fn: Callable[..., Any], returns: str | None = None, **args: str) -> Kernel:
    """The kernel of ``fn``. A kernel called from Python declares its return type and every
    argument's type (names in order, checked against ``fn``'s parameters); a helper called
    only by other kernels declares none."""
    kernel = Kernel(fn, returns, args or None)
    KERNELS.append(kernel)
    return kernel


def per_sample_kernel(kernel: Kernel) -> Kernel:
    """Mark ``kernel`` as a per-sample step (see :meth:`Kernel.per_sample`); returns it."""
    kernel.per_sample_step = True
    return kernel


def c_array(values: Any) -> np.ndarray:
    """``values`` as a writable C-ordered float64 array (a copy only when needed): what a
    kernel's ``f8[...::1]`` argument takes."""
    return np.require(values, dtype=np.float64, requirements=["C", "W"])


def _kernel_dir_key() -> str:
    # the selection depends on where extensions are looked for (tests point it elsewhere)
    return os.environ.get("IMUHAL_KERNEL_DIR", "") + "\0" + os.environ.get("XDG_CACHE_HOME", "")


@cache
def _choose(kernel: Kernel, chosen: str, dir_key: str) -> Choice:
    """The backend for ``kernel`` under ``chosen`` (auto or forced); imports no numba."""
    if chosen == "python":
        return Choice("python", "IMUHAL_KERNELS=python or IMUHAL_NO_JIT=1")
    why_not_aot = "a helper kernel: compiled into the kernels that call it"
    if kernel.exported and chosen in ("auto", "aot"):
        from imuhal_filters.common import aot

        found = aot.find(kernel)
        if found.function is not None:
            return Choice("aot", found.reason, found.function)
        why_not_aot = found.reason
    if chosen == "aot":
        raise KernelUnavailable(
            f"IMUHAL_KERNELS=aot, but kernel {kernel.name} has no usable extension "
            f"({why_not_aot}): run `imuhal kernels build` or unset IMUHAL_KERNELS")
    # "no extension built in DIR (run ...)" says it once, with the fix; any other reason is
    # why there is no extension to serve this kernel
    if not why_not_aot.startswith("no extension built"):
        why_not_aot = f"no extension ({why_not_aot})"
    if _INSTALLED:
        return Choice("jit", "numba installed" if chosen == "jit" else
                      f"{why_not_aot}; numba installed")
    if chosen == "jit":
        raise KernelUnavailable("IMUHAL_KERNELS=jit needs numba: pip install -e '.[fast]'")
    return Choice("python", f"{why_not_aot}; numba not installed")


def swap_helpers(fn: Callable[..., Any], compile_helper: Callable[[Kernel], Any]) -> None:
    """Point ``fn``'s module names for helper kernels at their compiled form: numba needs
    them compiled before it types the caller (``compile_helper`` compiles one, recursively
    through its own helpers)."""
    for name in fn.__code__.co_names:
        helper = fn.__globals__.get(name)
        if isinstance(helper, Kernel):
            swap_helpers(helper.fn, compile_helper)
            fn.__globals__[name] = compile_helper(helper)


@cache
def _jitted(kernel: Kernel) -> Callable[..., Any]:
    """``kernel`` compiled by numba (no Python objects, cached on disk), with its declared
    signature when it has one."""
    import numba

    # numba's on-disk cache notices a change to the kernel's own file only: a kernel that
    # calls a helper of another module (common/fast_frames.py) is compiled afresh per process
    cache = len(kernel.modules()) == 1  # while the helpers' names still name them
    swap_helpers(kernel.fn, _jitted)
    if kernel.exported:
        return numba.njit(kernel.signature(), cache=cache, nogil=True)(kernel.fn)
    return numba.njit(cache=cache, nogil=True)(kernel.fn)
