#!/usr/bin/env python3
"""Run tests/kernel inside a small Linux guest booted by virtme-ng; exit with the guest's code.

    python tests/kernel/run.py [PYTEST ARGS...]

What it does, in order (it installs nothing; a missing tool is a one-line error, exit 2):

1. Builds ONCE a small x86-64 kernel from Debian's ``linux-source-6.1`` package (the tarball in
   /usr/src) with virtme-ng's guest config plus tests/kernel/kernel.config (gpio-sim,
   gpio-mockup, i2c-stub, IIO configfs + dummy + hrtimer/sysfs triggers, spidev, Bluetooth with
   the virtual HCI driver). The result is cached in ``~/.cache/imuhal/kernel/<hash>`` (``<hash>``:
   the first 16 hex digits of the fragment's SHA-256; ``$XDG_CACHE_HOME`` is honoured), so only
   an edit of the fragment rebuilds (about 13 minutes on 2 cores).
2. Builds the project's own test modules (tests/kernel/modules) against that kernel, cached by
   the hash of their sources.
3. Decides between KVM and TCG: /dev/kvm is used only if a guest really boots with it within
   a time limit (on some hosts /dev/kvm is a software hypervisor that never gets past the
   decompressor); the verdict is remembered until the host reboots.
4. Boots the guest with the host's root file system shared read-only, so this venv's Python
   runs inside unchanged, and runs ``python -m pytest tests/kernel`` there as root with
   IMUHAL_KERNEL_GUEST=1 and IMUHAL_KERNEL_MODULES=<folder of the .ko files>.

Needs: Debian packages qemu-system-x86 busybox-static udev linux-source-6.1 gcc make bc flex
bison libelf-dev libssl-dev cpio kmod, and ``pip install -e ".[kernel]"`` (virtme-ng).
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
from collections.abc import Iterator
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
FRAGMENT = HERE / "kernel.config"
MODULES_SRC = HERE / "modules"
SOURCE_TARBALL = Path("/usr/src/linux-source-6.1.tar.xz")
SOURCE_DIR_NAME = "linux-source-6.1"
#: what the guest needs from the kernel build, copied beside the cached tree's top
KERNEL_ARTIFACTS = {"bzImage": "arch/x86/boot/bzImage", "i2c-stub.ko": "drivers/i2c/i2c-stub.ko"}
KVM_PROBE_TIMEOUT_S = 40.0
GUEST_TIMEOUT_S = 1800.0
EXIT_USAGE = 2


class SetupError(Exception):
    """A missing tool or package: one line naming it and how to get it."""


def _log(message: str) -> None:
    print(f"[kernel-tests] {message}", file=sys.stderr, flush=True)


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "imuhal" / "kernel"


def fragment_hash() -> str:
    return hashlib.sha256(FRAGMENT.read_bytes()).hexdigest()[:16]


def modules_hash(kernel_dir: Path) -> str:
    digest = hashlib.sha256(kernel_dir.name.encode())
    for path in sorted(MODULES_SRC.iterdir()):
        if path.is_file():
            digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _venv_tool(name: str) -> str | None:
    """A console script of this interpreter's environment first, then PATH."""
    beside = Path(sys.executable).parent / name
    if beside.exists():
        return str(beside)
    return shutil.which(name)


def check_build_tools() -> None:
    """Everything the kernel and module builds need, or SetupError naming the first missing."""
    apt = "sudo apt-get install {}"
    for tool, package in (("make", "make"), ("gcc", "gcc"), ("bc", "bc"), ("flex", "flex"),
                          ("bison", "bison"), ("cpio", "cpio")):
        if shutil.which(tool) is None:
            raise SetupError(f"'{tool}' not found (kernel build): {apt.format(package)}")
    for header, package in (("/usr/include/gelf.h", "libelf-dev"),
                            ("/usr/include/openssl/opensslv.h", "libssl-dev")):
        if not Path(header).exists():
            raise SetupError(f"{header} not found (kernel build): {apt.format(package)}")
    if not SOURCE_TARBALL.exists():
        raise SetupError(f"{SOURCE_TARBALL} not found (kernel source): "
                         f"{apt.format('linux-source-6.1')}")
    if _venv_tool("virtme-configkernel") is None:
        raise SetupError("virtme-configkernel not found (guest kernel config): "
                         "pip install -e \".[kernel]\"")


def check_run_tools() -> None:
    """Everything booting the guest needs, or SetupError naming the first missing."""
    if _venv_tool("vng") is None:
        raise SetupError("vng (virtme-ng) not found: pip install -e \".[kernel]\"")
    if shutil.which("qemu-system-x86_64") is None:
        raise SetupError("qemu-system-x86_64 not found: sudo apt-get install qemu-system-x86")
    if shutil.which("busybox") is None:
        raise SetupError("busybox not found (virtme-ng's guest init): "
                         "sudo apt-get install busybox-static")
    if not any(Path(p).exists() for p in ("/lib/systemd/systemd-udevd",
                                            "/usr/lib/systemd/systemd-udevd")):
        raise SetupError("systemd-udevd not found (virtme-ng's guest needs it for the "
                         "command's I/O ports and exit code): sudo apt-get install udev")
    if shutil.which("insmod") is None and not Path("/usr/sbin/insmod").exists():
        raise SetupError("insmod not found (loads the test modules in the guest): "
                         "sudo apt-get install kmod")


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """One builder at a time per cache entry (two CI jobs or two shells)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _run_logged(cmd: list[str], cwd: Path, log: Path) -> None:
    with open(log, "a") as out:
        out.write(f"\n+ {' '.join(cmd)}\n")
        out.flush()
        result = subprocess.run(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT, check=False)
    if result.returncode != 0:
        tail = "\n".join(log.read_text(errors="replace").splitlines()[-25:])
        raise RuntimeError(f"{' '.join(cmd[:3])} failed (rc={result.returncode}), "
                           f"log {log}:\n{tail}")


def _jobs() -> str:
    return str(len(os.sched_getaffinity(0)))


def build_kernel(root: Path) -> Path:
    """The cached kernel folder for the current fragment, built first when absent."""
    entry = root / fragment_hash()
    done = entry / "complete"
    if done.exists():
        return entry
    check_build_tools()
    with _locked(root / f"{entry.name}.lock"):
        if done.exists():
            return entry
        if entry.exists():
            shutil.rmtree(entry)  # a build that died half-way: start clean
        entry.mkdir(parents=True)
        log = entry / "build.log"
        _log(f"building the guest kernel once into {entry} (about 13 min on 2 cores; "
             f"log {log})")
        started = time.monotonic()
        with tarfile.open(SOURCE_TARBALL) as tar:
            if hasattr(tarfile, "fully_trusted_filter"):  # Python >= 3.11.4 asks
                tar.extractall(entry, filter="fully_trusted")
            else:
                tar.extractall(entry)
        tree = entry / SOURCE_DIR_NAME
        shutil.copy(FRAGMENT, entry / "kernel.config")
        _run_logged([_venv_tool("virtme-configkernel") or "virtme-configkernel",
                     "--defconfig", "--custom", str(FRAGMENT)], tree, log)
        # virtme-configkernel appends its own generic options after the fragment (debug info
        # among them): merge the fragment again so that it has the last word
        _run_logged(["scripts/kconfig/merge_config.sh", "-m", ".config", str(FRAGMENT)],
                    tree, log)
        _run_logged(["make", "olddefconfig"], tree, log)
        _run_logged(["nice", "-n", "10", "make", f"-j{_jobs()}", "bzImage", "modules"],
                    tree, log)
        for name, rel in KERNEL_ARTIFACTS.items():
            shutil.copy(tree / rel, entry / name)
        seconds = time.monotonic() - started
        (entry / "build-seconds").write_text(f"{seconds:.0f}\n")
        done.write_text(f"{SOURCE_TARBALL} + {FRAGMENT.name} in {seconds:.0f} s\n")
        _log(f"kernel built in {seconds:.0f} s")
    return entry


def build_modules(entry: Path) -> Path:
    """The project's test modules built against the cached kernel tree (cached by source)."""
    out = entry / "modules" / modules_hash(entry)
    if (out / "complete").exists():
        return out
    with _locked(entry / "modules.lock"):
        if (out / "complete").exists():
            return out
        if out.exists():
            shutil.rmtree(out)
        shutil.copytree(MODULES_SRC, out)
        log = out / "build.log"
        _run_logged(["make", "-C", str(entry / SOURCE_DIR_NAME), f"M={out}", "modules"],
                    out, log)
        # the kernel's own module-only test driver travels with them
        shutil.copy(entry / "i2c-stub.ko", out / "i2c-stub.ko")
        (out / "complete").write_text("ok\n")
    return out


def _boot_id() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return "unknown"


def _vng_command(kernel: Path, command: str, *, kvm: bool, extra: list[str]) -> list[str]:
    cmd = [_venv_tool("vng") or "vng", "--run", str(kernel), "--user", "root",
           "--memory", "1G", "--cpus", "2"]
    if not kvm:
        cmd.append("--disable-kvm")
    return cmd + extra + ["--exec", command]


def _run_guest(cmd: list[str], timeout_s: float, env: dict[str, str] | None = None,
               capture: bool = False) -> tuple[int | None, str]:
    """Run vng in its own session; on timeout kill the whole group (vng otherwise leaves its
    QEMU child running). Returns (exit code or None on timeout, captured output)."""
    if env is None:  # vng runs virtme-run from PATH: this environment's scripts first
        env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, start_new_session=True, env=env,
                            stdout=subprocess.PIPE if capture else None,
                            stderr=subprocess.STDOUT if capture else None, text=capture)
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return None, ""
    return proc.returncode, out or ""


def kvm_usable(entry: Path) -> tuple[bool, str]:
    """Whether /dev/kvm really boots this guest: a trial boot with a time limit (a software
    hypervisor such as kvm_pvm exposes /dev/kvm but crawls through an ordinary kernel's
    decompressor for minutes). The verdict is cached per host boot."""
    if os.environ.get("IMUHAL_KERNEL_KVM") in ("0", "1"):
        forced = os.environ["IMUHAL_KERNEL_KVM"] == "1"
        return forced, f"IMUHAL_KERNEL_KVM={int(forced)}"
    if not os.access("/dev/kvm", os.R_OK | os.W_OK):
        return False, "no usable /dev/kvm"
    verdict = entry / f"kvm-{_boot_id()}"
    if verdict.exists():
        return verdict.read_text().strip() == "yes", f"cached trial boot ({verdict.name})"
    marker = "imuhal-kvm-probe-ok"
    started = time.monotonic()
    code, out = _run_guest(_vng_command(entry / "bzImage", f"echo {marker}", kvm=True,
                                        extra=[]), KVM_PROBE_TIMEOUT_S, capture=True)
    ok = code == 0 and marker in out
    verdict.write_text("yes\n" if ok else "no\n")
    took = time.monotonic() - started
    return ok, (f"trial boot with KVM {'passed' if ok else 'failed'} in {took:.0f} s"
                + ("" if ok else f" (rc={code}; limit {KVM_PROBE_TIMEOUT_S:.0f} s)"))


def guest_command(modules: Path, pytest_args: list[str]) -> str:
    """The shell line the guest runs: pytest of tests/kernel with the guest's markers set."""
    import shlex

    if not any(a.startswith("tests/kernel") for a in pytest_args):
        pytest_args = [*pytest_args, "tests/kernel"]  # options alone: still only this suite
    args = " ".join(shlex.quote(a) for a in pytest_args)
    return (f"cd {shlex.quote(str(REPO))} && "
            f"IMUHAL_KERNEL_GUEST=1 IMUHAL_KERNEL_MODULES={shlex.quote(str(modules))} "
            f"PYTHONDONTWRITEBYTECODE=1 {shlex.quote(sys.executable)} -m pytest "
            f"-p no:cacheprovider {args}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Build (once, cached) a small kernel and run pytest tests/kernel inside "
                    "a virtme-ng guest; exits with the guest's exit code.")
    parser.add_argument("--build-only", action="store_true",
                        help="build (or find) the cached kernel and modules, then stop")
    parser.add_argument("--timeout", type=float, default=GUEST_TIMEOUT_S,
                        help="seconds before the guest is killed (default %(default)s)")
    parser.add_argument("pytest_args", nargs=argparse.REMAINDER,
                        help="arguments for pytest inside the guest (default: tests/kernel)")
    args, unknown = parser.parse_known_args(argv)  # pytest's own options pass through
    args.pytest_args = unknown + args.pytest_args
    try:
        if not args.build_only:
            check_run_tools()
        entry = build_kernel(cache_root())
        modules = build_modules(entry)
    except SetupError as exc:
        print(f"kernel-tests: {exc}", file=sys.stderr)
        return EXIT_USAGE
    _log(f"kernel {entry}, modules {modules}")
    if args.build_only:
        return 0
    kvm, why = kvm_usable(entry)
    _log(f"{'KVM' if kvm else 'TCG (no KVM)'}: {why}")
    command = guest_command(modules, [a for a in args.pytest_args if a != "--"])
    started = time.monotonic()
    # virtme-ng gives the guest a fresh /tmp: folders there are shared explicitly
    shared = [f"--rodir={p}" for p in (REPO, modules) if Path("/tmp") in p.parents]
    code, _ = _run_guest(_vng_command(entry / "bzImage", command, kvm=kvm, extra=shared),
                         args.timeout)
    took = time.monotonic() - started
    if code is None:
        _log(f"guest killed after {args.timeout:.0f} s")
        return 1
    _log(f"guest exit code {code} after {took:.0f} s")
    return code


if __name__ == "__main__":
    sys.exit(main())
