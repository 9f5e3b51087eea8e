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

import hashlib
import importlib.util
import os
import re
import types
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any, Literal

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
        self.inline: Literal["never", "always"] = "never"
        """numba's ``inline`` for a helper kernel (:func:`inline_kernel` sets ``always``)."""
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
        those of the helper kernels it calls (module globals or closure variables, as
        ``common.fast_ahrs.ahrs_rows`` makes them), transitively (what its fingerprint and
        its JIT cache key cover)."""
        if self._modules is None:
            found = [self.module]
            for helper in _helpers(self.fn):
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

    def unchecked(self) -> Callable[..., Any]:
        """The compiled function for the current environment, for a caller that calls it
        many times with arguments it builds itself (an AHRS's row kernel, once per fusion
        step): ``__call__`` looks up the backend (four environment reads) and checks every
        argument at each call, about 15 us together, more than a small step's whole kernel
        run. Raises RuntimeError where it runs in Python (``available()`` is False) and
        KernelUnavailable as ``choice`` does; a JIT kernel is compiled (or loaded from
        numba's cache) now."""
        choice = self.choice()
        if choice.backend == "python":
            raise RuntimeError(f"kernel {self.name} has no compiled backend here: the "
                               "caller must check available() first")
        return choice.function if choice.function is not None else _jitted(self)

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
        if not self.exported:
            # a helper called from Python (the Python path shares common/fast_ahrs.py's
            # gate): its compiled form exists only inside the kernels that call it
            return self.fn(*args)
        choice = self.choice()
        if choice.backend == "python":
            raise RuntimeError(f"kernel {self.name} called without a compiled backend: the "
                               "caller must check available() first")
        if self.args is not None:
            self.check(args)
        fn = choice.function if choice.function is not None else _jitted(self)
        return fn(*args)


@dataclass(frozen=True)
class Choice:
    """A kernel's backend and why it was chosen (what ``imuhal kernels status`` shows)."""

    backend: str
    reason: str
    function: Callable[..., Any] | None = None
    """The extension's function (aot only; the JIT compiles on the first call)."""


KERNELS: list[Kernel] = []
"""Every kernel defined so far (its module imported), in definition order."""

_BY_FUNCTION: dict[Callable[..., Any], Kernel] = {}
"""Each kernel by its plain function."""


def jit(fn: Callable[..., Any], returns: str | None = None, **args: str) -> Kernel:
    """The kernel of ``fn``. A kernel called from Python declares its return type and every
    argument's type (names in order, checked against ``fn``'s parameters); a helper called
    only by other kernels declares none."""
    kernel = Kernel(fn, returns, args or None)
    KERNELS.append(kernel)
    _BY_FUNCTION[fn] = kernel
    return kernel


def per_sample_kernel(kernel: Kernel) -> Kernel:
    """Mark ``kernel`` as a per-sample step (see :meth:`Kernel.per_sample`); returns it."""
    kernel.per_sample_step = True
    return kernel


def inline_kernel(kernel: Kernel) -> Kernel:
    """Mark the helper ``kernel`` to be inlined into its callers (numba's
    ``inline="always"``: its typed IR is copied into each caller, on the JIT and in the
    extension), so a kernel split into such helpers compiles as the one function it was. A
    helper call kept apart passes its arguments and tuples through a call each time: the
    Freescale kernel's ten per-window helpers cost 9-29 % that way (docs/performance.md).
    numba cannot inline a helper that calls a closure with ``*args``. Returns ``kernel``."""
    if kernel.exported:
        raise TypeError(f"kernel {kernel.name} is called from Python: only a helper inlines")
    kernel.inline = "always"
    return kernel


def c_array(values: Any) -> np.ndarray:
    """``values`` as a writable C-ordered float64 array (a copy only when needed): what a
    kernel's ``f8[...::1]`` argument takes."""
    if type(values) is np.ndarray and values.dtype == _F8:
        flags = values.flags
        if flags.c_contiguous and flags.writeable:
            # the usual case (a block's fresh arrays): np.require's Python wrapper, which
            # builds a set of its requirements at every call, costs more than this test
            return values
    return np.require(values, dtype=np.float64, requirements=["C", "W"])


_F8 = np.dtype(np.float64)


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


def _as_kernel(value: Any) -> Kernel | None:
    """``value`` as a helper kernel: a Kernel, or the plain function of one (a helper that
    the Python path calls too names its helpers by their plain functions)."""
    if isinstance(value, Kernel):
        return value
    try:
        return _BY_FUNCTION.get(value)
    except TypeError:  # unhashable
        return None


def _helpers(fn: Callable[..., Any]) -> list[Kernel]:
    """The helper kernels ``fn`` calls: module globals it names, and closure variables."""
    named = [fn.__globals__.get(name) for name in fn.__code__.co_names]
    enclosed = [cell.cell_contents for cell in fn.__closure__ or ()]
    return [k for k in map(_as_kernel, named + enclosed) if k is not None]


def compiled_copy(fn: Callable[..., Any], compile_helper: Callable[[Kernel], Any]
                  ) -> Callable[..., Any]:
    """A copy of ``fn`` for numba to compile: its names for helper kernels (module globals
    and closure variables, naming a Kernel or its plain function) bound to their compiled
    form (``compile_helper`` compiles one, recursively through its own helpers; numba needs
    them compiled before it types the caller). ``fn`` and its module are left as they are,
    so Python keeps calling the plain helpers (:meth:`Kernel.__call__`)."""
    named = {name: _as_kernel(fn.__globals__.get(name)) for name in fn.__code__.co_names}
    bound = {name: compile_helper(k) for name, k in named.items() if k is not None}
    cells = fn.__closure__ or ()
    enclosed = [_as_kernel(c.cell_contents) for c in cells]
    if not bound and not any(enclosed):
        return fn
    scope = {**fn.__globals__, **bound}
    closure = tuple(c if k is None else types.CellType(compile_helper(k))
                    for c, k in zip(cells, enclosed, strict=True))
    copy = types.FunctionType(fn.__code__, scope, fn.__name__, fn.__defaults__,
                              closure or None)
    copy.__qualname__, copy.__module__, copy.__doc__ = fn.__qualname__, fn.__module__, fn.__doc__
    return copy


@cache
def _jitted(kernel: Kernel) -> Callable[..., Any]:
    """``kernel`` compiled by numba (no Python objects), with its declared signature when it
    has one. A kernel called from Python is cached on disk, under a key that covers the
    sources of every module its compiled code comes from (:meth:`Kernel.modules`): numba's
    own cache notices a change to the kernel's own file only, not to a helper of another
    module (common/fast_ahrs.py). Helper kernels are not cached themselves: they are
    compiled into their callers (and then into their callers' cache entries)."""
    import numba

    fn = compiled_copy(kernel.fn, _jitted)
    if not kernel.exported:
        return numba.njit(nogil=True, inline=kernel.inline)(fn)
    dispatcher = numba.njit(nogil=True)(fn)
    _cache_by_sources(dispatcher, _sources_key(kernel.modules()))
    dispatcher.compile(kernel.signature())
    dispatcher.disable_compile()  # as numba.njit(signature) does: no other signature
    return dispatcher


def _sources_key(modules: list[str]) -> str:
    """The hash of ``modules``' sources and of this module's (how they are compiled, e.g.
    :func:`inline_kernel`)."""
    from imuhal_filters.common import aot

    every = [*modules, __name__]
    return hashlib.sha256(" ".join(aot.source_hash(m) for m in every).encode()).hexdigest()


def _cache_by_sources(dispatcher: Any, sources: str) -> None:
    """Give ``dispatcher`` numba's on-disk cache with ``sources`` added to each entry's key
    (its index key: signature, target, bytecode). This reaches into numba's cache class
    (``numba.core.caching.FunctionCache``, the one ``cache=True`` installs); a numba without
    it leaves the kernel uncached, compiled afresh per process, never stale."""
    try:
        from numba.core.caching import FunctionCache
    except ImportError:
        return
    if not hasattr(dispatcher, "_cache") or not hasattr(FunctionCache, "_index_key"):
        return

    base: Any = FunctionCache  # numba has no type information

    class SourcesCache(base):  # a subclass of numba's (untyped) class
        def _index_key(self, sig: Any, codegen: Any) -> tuple[Any, ...]:
            key: tuple[Any, ...] = super()._index_key(sig, codegen)
            return (*key, sources)

    try:
        dispatcher._cache = SourcesCache(dispatcher.py_func)
    except RuntimeError:  # numba finds no writable cache directory: run uncached
        return
