"""``imuhal kernels build``: every kernel compiled ahead of time into one extension.

numba's ``pycc`` compiles each exported kernel (the same function the JIT compiles, with the
signature declared next to it in its ``*/fast.py``) and the helper kernels it calls into a
CPython extension that needs neither numba nor LLVM at run time. It needs numba, setuptools
and a C compiler with Python's headers at build time. numba marks ``pycc`` as pending
deprecation (since 0.57: "Replacement technology is being developed"); the build silences
that warning, and a numba without ``pycc`` is reported as such (the kernels then keep running
on the JIT).

The build is atomic: it compiles in a temporary directory inside the kernel directory,
imports the result to check every kernel is there, then moves the extension and last its
manifest into place (the loader only trusts a manifest), so a failed or interrupted build
never leaves a half-written extension where it is loaded from, nor removes a good one. Code
is generated for the architecture's generic CPU (no host-specific instructions), so a
kernel directory in a shared home directory works on every machine of that architecture.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import io
import json
import os
import shutil
import sys
import sysconfig
import tempfile
import time
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from imuhal.core.errors import ImuhalError
from imuhal_filters.common import aot, fast

KEEP = 8
"""Extensions kept per Python (several checkouts may share one kernel directory); older
ones are removed after a successful build."""


class KernelBuildError(ImuhalError):
    """The build cannot run here (the message names what is missing and the fix)."""


@dataclass(frozen=True)
class Built:
    extension: Path
    kernels: tuple[str, ...]
    seconds: float


def exported_kernels() -> list[fast.Kernel]:
    """Every kernel called from Python, its module imported."""
    for module in aot.KERNEL_MODULES:
        importlib.import_module(module)
    kernels = [k for k in fast.KERNELS if k.exported and k.module in aot.KERNEL_MODULES]
    missing = [k.name for k in fast.KERNELS if k.exported and k.module not in aot.KERNEL_MODULES]
    if missing:  # a kernel module added without listing it: a bug, caught by the tests
        raise RuntimeError(f"kernels {missing} are in no module of aot.KERNEL_MODULES")
    return kernels


def _toolchain() -> Any:
    """numba's pycc compiler class, or a KernelBuildError naming what is missing."""
    try:
        import numba
    except ImportError as exc:
        raise KernelBuildError("imuhal kernels build needs numba: pip install -e '.[fast]' "
                               f"(or pip install numba) ({exc})") from exc
    try:
        import setuptools  # noqa: F401 - pycc compiles and links through it
    except ImportError as exc:
        raise KernelBuildError("imuhal kernels build needs setuptools: "
                               "pip install -e '.[fast]' (or pip install setuptools)") from exc
    try:
        with warnings.catch_warnings():  # its pending deprecation: see the module's docstring
            warnings.simplefilter("ignore", PendingDeprecationWarning)
            from numba.pycc import CC
            from numba.pycc.platform import external_compiler_works
    except ImportError as exc:
        raise KernelBuildError(
            f"numba {numba.__version__} has no numba.pycc (deprecated by numba, now "
            "removed): install a numba that has it (pip install 'numba<0.70' if your Python "
            "allows) or run without an extension (the kernels use numba's JIT, about 120 MB "
            f"more memory) ({exc})") from exc
    headers = Path(sysconfig.get_paths()["include"]) / "Python.h"
    if not headers.is_file():
        raise KernelBuildError(f"Python's C headers are missing ({headers}): install them "
                               "(Debian/Ubuntu: apt-get install python3-dev)")
    with _quiet():
        works = external_compiler_works()
    if not works:
        raise KernelBuildError("imuhal kernels build needs a working C compiler: install one "
                               "(Debian/Ubuntu: apt-get install gcc; or set CC)")
    return CC


@contextlib.contextmanager
def _quiet() -> Any:
    """Silence the compiler's chatter (it writes to the process's stdout and stderr)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        os.dup2(null.fileno(), 2)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def build(directory: Path | None = None) -> Built:
    """Compile every exported kernel into one extension in ``directory`` (default: the
    kernel directory). Raises KernelBuildError when the tools are missing or the build fails;
    what was there before is then left as it was."""
    start = time.perf_counter()
    cc_class = _toolchain()
    import numba

    d = aot.kernel_dir() if directory is None else directory
    try:
        d.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".build-", dir=d))
    except OSError as exc:
        raise KernelBuildError(f"cannot write the kernel directory {d} ({exc.strerror}): set "
                               "IMUHAL_KERNEL_DIR to a writable directory") from exc
    try:
        kernels = exported_kernels()
        record: dict[str, Any] = {
            "format": aot.FORMAT,
            "env": aot.environment(numba.__version__),
            "shared": aot.shared_hash(),
            "sources": {m: aot.source_hash(m)
                        for m in dict.fromkeys(m for k in kernels for m in k.modules())},
            "kernels": {k.name: k.module for k in kernels},
        }
        name = aot.PREFIX + aot.fingerprint(record)
        record["built_utc"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
        record["numba_pycc"] = True
        cc = cc_class(name, source_module=__name__)
        cc.output_dir = str(tmp)
        helpers: dict[int, Any] = {}

        def compile_helper(helper: fast.Kernel) -> Any:
            if id(helper) not in helpers:
                helpers[id(helper)] = numba.njit(nogil=True, inline=helper.inline)(
                    fast.compiled_copy(helper.fn, compile_helper))
            return helpers[id(helper)]

        for k in kernels:
            cc.export(k.name, k.signature())(fast.compiled_copy(k.fn, compile_helper))
        saved_tempdir = tempfile.tempdir
        tempfile.tempdir = str(tmp)  # pycc's own build directory too, removed below
        try:
            with _quiet():
                cc.compile()
        except Exception as exc:  # the compiler's own errors: name them, keep what was there
            first = (str(exc).splitlines() or [""])[0]
            raise KernelBuildError(
                f"building the kernel extension failed ({type(exc).__name__}: "
                f"{first[:300]}{'...' if len(first) > 300 else ''}); nothing was replaced, the "
                "kernels keep running as before (numba's JIT or Python)") from exc
        finally:
            tempfile.tempdir = saved_tempdir
        extension = tmp / (name + aot.ext_suffix())
        manifest = tmp / (name + ".json")
        record["extension_sha256"] = hashlib.sha256(extension.read_bytes()).hexdigest()
        manifest.write_text(json.dumps(record, indent=1, sort_keys=True))
        built = aot.load(extension, name)
        lacking = [k.name for k in kernels if not hasattr(built, k.name)]
        if lacking:
            raise KernelBuildError(f"the built extension lacks {lacking}")
        os.replace(extension, d / extension.name)
        os.replace(manifest, d / manifest.name)  # last: the loader trusts manifests only
        _prune(d)
        return Built(d / extension.name, tuple(k.name for k in kernels),
                     time.perf_counter() - start)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _prune(d: Path) -> None:
    """Remove all but the newest :data:`KEEP` extensions built for this Python."""
    mine = [m for m in aot.manifests(d) if m.record["env"]["ext_suffix"] == aot.ext_suffix()]
    for m in mine[KEEP:]:
        with contextlib.suppress(OSError):
            m.path.unlink()  # the manifest first: the extension is then never used
            m.extension.unlink()
