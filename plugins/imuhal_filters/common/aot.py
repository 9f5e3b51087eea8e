"""Where the ahead-of-time compiled kernels live, their fingerprint, and loading them.

``imuhal kernels build`` (:mod:`imuhal_filters.common.aot_build`) compiles every kernel of
:data:`KERNEL_MODULES` with ``numba.pycc`` into one CPython extension in the kernel directory:
``$IMUHAL_KERNEL_DIR``, else ``$XDG_CACHE_HOME/imuhal/kernels``, else
``~/.cache/imuhal/kernels``. Next to it, a manifest (JSON) records what it was built from:
the SHA-256 of each kernel module's source and of the build's own sources, the extension
suffix (Python version and ABI, platform), numpy's version and numba's. Both files are named
with the fingerprint, a hash of that record.

A kernel runs from an extension only when the record matches now: its module's source and
that of every module whose helper kernels it calls (``common/fast_ahrs.py``'s gate and row
loop, ``common/fast_frames.py``), the shared sources, this Python, this numpy, and the
installed numba (an extension needs no numba at run time: when numba is absent, the numba it
was built with is accepted). A kernel edited after the build runs on the JIT or in Python
until the next build, never stale compiled code; the other kernels keep their extension.
Nothing here imports numba.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import json
import os
import sys
import sysconfig
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from imuhal_filters.common.fast import Kernel

KERNEL_MODULES = (
    "imuhal_filters.madgwick.fast",
    "imuhal_filters.mahony.fast",
    "imuhal_filters.imufilter.fast",
    "imuhal_filters.freescale.fast",
    "imuhal_filters.vario.fast",
    "imuhal_filters.decoupled.fast",
)
"""Every module with kernels: the build compiles the exported kernels of each."""

SHARED_MODULES = ("imuhal_filters.common.fast", "imuhal_filters.common.aot_build")
"""Sources every extension depends on besides the kernels' own (signatures, build flags)."""

FORMAT = 1
"""Version of the manifest and of the extension's layout (exported names)."""

PREFIX = "imuhal_kernels_"


def kernel_dir() -> Path:
    """The directory extensions are built into and loaded from."""
    override = os.environ.get("IMUHAL_KERNEL_DIR")
    if override:
        return Path(override).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "imuhal" / "kernels"


def ext_suffix() -> str:
    """The extension file suffix: Python version, ABI and platform (``.cpython-311-...so``)."""
    return str(sysconfig.get_config_var("EXT_SUFFIX") or ".so")


@cache
def numba_version() -> str | None:
    """The installed numba's version (read from its metadata, not imported), or None."""
    try:
        return importlib.metadata.version("numba")
    except importlib.metadata.PackageNotFoundError:
        return None


def environment(numba: str | None) -> dict[str, Any]:
    """What an extension's compiled code depends on besides its sources."""
    return {"ext_suffix": ext_suffix(), "numpy": np.__version__, "numba": numba}


@cache
def source_hash(module: str) -> str:
    """SHA-256 of a module's source file (found without importing it)."""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ImportError(f"no module {module}")
    return hashlib.sha256(Path(spec.origin).read_bytes()).hexdigest()


def shared_hash() -> str:
    return hashlib.sha256("".join(source_hash(m) for m in SHARED_MODULES).encode()).hexdigest()


def fingerprint(record: dict[str, Any]) -> str:
    """The name-giving hash of a manifest's record (everything but the file names)."""
    keys = ("format", "env", "shared", "sources", "kernels")
    body = json.dumps({k: record.get(k) for k in keys}, sort_keys=True)
    return hashlib.sha256(body.encode()).hexdigest()[:20]


@dataclass(frozen=True)
class Manifest:
    """One built extension, as its manifest describes it."""

    path: Path
    """The manifest file (``imuhal_kernels_<fingerprint>.json``)."""
    record: dict[str, Any]

    @property
    def module_name(self) -> str:
        return self.path.stem

    @property
    def extension(self) -> Path:
        return self.path.with_name(self.module_name + str(self.record["env"]["ext_suffix"]))

    def intact(self) -> bool:
        """The extension's bytes are the ones built (SHA-256 in the manifest)."""
        return _file_hash(self.extension) == self.record.get("extension_sha256")

    def mismatch(self, kernel: Kernel) -> str | None:
        """Why ``kernel`` cannot run from this extension now (None: it can)."""
        env, now = self.record["env"], environment(numba_version())
        if env["ext_suffix"] != now["ext_suffix"]:
            return f"built for another Python ({env['ext_suffix']})"
        if env["numpy"] != now["numpy"]:
            return f"built for numpy {env['numpy']}, this is numpy {now['numpy']}"
        if now["numba"] is not None and env["numba"] != now["numba"]:
            return f"built with numba {env['numba']}, numba {now['numba']} is installed"
        if self.record["kernels"].get(kernel.name) != kernel.module:
            return f"it has no kernel {kernel.name}"
        for module in kernel.modules():
            if self.record["sources"].get(module) != source_hash(module):
                return (f"stale: built for other sources ({module.replace('.', '/')}.py "
                        "changed since)")
        if self.record["shared"] != shared_hash():
            return "stale: built for other sources (common/fast.py or common/aot_build.py)"
        return None


def manifests(directory: Path) -> list[Manifest]:
    """The valid manifests in ``directory``, newest first (a manifest whose name is not its
    record's fingerprint, or whose extension is missing, is ignored)."""
    found = []
    try:
        paths = list(directory.glob(PREFIX + "*.json"))
    except OSError:
        return []
    for path in paths:
        try:
            record = json.loads(path.read_text())
            if record.get("format") != FORMAT or path.stem != PREFIX + fingerprint(record):
                continue
            m = Manifest(path, record)
            if m.extension.is_file():
                found.append((path.stat().st_mtime, m))
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue
    return [m for _, m in sorted(found, key=lambda x: x[0], reverse=True)]


@dataclass(frozen=True)
class Found:
    """The extension's function for a kernel, or why there is none."""

    function: Callable[..., Any] | None
    reason: str
    manifest: Manifest | None = None


def find(kernel: Kernel, directory: Path | None = None) -> Found:
    """``kernel``'s compiled function from the newest matching extension in ``directory``
    (default :func:`kernel_dir`)."""
    d = kernel_dir() if directory is None else directory
    candidates = manifests(d)
    if not candidates:
        return Found(None, f"no extension built in {d} (run `imuhal kernels build`)")
    reasons = []
    for m in candidates:
        why = m.mismatch(kernel)
        if why is None and not m.intact():
            # loading a damaged shared object can kill the process (SIGBUS), so check first
            why = f"damaged: {m.extension.name} is not the file its manifest describes"
        if why is None:
            try:
                module = load(m.extension, m.module_name)
            except (ImportError, OSError) as exc:
                why = f"cannot load {m.extension.name}: {exc}"
            else:
                fn = getattr(module, kernel.name, None)
                if fn is not None:
                    return Found(fn, f"extension {m.extension.name}", m)
                why = f"{m.extension.name} lacks {kernel.name}"
        reasons.append(why)
    return Found(None, reasons[0])


def _file_hash(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


@cache
def load(path: Path, name: str) -> Any:
    """Import the extension at ``path`` as module ``name`` (once per process)."""
    if name in sys.modules:
        return sys.modules[name]
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, str(path), loader=loader)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    sys.modules[name] = module
    return module
