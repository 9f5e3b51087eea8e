"""What the kernel tests need from the guest: whether this is it, the test modules, configfs.

The tests in tests/kernel run against a real kernel's interfaces and only inside the guest that
tests/kernel/run.py boots: the runner sets IMUHAL_KERNEL_GUEST=1 and IMUHAL_KERNEL_MODULES
(the folder of the built .ko files), and the tests need root to load modules and write
configfs. Outside it every test skips with one line saying why; a fixture whose kernel
interface is missing (a kernel built without it) skips naming the interface.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

GUEST_ENV = "IMUHAL_KERNEL_GUEST"
MODULES_ENV = "IMUHAL_KERNEL_MODULES"
CONFIGFS = Path("/sys/kernel/config")
RUN_HINT = "python tests/kernel/run.py"


def outside_guest_reason() -> str | None:
    """Why this process is not the kernel-test guest, or None when it is."""
    if os.environ.get(GUEST_ENV) != "1":
        return f"kernel test: runs only inside the kernel-test guest ({RUN_HINT})"
    modules = os.environ.get(MODULES_ENV, "")
    if not modules or not (Path(modules) / "i2c-stub.ko").is_file():
        return f"kernel test: {MODULES_ENV} does not name the built test modules ({RUN_HINT})"
    if os.geteuid() != 0:
        return "kernel test: needs root inside the guest to load modules and write configfs"
    return None


def modules_dir() -> Path:
    return Path(os.environ[MODULES_ENV])


def _run(cmd: list[str]) -> None:
    # the guest's PATH may lack the sbin folders where insmod, rmmod and mount live
    program = shutil.which(cmd[0], path=f"{os.environ.get('PATH', '')}:/usr/sbin:/sbin")
    result = subprocess.run([program or cmd[0], *cmd[1:]], capture_output=True, text=True,
                            check=False)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {result.stderr.strip()}")


@contextmanager
def loaded_module(name: str, *params: str) -> Iterator[None]:
    """``insmod`` the test module ``name``.ko with ``params``; ``rmmod`` it afterwards."""
    path = modules_dir() / f"{name}.ko"
    if not path.is_file():
        pytest.skip(f"kernel test: {path} was not built")
    _run(["insmod", str(path), *params])
    try:
        yield
    finally:
        _run(["rmmod", name.replace("-", "_")])


def i2c_device_named(name: str) -> str:
    """The /dev/i2c-N of the adapter whose sysfs name is ``name``."""
    for adapter in sorted(Path("/sys/bus/i2c/devices").glob("i2c-*")):
        if (adapter / "name").read_text().strip() == name:
            return f"/dev/{adapter.name}"
    raise RuntimeError(f"no I2C adapter named {name!r} in /sys/bus/i2c/devices")


def mounted_configfs() -> Path:
    """configfs mounted at /sys/kernel/config (virtme-ng does not mount it)."""
    if not CONFIGFS.is_dir():
        pytest.skip("kernel test: the kernel has no configfs (/sys/kernel/config)")
    if not any(CONFIGFS.iterdir()) and not os.path.ismount(CONFIGFS):
        _run(["mount", "-t", "configfs", "none", str(CONFIGFS)])
    return CONFIGFS


def wait_for(path: Path, timeout_s: float = 5.0) -> Path:
    """``path`` once it exists (udev-less devtmpfs nodes and sysfs appear asynchronously)."""
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{path} did not appear within {timeout_s} s")
        time.sleep(0.01)
    return path
