"""Where flight-app sentences go: a serial port, a pseudo-terminal, or a TCP server.

Every transport only writes and never blocks the pipeline: what cannot be written now (no
reader on the pty, a TCP client that stopped reading) is dropped and counted, as a serial
line with nobody listening would lose it. A reader gets whole sentences or none: a write
the kernel takes only in part has its tail sent before anything newer
(:class:`WholeWrites`), so a slow app loses sentences, never the end of one glued to the
start of the next (which would cost it both: the joined line fails its checksum).

``open_transport(spec)`` reads the CLI's form: ``serial:PORT@BAUD``, ``pty`` or
``pty:LINK`` (a symlink to the pty's slave at LINK, so the flight app's setting survives
restarts), ``tcp:PORT`` (loopback), ``tcp:HOST:PORT``, or ``ble`` / ``ble:NAME`` (a Bluetooth
LE peripheral, imuhal.sinks.flight.ble). ``check_transport(spec)`` reads and checks it
without opening anything, so a run finds a mistake before it starts.
"""

from __future__ import annotations

import contextlib
import errno
import ipaddress
import os
import socket
import termios
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from imuhal.core.errors import ImuhalError

TRANSPORT_FORMS = "serial:PORT@BAUD, pty, pty:LINK, tcp:PORT, tcp:HOST:PORT, ble or ble:NAME"


class Transport(Protocol):
    description: str

    @property
    def dropped_bytes(self) -> int:
        """Bytes the reader did not get (whole sentences), counted since the start."""

    def write(self, data: bytes) -> None: ...

    def close(self) -> None: ...


class WholeWrites:
    """One reader's non-blocking writes, whole: the unsent tail of a write the kernel took
    in part goes out before anything newer, and a newer write that cannot go out behind it
    is dropped whole. ``send`` is the non-blocking write (bytes taken; 0 or BlockingIOError
    when none)."""

    def __init__(self, send: Callable[[bytes], int]) -> None:
        self._send = send
        self._tail = b""
        self.dropped_bytes = 0

    def _try(self, data: bytes) -> int:
        try:
            return self._send(data)
        except BlockingIOError:
            return 0

    def write(self, data: bytes) -> int:
        """Hand ``data`` over, after the tail of an earlier write; bytes taken by the
        reader in this call. OSError other than a full buffer is the caller's."""
        taken = 0
        if self._tail:
            sent = self._try(self._tail)
            taken += sent
            self._tail = self._tail[sent:]
            if self._tail:
                self.dropped_bytes += len(data)
                return taken
        sent = self._try(data)
        self._tail = data[sent:]
        return taken + sent

    def close(self) -> None:
        """The reader is gone: a tail not sent is dropped."""
        self.dropped_bytes += len(self._tail)
        self._tail = b""


class SerialTransport:
    """A UART (or Bluetooth SPP device) through pyserial."""

    def __init__(self, port: str, baudrate: int, *, serial_factory: Callable[..., Any] | None = None
                 ) -> None:
        import serial

        factory = serial_factory or serial.serial_for_url
        try:
            self._port = factory(port, baudrate=baudrate, timeout=0, write_timeout=0)
        except (OSError, serial.SerialException, ValueError) as exc:
            raise _cannot_open(port, baudrate, str(exc)) from None
        self.description = f"serial port {port} at {baudrate} baud"
        self.dropped_bytes = 0

    def write(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except Exception:  # pyserial's write timeout: the line cannot take more now
            self.dropped_bytes += len(data)

    def close(self) -> None:
        self._port.close()


class PtyTransport:
    """A pseudo-terminal: a flight app on the same machine opens ``slave_path`` (or
    ``link``) as if it were a serial device. The slave side is raw (no echo, no newline
    translation), so sentences arrive byte for byte."""

    def __init__(self, link: str | os.PathLike[str] | None = None) -> None:
        self._link = Path(link) if link is not None else None
        if self._link is not None:
            _check_pty_link(self._link)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave, termios.TCSANOW)
        os.set_blocking(self._master, False)
        self.slave_path = os.ttyname(self._slave)
        if self._link is not None:
            tmp = self._link.with_name(f".{self._link.name}.{os.getpid()}")
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            try:
                os.symlink(self.slave_path, tmp)
                os.replace(tmp, self._link)  # atomic: an app never sees the link missing
            except OSError as exc:
                os.close(self._master)
                os.close(self._slave)
                with contextlib.suppress(OSError):
                    tmp.unlink()
                raise _cannot_link(self._link, exc.strerror or str(exc)) from None
        where = f"{self._link} -> {self.slave_path}" if self._link else self.slave_path
        self.description = f"pseudo-terminal {where}"
        self._out = WholeWrites(self._send)

    @property
    def path(self) -> str:
        """What the flight app opens: the link if there is one, else the slave device."""
        return str(self._link) if self._link is not None else self.slave_path

    @property
    def dropped_bytes(self) -> int:
        return self._out.dropped_bytes

    def _send(self, data: bytes) -> int:
        try:
            return os.write(self._master, data)
        except OSError as exc:
            # EIO: no app has the slave open (the pty's buffer is then not filling)
            if exc.errno not in (errno.EAGAIN, errno.EIO):
                raise
            return 0

    def write(self, data: bytes) -> None:
        self._out.write(data)

    def close(self) -> None:
        self._out.close()
        if self._link is not None and self._link.is_symlink() and \
                os.readlink(self._link) == self.slave_path:
            self._link.unlink()
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


MAX_TCP_CLIENTS = 8
"""Flight apps connected at once (a phone, a tablet, a logger); more are refused."""
TCP_STALL_S = 10.0
"""A client that has taken no byte for this long (it stopped reading, or its network went
away without a reset) is disconnected: it costs a descriptor and a send buffer."""
_NO_DESCRIPTOR = (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM)


def is_loopback(host: str) -> bool:
    """True for a loopback address or ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class TcpTransport:
    """A TCP server (XCSoar and XCTrack connect as clients); every connected client gets
    every sentence. Loopback only unless a host is named.

    Bounded: one thread (the pipeline's; accepting happens at each write), at most
    ``max_clients`` clients (more are accepted and closed at once, counted in
    ``refused_clients``), a client that takes nothing for ``stall_s`` is dropped, and a
    process out of descriptors (EMFILE) refuses the client instead of ending the run."""

    def __init__(self, port: int, host: str = "127.0.0.1", *,
                 max_clients: int = MAX_TCP_CLIENTS, stall_s: float = TCP_STALL_S) -> None:
        self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._server.bind((host, port))
        except OSError as exc:
            self._server.close()
            raise ImuhalError(f"--nmea tcp:{port}: cannot listen on {host}:{port} ({exc}); "
                              "choose another port") from None
        self._server.listen(4)
        self._server.setblocking(False)
        self.port = self._server.getsockname()[1]
        self.host = host
        self.description = f"TCP server {host}:{self.port}"
        self.max_clients = max_clients
        self.stall_s = stall_s
        self._clients: dict[socket.socket, tuple[WholeWrites, float]] = {}
        """Client -> its writes and the monotonic time it last took a byte (or connected)."""
        self._dropped_gone = 0
        """Bytes dropped by clients no longer connected."""
        self.refused_clients = 0
        self.stalled_clients = 0

    @property
    def exposure(self) -> str | None:
        """A warning when the server is reachable beyond this machine, else None."""
        if is_loopback(self.host):
            return None
        return (f"--nmea tcp:{self.host}:{self.port} is reachable from the network: anyone on "
                f"it can read the flight data (at most {self.max_clients} at once); bind "
                "127.0.0.1 unless an app on another device needs it")

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._server.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in _NO_DESCRIPTOR:
                    # Out of descriptors: the client waits in the backlog (or the kernel
                    # refuses it once that is full); the run goes on.
                    self.refused_clients += 1
                    return
                raise
            if len(self._clients) >= self.max_clients:
                self.refused_clients += 1
                client.close()
                continue
            client.setblocking(False)
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._clients[client] = (WholeWrites(client.send), time.monotonic())

    @property
    def clients(self) -> int:
        self._accept()
        return len(self._clients)

    @property
    def dropped_bytes(self) -> int:
        """Bytes some client did not get, over every client, gone ones included."""
        return self._dropped_gone + sum(out.dropped_bytes for out, _ in self._clients.values())

    def write(self, data: bytes) -> None:
        self._accept()
        now = time.monotonic()
        for client, (out, last) in list(self._clients.items()):
            try:
                sent = out.write(data)
            except OSError:  # the app went away
                self._drop(client)
                continue
            if sent:
                self._clients[client] = (out, now)
            elif now - last >= self.stall_s:
                self.stalled_clients += 1
                self._drop(client)

    def _drop(self, client: socket.socket) -> None:
        out, _ = self._clients.pop(client)
        out.close()
        self._dropped_gone += out.dropped_bytes
        client.close()

    def close(self) -> None:
        for client in list(self._clients):
            self._drop(client)
        self._server.close()


@dataclass(frozen=True)
class TransportSpec:
    """An ``--nmea`` output as read from its CLI form, checked but not opened: a run checks
    every output this way before it starts (and before an emulated board's calibration), so
    a mistake costs the user no wait."""

    kind: str
    """serial, pty, tcp or ble."""
    spec: str
    """The CLI form as given."""
    where: str = ""
    """serial: the port; pty: the link ("" for none); tcp: the host; ble: the name."""
    number: int = 0
    """serial: the baud rate; tcp: the port."""

    def open(self) -> Transport:
        """The transport itself (a port opened, a pty made, a socket bound)."""
        if self.kind == "pty":
            return PtyTransport(self.where or None)
        if self.kind == "tcp":
            return TcpTransport(self.number, self.where)
        if self.kind == "ble":
            from imuhal.sinks.flight.ble import BlessPeripheral, BleTransport

            return BleTransport(BlessPeripheral(self.where))
        return SerialTransport(self.where, self.number)


def check_transport(spec: str) -> TransportSpec:
    """Reads ``spec`` (see the module docstring) and checks what can be checked without
    opening it: the form, the TCP port's range, a serial device's path, a pty link's folder.
    A mistake is an ImuhalError naming the form expected or the path to fix."""
    kind, _, rest = spec.partition(":")
    if kind == "pty":
        if rest:
            _check_pty_link(Path(rest))
        return TransportSpec("pty", spec, rest)
    if kind == "tcp" and rest:
        host, _, port_text = rest.rpartition(":")
        try:
            port = int(port_text)
        except ValueError:
            port = -1
        if not 0 <= port <= 65535:
            raise ImuhalError(f"--nmea {spec}: the port must be a number 0-65535 "
                              f"(forms: {TRANSPORT_FORMS})")
        return TransportSpec("tcp", spec, host or "127.0.0.1", port)
    if kind == "ble":
        return TransportSpec("ble", spec, rest or "imuhal vario")
    if kind == "serial" and rest:
        port_path, at, baud_text = rest.rpartition("@")
        if not at or not port_path or not baud_text.isdigit():
            raise ImuhalError(f"--nmea {spec}: write serial:PORT@BAUD, e.g. "
                              "serial:/dev/ttyUSB0@115200")
        # pyserial also takes URLs (socket://, rfc2217://): only a plain path is looked at
        if "://" not in port_path and not os.path.exists(port_path):
            raise _cannot_open(port_path, int(baud_text), "no such device")
        return TransportSpec("serial", spec, port_path, int(baud_text))
    raise ImuhalError(f"--nmea {spec!r}: unknown output; use one of {TRANSPORT_FORMS}")


def _check_pty_link(link: Path) -> None:
    """The checks :class:`PtyTransport` makes again when it makes the link."""
    if link.exists() and not link.is_symlink():
        raise ImuhalError(f"--nmea pty:{link}: {link} exists and is not a symlink; name a new "
                          "path (imuhal only replaces its own links)")
    folder = link.parent
    reason = ("No such file or directory" if not folder.is_dir() else
              None if os.access(folder, os.W_OK | os.X_OK) else "Permission denied")
    if reason is not None:
        raise _cannot_link(link, reason)


def _cannot_link(link: Path, reason: str) -> ImuhalError:
    """The one-line error for a pty link that cannot be made (checked or tried)."""
    return ImuhalError(f"--nmea pty:{link}: cannot make the link there ({reason}); name a "
                       "path in a folder you can write to, e.g. pty:/tmp/vario")


def _cannot_open(port: str, baudrate: int, reason: str) -> ImuhalError:
    """The one-line error for a serial port that cannot be opened (checked or tried)."""
    return ImuhalError(f"--nmea serial:{port}@{baudrate}: cannot open {port} ({reason}); "
                       "check the device path and its permissions")


def open_transport(spec: str) -> Transport:
    """A transport from its CLI form (see the module docstring); a mistake is an
    ImuhalError naming the form expected."""
    return check_transport(spec).open()
