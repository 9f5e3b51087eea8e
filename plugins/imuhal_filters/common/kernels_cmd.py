"""``imuhal kernels build|status``: the ahead-of-time compiled kernels (a plugin command).

``build`` compiles every kernel into one extension in the kernel directory (needs numba and a
C compiler: ``pip install -e ".[fast]"``); ``status`` shows which backend each kernel uses
now (aot, jit or python) and why. See docs/performance.md, "Ahead-of-time kernels".
"""

from __future__ import annotations

import argparse
import importlib

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal.plugins.registry import Command, Registry
from imuhal_filters.common import aot, fast


class KernelsCommand(Command):
    name = "kernels"
    help = "build the ahead-of-time compiled kernels, or show which backend each kernel uses"
    description = ("build: compile every estimator kernel into one extension (needs numba and a "
                   "C compiler; pip install -e '.[fast]'), so that runs need no numba; "
                   "status: which backend (aot, jit, python) each kernel uses, and why. "
                   "IMUHAL_KERNEL_DIR sets where extensions live; IMUHAL_KERNELS=aot|jit|"
                   "python|auto forces a backend.")

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
        actions.add_parser("build", help="compile every kernel into the kernel directory")
        actions.add_parser("status", help="which backend each kernel uses, and why")

    def run(self, args: argparse.Namespace, registry: Registry) -> int:
        if args.action == "build":
            return build()
        return status()


def build() -> int:
    from imuhal_filters.common import aot_build

    built = aot_build.build()
    print(f"built {len(built.kernels)} kernels into {built.extension} "
          f"in {built.seconds:.1f} s: {', '.join(built.kernels)}")
    return 0


def status() -> int:
    """One line per kernel: its backend now and why (a forced backend it cannot use: the
    reason, not an error)."""
    chosen = fast.mode()  # a mistaken IMUHAL_KERNELS: the one-line error, nothing else
    for module in aot.KERNEL_MODULES:
        importlib.import_module(module)
    print(f"kernel directory: {aot.kernel_dir()}")
    print(f"selection: {chosen} (IMUHAL_KERNELS)")
    kernels = sorted((k for k in fast.KERNELS if k.exported),
                     key=lambda k: aot.KERNEL_MODULES.index(k.module))
    for kernel in kernels:
        try:
            choice = kernel.choice()
            backend, reason = choice.backend, choice.reason
        except fast.KernelUnavailable as exc:
            backend, reason = "none", str(exc)
        if kernel.per_sample_step and backend == "jit" and chosen == "auto":
            backend, reason = "python", (f"{reason}; a per-sample step runs compiled only "
                                         "from the extension (IMUHAL_KERNELS=jit forces it)")
        print(f"  {kernel.name:<16} {backend:<7} {reason}")
    return 0


@hookimpl
def imuhal_register_commands(register: Registrar) -> None:
    register(KernelsCommand)
