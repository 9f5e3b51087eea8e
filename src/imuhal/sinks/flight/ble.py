"""Bluetooth LE output for phones: the Nordic UART service carrying the flight sentences, and
the Environmental Sensing service's pressure characteristic.

Phones reach a vario over BLE far more often than over a serial cable. The de-facto service
is Nordic's UART service (NUS, ``6E400001-B5A3-F393-E0A9-E50E24DCCA9E``): the vario notifies
its sentences on the TX characteristic (``6E400003``); the central may write to RX
(``6E400002``), which imuhal ignores. XCTrack, XCSoar and other apps read LK8EX1 and LXWP0
there (XCSoar #2725). A notification carries at most ATT_MTU - 3 bytes: 20 with the default
MTU of 23, which every central accepts; ``chunk_bytes`` may be raised where the MTU
negotiated is known to be larger. Sentences are cut into chunks in order and never
interleaved, so a central rebuilds them by concatenating notifications and splitting at
CR LF. The Environmental Sensing service (``0x181A``) carries the static pressure in its
Pressure characteristic (``0x2A6D``: uint32, little-endian, 0.1 Pa), notified at
``pressure_hz`` (XCSoar #3156).

:class:`BleTransport` does the framing over a :class:`Peripheral` (the radio side);
:class:`BlessPeripheral` is that side on Linux: BlueZ over D-Bus through ``bless``
(``imuhal[ble]``). Nothing blocks the pipeline: when the radio falls behind (more than
``max_backlog`` notifications waiting), whole sentences are dropped and counted, never
parts of one.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
import threading
from typing import Any, Protocol

from imuhal.core.errors import ImuhalError
from imuhal.sinks.pacing import RateLimiter

NUS_SERVICE = "6e400001-b5a3-f393-e0a9-e50e24dcca9e"
NUS_RX = "6e400002-b5a3-f393-e0a9-e50e24dcca9e"
NUS_TX = "6e400003-b5a3-f393-e0a9-e50e24dcca9e"
ESS_SERVICE = "0000181a-0000-1000-8000-00805f9b34fb"
ESS_PRESSURE = "00002a6d-0000-1000-8000-00805f9b34fb"
DEFAULT_CHUNK_BYTES = 20
"""ATT_MTU 23 (the default every central accepts) less the 3-byte notification header."""
BLE_SENTENCES = ("LK8EX1", "LXWP0")
"""What ``--nmea ble`` sends unless ``--nmea-sentences`` says otherwise."""


class Peripheral(Protocol):
    """The radio side of :class:`BleTransport`."""

    description: str

    def notify(self, service_uuid: str, char_uuid: str, value: bytes) -> None:
        """Set the characteristic's value and notify subscribed centrals (never blocks)."""

    def backlog(self) -> int:
        """Notifications handed over and not yet sent."""

    def close(self) -> None: ...


def chunks(data: bytes, size: int) -> list[bytes]:
    """``data`` in order, in pieces of at most ``size`` bytes."""
    return [data[i:i + size] for i in range(0, len(data), size)]


def ess_pressure(pressure_pa: float) -> bytes:
    """The Pressure characteristic (0x2A6D): uint32 little-endian in units of 0.1 Pa."""
    return struct.pack("<I", max(0, min(0xFFFFFFFF, round(pressure_pa * 10))))


class BleTransport:
    """Flight sentences as NUS TX notifications, pressure as the ESS characteristic."""

    def __init__(self, peripheral: Peripheral, *, chunk_bytes: int = DEFAULT_CHUNK_BYTES,
                 max_backlog: int = 64, pressure_hz: float = 10.0) -> None:
        if not 20 <= chunk_bytes <= 512:
            raise ImuhalError(f"BLE chunk size {chunk_bytes}: use 20 (ATT MTU 23) up to 512 "
                              "bytes (the negotiated MTU less 3)")
        self.peripheral = peripheral
        self.chunk_bytes = chunk_bytes
        self.max_backlog = max_backlog
        self.pressure_hz = pressure_hz
        self.description = f"Bluetooth LE, Nordic UART service ({peripheral.description})"
        self.dropped_bytes = 0
        self.notifications = 0
        self._pacing = RateLimiter()

    def write(self, data: bytes) -> None:
        """One sentence (or more, whole): all of its chunks are handed over, or none."""
        pieces = chunks(data, self.chunk_bytes)
        if self.peripheral.backlog() + len(pieces) > self.max_backlog:
            self.dropped_bytes += len(data)
            return
        for piece in pieces:
            self.peripheral.notify(NUS_SERVICE, NUS_TX, piece)
        self.notifications += len(pieces)

    def set_pressure_pa(self, pressure_pa: float, t_ns: int) -> None:
        """The static pressure at ``t_ns``: notified at most every 1 / ``pressure_hz``."""
        if not self._pacing.due("pressure", t_ns, self.pressure_hz):
            return
        self.peripheral.notify(ESS_SERVICE, ESS_PRESSURE, ess_pressure(pressure_pa))

    def close(self) -> None:
        self.peripheral.close()


class BlessPeripheral:
    """The GATT server on BlueZ (D-Bus) through ``bless``, in its own thread and event loop:
    the NUS service (TX notify + read, RX write) and the ESS pressure characteristic
    (read + notify), advertised under ``name``. Needs bluetoothd on the system bus and a
    powered LE adapter."""

    def __init__(self, name: str = "imuhal vario", *, start_timeout_s: float = 15.0) -> None:
        try:
            from bless import (
                BlessServer,
                GATTAttributePermissions,
                GATTCharacteristicProperties,
            )
        except ImportError as exc:
            raise ImuhalError(f"--nmea ble needs bless ({exc}): pip install 'imuhal[ble]' "
                              "(BlueZ on Linux)") from None
        self.description = f"advertised as {name!r}"
        self._pending = 0
        self._lock = threading.Lock()
        self._loop = asyncio.new_event_loop()
        self._server: Any = None
        self._error: BaseException | None = None
        ready = threading.Event()
        props = GATTCharacteristicProperties
        perms = GATTAttributePermissions

        async def setup() -> None:
            server = BlessServer(name=name, loop=self._loop)
            server.read_request_func = lambda char, **_: char.value
            server.write_request_func = lambda char, value, **_: None  # commands ignored
            await server.add_new_service(NUS_SERVICE)
            await server.add_new_characteristic(
                NUS_SERVICE, NUS_TX, props.notify | props.read, bytearray(), perms.readable)
            await server.add_new_characteristic(
                NUS_SERVICE, NUS_RX, props.write | props.write_without_response, None,
                perms.writeable)
            await server.add_new_service(ESS_SERVICE)
            await server.add_new_characteristic(
                ESS_SERVICE, ESS_PRESSURE, props.read | props.notify, bytearray(4),
                perms.readable)
            await server.start()
            self._server = server

        def run() -> None:
            asyncio.set_event_loop(self._loop)
            try:
                self._loop.run_until_complete(setup())
            except BaseException as exc:  # no adapter, no bluetoothd, no D-Bus
                self._error = exc
                ready.set()
                return
            ready.set()
            self._loop.run_forever()

        self._thread = threading.Thread(target=run, name="imuhal-ble", daemon=True)
        self._thread.start()
        if not ready.wait(start_timeout_s) or self._error is not None:
            why = self._error or "no answer from BlueZ"
            self._stop_loop()
            raise ImuhalError(f"--nmea ble: cannot start the Bluetooth LE peripheral ({why}); "
                              "check that bluetoothd runs and an adapter is powered "
                              "(bluetoothctl power on)") from None

    def backlog(self) -> int:
        return self._pending

    def notify(self, service_uuid: str, char_uuid: str, value: bytes) -> None:
        with self._lock:
            self._pending += 1
        self._loop.call_soon_threadsafe(self._set, service_uuid, char_uuid, bytes(value))

    def _set(self, service_uuid: str, char_uuid: str, value: bytes) -> None:
        try:
            char = self._server.get_characteristic(char_uuid)
            char.value = bytearray(value)
            self._server.update_value(service_uuid, char_uuid)
        finally:
            with self._lock:
                self._pending -= 1

    def _stop_loop(self) -> None:
        if self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)

    def close(self) -> None:
        if self._server is not None:
            server, self._server = self._server, None
            future = asyncio.run_coroutine_threadsafe(server.stop(), self._loop)
            # the adapter may have gone away: then there is nothing left to stop
            with contextlib.suppress(Exception):
                future.result(timeout=5)
        self._stop_loop()
