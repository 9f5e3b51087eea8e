"""Bluetooth LE for real: imuhal's ``--nmea ble`` peripheral on BlueZ, read by a central.

Inside the guest, with nothing of the host's: a D-Bus system bus of the test's own
(``dbus-daemon`` with a configuration in a temporary folder), BlueZ's ``btvirt`` making two
LE controllers on the kernel's virtual HCI driver (``/dev/vhci``, CONFIG_BT_HCIVHCI; the two
are linked inside btvirt, so one's advertising reaches the other's scan), ``bluetoothd`` on
that bus with a configuration of the test's own, ``imuhal run --emulate thermal --realtime
--nmea ble`` (bless's GATT server) on hci0, and a ``bleak`` central on hci1 that discovers the
Nordic UART service, subscribes to its TX characteristic, rebuilds the sentences
(concatenate, split at CR LF) and reads the Environmental Sensing pressure characteristic.
The same run also serves its sentences on a loopback TCP port (``--nmea tcp:0``), read by
the test from the start: what the central heard must be that stream's sentences, in order,
none twice, and none missing but what imuhal says it dropped for the radio.

The central's link is opened by the kernel (mgmt Add Device with auto-connect, as
``btmgmt add-device -a 2`` sends it), not by bleak's ``Device1.Connect``: BlueZ 5.66's
bluetoothd marks a link it opened itself as connected when its ATT socket connects, and if
that happens before it has read the kernel's Device Connected event (always, in the emulated
guest, where both arrive while bluetoothd is busy) it never sets the device's ``Connected``
property; bleak then sees ``Connected`` false, gives up with "failed to discover services,
device disconnected" and disconnects. Everything after the link (service discovery, the
subscription, the notifications, the read) is bleak's through bluetoothd's D-Bus GATT API.

What this does not test: a phone's Bluetooth stack and apps (XCTrack, XCSoar), radio range
and interference, pairing (the peripheral asks for none), the connection request made by
the central's own host (see above), enhanced ATT (one ATT channel, as phones use), and MTUs
above the 23-byte default (imuhal sends 20-byte notifications either way). Rates are checked
loosely: the guest is emulated (TCG), so its timing says nothing about a board's.
"""

from __future__ import annotations

import asyncio
import itertools
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from tests.sinks.nmea_reader import read_lxwp0, read_sentence

from imuhal.sinks.flight.ble import ESS_PRESSURE, ESS_SERVICE, NUS_SERVICE, NUS_TX

HERE = Path(__file__).resolve().parent
BOARD = HERE / "data" / "ble-vario.yaml"
PERIPHERAL, CENTRAL = "hci0", "hci1"
LISTEN_MAX_S = 90.0
"""How long the central listens at most, waiting for MIN_EACH of each sentence."""
MIN_EACH = 20
"""Sentences of each kind the central needs to hear (2 s of them at 10 Hz)."""

BLUETOOTHD_CONFIG = """[General]
ControllerMode = le
Privacy = off
[GATT]
Cache = no
Channels = 1
[Policy]
AutoEnable = true
"""
"""bluetoothd's main.conf for the test (``-f``): LE only, no privacy (the central connects to
the public address it scanned), no GATT cache, one ATT channel (no EATT)."""

DBUS_CONFIG = """<!DOCTYPE busconfig PUBLIC "-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN"
 "http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd">
<busconfig>
  <type>system</type>
  <listen>unix:path={socket}</listen>
  <auth>EXTERNAL</auth>
  <policy context="default">
    <allow user="*"/>
    <allow own="*"/>
    <allow send_destination="*"/>
    <allow receive_sender="*"/>
  </policy>
</busconfig>
"""


def _program(name: str, package: str) -> str:
    found = shutil.which(name, path=f"{os.environ.get('PATH', '')}:/usr/sbin:/sbin:"
                                    "/usr/libexec/bluetooth")
    if found is None:
        pytest.skip(f"kernel test: {name} not found (apt-get install {package})")
    return found


def _wait(what: str, ready: Callable[[], bool], timeout_s: float, logs: list[Path]) -> None:
    deadline = time.monotonic() + timeout_s
    while not ready():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} not ready within {timeout_s:.0f} s\n" + _tails(logs))
        time.sleep(0.1)


def _tails(logs: list[Path]) -> str:
    """The first and last lines of each log (start-up problems come first), then the last
    of the kernel's messages (with the Bluetooth core's debug lines, see _kernel_debug)."""
    out = []
    for log in logs:
        if log.exists():
            lines = log.read_text(errors="replace").splitlines()
            shown = lines if len(lines) <= 30 else [*lines[:10], "...", *lines[-20:]]
            out.append(f"--- {log.name}:\n" + "\n".join(shown))
    kernel = subprocess.run(["dmesg"], capture_output=True, text=True, check=False)
    out.append("--- kernel (dmesg, last 40 lines):\n"
               + "\n".join(kernel.stdout.splitlines()[-40:]))
    return "\n".join(out)


def _kernel_debug(on: bool) -> None:
    """The kernel Bluetooth core's pr_debug lines (HCI, L2CAP, SMP: what a failed link shows
    only there) on or off, through dynamic debug (CONFIG_DYNAMIC_DEBUG, debugfs)."""
    control = Path("/sys/kernel/debug/dynamic_debug/control")
    if not control.parent.parent.is_dir():
        return
    if not control.exists():
        subprocess.run(["mount", "-t", "debugfs", "none", "/sys/kernel/debug"],
                       capture_output=True, check=False)
    if control.exists():
        control.write_text(f"file net/bluetooth/* {'+' if on else '-'}p\n")


@dataclass
class BlueZ:
    """The running stack: the bus address for clients, the daemons' logs."""

    env: dict[str, str]
    folder: Path
    logs: list[Path] = field(default_factory=list)
    processes: list[subprocess.Popen[bytes]] = field(default_factory=list)

    def start(self, name: str, cmd: list[str]) -> subprocess.Popen[bytes]:
        log = self.folder / f"{name}.log"
        self.logs.append(log)
        with open(log, "wb") as out:
            process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out,
                                       stderr=subprocess.STDOUT, env=self.env)
        self.processes.append(process)
        return process

    def stop(self) -> None:
        for process in reversed(self.processes):
            if process.poll() is None:
                process.terminate()
                try:
                    process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()


def _adapters(dbus_send: str, env: dict[str, str]) -> dict[str, bool]:
    """BlueZ's adapters on the bus, name -> powered, as ``dbus-send`` prints them (the
    reference client of the dbus package; empty until bluetoothd answers)."""
    result = subprocess.run(
        [dbus_send, "--system", "--print-reply", "--dest=org.bluez", "/",
         "org.freedesktop.DBus.ObjectManager.GetManagedObjects"],
        capture_output=True, text=True, env=env, timeout=60, check=False)
    adapters: dict[str, bool] = {}
    current = None
    lines = result.stdout.splitlines() if result.returncode == 0 else []
    for line, following in itertools.pairwise([*lines, ""]):
        path = re.search(r'object path "/org/bluez/(hci\d+)"', line)
        if path:
            current = path.group(1)
            adapters[current] = False
        elif current and '"Powered"' in line:
            adapters[current] = "boolean true" in following
    return adapters


def _power_on(dbus_send: str, env: dict[str, str], adapter: str) -> None:
    subprocess.run([dbus_send, "--system", "--print-reply", "--dest=org.bluez",
                    f"/org/bluez/{adapter}", "org.freedesktop.DBus.Properties.Set",
                    "string:org.bluez.Adapter1", "string:Powered", "variant:boolean:true"],
                   capture_output=True, env=env, timeout=60, check=True)


def _device_connected(dbus_send: str, env: dict[str, str], path: str) -> bool:
    """bluetoothd's ``Connected`` property of the device object at ``path``."""
    result = subprocess.run(
        [dbus_send, "--system", "--print-reply", "--dest=org.bluez", path,
         "org.freedesktop.DBus.Properties.Get", "string:org.bluez.Device1",
         "string:Connected"], capture_output=True, text=True, env=env, timeout=60, check=False)
    return "boolean true" in result.stdout


def _btmgmt(btmgmt: str, index: str, *args: str) -> str:
    """What ``btmgmt --index INDEX ARGS`` prints; AssertionError if it fails. Its standard
    input stays open until it is done: at end of input btmgmt quits before the kernel's
    answer arrives, printing nothing."""
    with subprocess.Popen([btmgmt, "--index", index, *args], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as run:
        try:
            code = run.wait(timeout=60)
        except subprocess.TimeoutExpired:
            run.kill()
            raise
        out = run.stdout.read() if run.stdout else ""
    assert code == 0, f"btmgmt --index {index} {' '.join(args)}: exit {code}: {out}"
    return out


def _controller_ready(btmgmt: str, index: int) -> bool:
    """Whether the kernel's management interface lists controller ``index`` (its setup done)."""
    try:
        return "addr " in _btmgmt(btmgmt, str(index), "info")
    except AssertionError:
        return False


def _start_controllers(stack: BlueZ, btvirt: str, btmgmt: str) -> None:
    """btvirt's two LE controllers, both through the kernel's setup. The kernel resets a new
    controller at once and gives up after 2 s without an answer (``command 0x0c03 tx
    timeout``); btvirt answers only once both exist, which on a busy emulated host can take
    longer. A controller whose setup failed never reaches the management interface, so
    btvirt is started again (its controllers go away with it)."""
    attempts = 3
    for attempt in range(1, attempts + 1):
        process = stack.start(f"btvirt-{attempt}", [btvirt, "-L", "-l2"])
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and process.poll() is None:
            if all(_controller_ready(btmgmt, i) for i in (0, 1)):
                return
            time.sleep(0.5)
        process.terminate()
        process.wait(timeout=10)
        gone = time.monotonic() + 10
        while Path("/sys/class/bluetooth", PERIPHERAL).exists() and time.monotonic() < gone:
            time.sleep(0.2)
    raise AssertionError(f"btvirt's two controllers not set up in {attempts} attempts\n"
                         + _tails(stack.logs))


@pytest.fixture
def bluez(tmp_path: Path) -> Iterator[BlueZ]:
    """dbus-daemon, btvirt's two LE controllers and bluetoothd, both adapters powered."""
    pytest.importorskip("bleak", reason="kernel test: bleak not installed (pip install -e "
                                        "\".[kernel]\")")
    dbus_daemon = _program("dbus-daemon", "dbus")
    dbus_send = _program("dbus-send", "dbus")
    btvirt = _program("btvirt", "bluez-test-tools")
    btmgmt = _program("btmgmt", "bluez")
    bluetoothd = _program("bluetoothd", "bluez")
    socket = tmp_path / "system_bus_socket"
    config = tmp_path / "system-bus.conf"
    config.write_text(DBUS_CONFIG.format(socket=socket))
    main_conf = tmp_path / "main.conf"
    main_conf.write_text(BLUETOOTHD_CONFIG)
    state = tmp_path / "bluetooth-state"  # bluetoothd's storage (the guest's /var is shared)
    state.mkdir()
    address = f"unix:path={socket}"
    stack = BlueZ(dict(os.environ, DBUS_SYSTEM_BUS_ADDRESS=address), tmp_path)
    _kernel_debug(True)
    try:
        stack.start("dbus-daemon", [dbus_daemon, f"--config-file={config}", "--nofork",
                                    "--nopidfile"])
        _wait("the D-Bus system bus", socket.exists, 20, stack.logs)
        _start_controllers(stack, btvirt, btmgmt)
        stack.env["STATE_DIRECTORY"] = str(state)
        stack.start("bluetoothd", [bluetoothd, "-n", "-d", "-f", str(main_conf)])
        del stack.env["STATE_DIRECTORY"]
        # generous: under emulation on a busy host bluetoothd's start-up alone took > 60 s
        _wait("bluetoothd's two adapters",
              lambda: set(_adapters(dbus_send, stack.env)) >= {PERIPHERAL, CENTRAL}, 300,
              stack.logs)
        for adapter in (PERIPHERAL, CENTRAL):
            _power_on(dbus_send, stack.env, adapter)
        _wait("both adapters powered", lambda: all(_adapters(dbus_send, stack.env).values()),
              120, stack.logs)
        yield stack
    finally:
        stack.stop()
        _kernel_debug(False)


@dataclass
class Heard:
    """What the central received: TX notifications with their arrival times, the pressure
    characteristic read once, the services the peripheral offered."""

    tx: list[tuple[float, bytes]]
    pressure: bytes
    services: dict[str, set[str]]


async def _central(stack: BlueZ, timeout_s: float) -> Heard:
    """Scan on hci1 for the peripheral, have the kernel open the link, then discover,
    subscribe, listen and read through bleak (it finds the bus through
    DBUS_SYSTEM_BUS_ADDRESS). The module's docstring says why the kernel opens the link."""
    from bleak import BleakClient, BleakScanner
    from bleak.backends.device import BLEDevice
    from bleak.backends.scanner import AdvertisementData

    dbus_send = _program("dbus-send", "dbus")
    btmgmt = _program("btmgmt", "bluez")
    print("central: scanning on hci1", file=sys.stderr, flush=True)
    device = None
    seen: set[str] = set()

    def ours(found: BLEDevice, adv: AdvertisementData) -> bool:
        seen.add(f"{found.address} {adv.local_name!r} {adv.service_uuids}")
        return NUS_SERVICE in adv.service_uuids or adv.local_name == "imuhal vario"

    for window in (1, 2):
        device = await BleakScanner.find_device_by_filter(
            ours, timeout=timeout_s, bluez={"adapter": CENTRAL})
        if device is not None:
            break
        # what the peripheral's controller says of its advertising, for the failure below;
        # a second window, as the emulated radio of a guest on a busy host has missed one
        # whole window (CI, 2026-12-06) while imuhal's advertisement was registered
        advertising = _btmgmt(btmgmt, PERIPHERAL.removeprefix("hci"), "advinfo")
        print(f"central: scan window {window}: nothing; hci0 advinfo: {advertising}",
              file=sys.stderr, flush=True)
    assert device is not None, (f"no peripheral advertising {NUS_SERVICE} in two windows of "
                                f"{timeout_s} s; heard {sorted(seen)[:10]}")
    index = CENTRAL.removeprefix("hci")
    # -a 2: connect automatically; -t 1: an LE public address, as advertised
    _btmgmt(btmgmt, index, "add-device", "-a", "2", "-t", "1", device.address)
    path = device.details["path"]
    _wait(f"the link to {device.address}",
          lambda: _device_connected(dbus_send, stack.env, path), timeout_s, stack.logs)
    tx: list[tuple[float, bytes]] = []
    print(f"central: {device} connected; discovering", file=sys.stderr, flush=True)
    async with BleakClient(device, timeout=timeout_s, bluez={"adapter": CENTRAL}) as client:
        services = {s.uuid: {c.uuid for c in s.characteristics} for s in client.services}
        _kernel_debug(False)  # the link is up: its debug lines no longer needed
        await client.start_notify(NUS_TX, lambda _, data: tx.append((time.monotonic(),
                                                                     bytes(data))))
        # until MIN_EACH of each kind: the emulated guest on a busy host keeps real time
        # only loosely, so the listening is counted in sentences, not seconds
        started = time.monotonic()
        while (b"".join(d for _, d in tx).count(b"\r\n") < 2 * MIN_EACH + 2
               and time.monotonic() - started < LISTEN_MAX_S):
            await asyncio.sleep(0.5)
        await client.stop_notify(NUS_TX)
        pressure = bytes(await client.read_gatt_char(ESS_PRESSURE))
        # no automatic reconnection, so that bleak's disconnect can end the link
        _btmgmt(btmgmt, index, "del-device", "-t", "1", device.address)
    return Heard(tx, pressure, services)


def _sentences(tx: list[tuple[float, bytes]]) -> list[tuple[float, str]]:
    """Whole sentences with the arrival time of their last piece; the subscription may start
    inside a sentence, so bytes before the first ``$`` are not one."""
    out: list[tuple[float, str]] = []
    pending = ""
    for t, data in tx:
        pending += data.decode("ascii")
        while "\r\n" in pending:
            line, pending = pending.split("\r\n", 1)
            out.append((t, line + "\r\n"))
    first = next(i for i, (_, line) in enumerate(out) if line.startswith("$"))
    return out[first:] if out[first][1].count("$") == 1 else out[first + 1:]


class Mirror:
    """The run's loopback TCP output, read in a thread from connection to the run's end:
    every sentence imuhal sent to its flight outputs from then on."""

    def __init__(self, port: int) -> None:
        self._socket = socket.create_connection(("127.0.0.1", port), timeout=60)
        self._data = bytearray()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        self._socket.settimeout(None)
        while chunk := self._socket.recv(65536):
            self._data += chunk

    def sentences(self, timeout_s: float) -> list[str]:
        """Every whole sentence, once the run has closed the connection."""
        self._thread.join(timeout_s)
        assert not self._thread.is_alive(), "the run did not close its TCP output"
        self._socket.close()
        lines = self._data.decode("ascii").split("\r\n")[:-1]
        return [line + "\r\n" for line in lines]


def _dropped_bytes(log: str, where: str) -> int:
    """What the run said it dropped for an output (``nmea: WHERE...: N bytes dropped``)."""
    found = re.search(rf"^nmea: {where}[^\n]*: (\d+) bytes dropped", log, re.MULTILINE)
    return int(found.group(1)) if found else 0


def _skipped(heard: list[str], sent: list[str]) -> list[str]:
    """The sentences of ``sent`` the central did not hear between its first and last, for
    the placement of ``heard`` in ``sent`` (in order, each sent sentence heard at most once)
    that skips the fewest bytes: a board at rest sends the same sentence several times, so
    the first match is not always the one heard. AssertionError if ``heard`` fits nowhere
    (a sentence added, repeated or out of order)."""
    best: list[str] | None = None
    for start in (k for k, line in enumerate(sent) if line == heard[0]):
        at, places = start, [start]
        try:
            for line in heard[1:]:
                at = sent.index(line, at + 1)
                places.append(at)
        except ValueError:
            continue
        placed = set(places)
        gap = [sent[k] for k in range(start, at + 1) if k not in placed]
        if best is None or sum(map(len, gap)) < sum(map(len, best)):
            best = gap
    assert best is not None, f"what the central heard is not what imuhal sent: {heard[:6]}"
    return best


def _rate_hz(times: list[float]) -> float:
    return (len(times) - 1) / (times[-1] - times[0])


def test_a_bleak_central_reads_imuhals_sentences_and_pressure_through_bluez(
        bluez: BlueZ, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DBUS_SYSTEM_BUS_ADDRESS", bluez.env["DBUS_SYSTEM_BUS_ADDRESS"])
    imuhal = str(Path(sys.executable).parent / "imuhal")
    peripheral = bluez.start("imuhal", [
        imuhal, "run", str(BOARD), "--emulate", "thermal", "--realtime", "--duration", "600",
        "--nmea-sentences", "LK8EX1,LXWP0", "--nmea", "tcp:0", "--nmea", "ble"])
    log = bluez.folder / "imuhal.log"
    # imuhal says where its sentences go once the peripheral is registered and advertising
    # (its start-up, imports included, takes minutes in the emulated guest on a busy host)
    _wait("imuhal's peripheral", lambda: "nmea: Bluetooth LE" in log.read_text(
        errors="replace") or peripheral.poll() is not None, 600, bluez.logs)
    assert peripheral.poll() is None, _tails(bluez.logs)
    port = re.search(r"^nmea: TCP server 127\.0\.0\.1:(\d+)", log.read_text(), re.MULTILINE)
    assert port, _tails(bluez.logs)
    mirror = Mirror(int(port.group(1)))
    try:
        heard = asyncio.run(_central(bluez, timeout_s=90.0))
    except BaseException:
        print(_tails(bluez.logs), file=sys.stderr)
        raise
    finally:
        if peripheral.poll() is None:
            peripheral.send_signal(signal.SIGTERM)  # a clean stop, as a service manager's
    assert peripheral.wait(timeout=60) == 0, _tails(bluez.logs)
    sent = mirror.sentences(timeout_s=60)
    assert NUS_TX in heard.services[NUS_SERVICE]
    assert ESS_PRESSURE in heard.services[ESS_SERVICE]
    assert heard.tx and all(len(data) <= 20 for _, data in heard.tx)  # ATT MTU 23 less 3
    sentences = _sentences(heard.tx)
    heads = [read_sentence(line)[0] for _, line in sentences]  # every checksum valid
    assert set(heads) == {"LK8EX1", "LXWP0"}
    # what was heard, for the docs' figures (shown by pytest -rA)
    listened_s = heard.tx[-1][0] - heard.tx[0][0]
    print(f"central: {len(heard.tx)} notifications, {len(sentences)} sentences in "
          f"{listened_s:.1f} s", file=sys.stderr)
    for head in ("LK8EX1", "LXWP0"):
        times = [t for (t, _), h in zip(sentences, heads, strict=True) if h == head]
        print(f"central: {head} x {len(times)} at {_rate_hz(times):.2f} Hz (wall clock)",
              file=sys.stderr)
        assert len(times) >= MIN_EACH
    # what the central heard is what imuhal sent, in order, nothing twice and nothing
    # missing but what imuhal says it dropped because the radio fell behind (the same
    # sentences went to the TCP output, which the test read from before the subscription)
    run_log = log.read_text(errors="replace")
    assert _dropped_bytes(run_log, "TCP server") == 0, "the test's TCP reader fell behind"
    skipped = _skipped([line for _, line in sentences], sent)
    dropped = _dropped_bytes(run_log, "Bluetooth LE")
    print(f"central: {len(sent)} sentences sent on TCP; {len(skipped)} between the first and "
          f"last heard not heard; imuhal dropped {dropped} bytes for BLE", file=sys.stderr)
    assert sum(len(line) for line in skipped) <= dropped, skipped[:4]
    lxwp0 = [read_lxwp0(line) for _, line in sentences if line.startswith("$LXWP0")]
    assert all(s["vario_m_s"] is not None and s["pressure_altitude_m"] is not None
               for s in lxwp0)
    # the characteristic read after the last notification: the pressure of about then
    last_lk8ex1 = [read_sentence(line)[1] for _, line in sentences if "LK8EX1" in line][-1]
    pressure_pa = struct.unpack("<I", heard.pressure)[0] / 10
    print(f"central: pressure characteristic {pressure_pa:.1f} Pa, last LK8EX1 "
          f"{last_lk8ex1[0]} Pa", file=sys.stderr)
    assert abs(pressure_pa - float(last_lk8ex1[0])) < 200.0
