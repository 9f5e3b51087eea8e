"""Byte-stream emulator of a u-blox-class GNSS receiver on a UART.

Written from the receiver's side: it turns the simulated world's true position and velocity
(earth NED relative to the scenario origin, handed over in ``PhysicalInputs``) into what the
receiver would send, through a GNSS error model (:class:`GnssErrorModel`), and answers UBX
CFG-RATE / CFG-MSG with ACK-ACK (anything else in class CFG: ACK-NAK).

Out of the box it behaves like a u-blox receiver from the factory: NMEA GGA, RMC, VTG and GSA
at 1 Hz and 9600 baud. NMEA sentences are written by imuhal's own encoders
(:mod:`imuhal.sinks.flight.sentences`), NAV-PVT by pyubx2's generator; the driver decodes
with pynmea2 and pyubx2's parser, and the tests decode with hand-written parsers as well.

Settings of the emulator (the fault-injection interface had not landed when this was
written): ``model`` (the error model, replaceable before or during a run) and
:meth:`lose_fix` (a fix-lost interval). Of the fault API's chip kinds it models ``reset``
(the factory configuration), ``frozen`` (a hung navigation engine: each epoch repeats the
last solution with its own time) and ``stale_navigation`` (a restart with the last solution
sent again, claiming a fix: with its old time, or with the running time marked not valid).
"""

from __future__ import annotations

import math
from collections import deque
from datetime import datetime, timedelta, timezone

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock
from imuhal.emulation import ChipEmulator, PhysicalInputs
from imuhal.sinks.flight import sentences as nmea

EARTH_A_M = 6378137.0
EARTH_E2 = 6.69437999014e-3
GPS_LEAP_S = 18
"""GPS time is ahead of UTC by this many seconds (since 2017)."""
NMEA_DEFAULT = ("GGA", "RMC", "VTG", "GSA")
_NMEA_BY_ID = {(0xF0, 0x00): "GGA", (0xF0, 0x01): "GLL", (0xF0, 0x02): "GSA",
               (0xF0, 0x03): "GSV", (0xF0, 0x04): "RMC", (0xF0, 0x05): "VTG"}


class GnssErrorModel(BaseModel):
    """How far the reported fix is from the truth, and when there is none.

    Position error per axis is a first-order Gauss-Markov process (correlation time
    ``position_tau_s``) whose standard deviation is the reported accuracy: north and east each
    ``horizontal_accuracy_m / sqrt(2)`` (so the horizontal error's rms is hAcc), down
    ``vertical_accuracy_m``. Velocity error is white, ``speed_accuracy_m_s`` per axis.
    """

    model_config = ConfigDict(extra="forbid")

    horizontal_accuracy_m: float = Field(2.5, ge=0)
    vertical_accuracy_m: float = Field(4.0, ge=0)
    speed_accuracy_m_s: float = Field(0.15, ge=0)
    position_tau_s: float = Field(30.0, gt=0)
    latency_s: float = Field(0.08, ge=0)
    """Measurement epoch to the first byte of its output."""
    time_to_first_fix_s: float = Field(1.0, ge=0)
    """Simulated time before the first fix (a u-blox M8 hot start: about 1 s)."""
    dropout_probability: float = Field(0.0, ge=0, le=1)
    """Chance that an epoch's output is lost entirely."""
    satellites: int = Field(9, ge=0, le=40)
    origin_latitude_deg: float = Field(46.6, ge=-90, le=90)
    origin_longitude_deg: float = Field(8.0, ge=-180, le=180)
    origin_height_msl_m: float = 920.0
    """Height of the scenario's origin above MSL (the default environment's origin)."""
    geoid_separation_m: float = 48.0
    """Ellipsoid height minus MSL height at the origin."""
    utc_start: datetime = datetime(2026, 6, 21, 11, 0, 0, tzinfo=timezone.utc)
    seed: int = 0


TX_BUFFER_BYTES = 4096
_FRESH_PHYSICS_NS = 50_000_000
"""Physics older than this at an epoch (the device not polled meanwhile) are replaced by the
world's own for the epoch: held 50 ms, a takeoff's 10 m/s^2 moves the velocity 0.5 m/s."""
"""The receiver's transmit buffer: output that would queue beyond it (more than the line
carries, or a host that does not read) is dropped whole, as a u-blox receiver drops
messages when its port's buffer is full, so the backlog stays bounded."""


class GnssEmulator(ChipEmulator):
    chip = "gnss"

    def __init__(self, clock: Clock | None = None) -> None:
        super().__init__(clock)
        self.model = GnssErrorModel()
        self.baudrate = 9600
        self.rate_hz = 1.0
        self.nmea_enabled: set[str] = set(NMEA_DEFAULT)
        self.nav_pvt = False
        self._fix_lost: list[tuple[float, float]] = []
        self._history: deque[tuple[int, PhysicalInputs]] = deque(maxlen=64)
        self._queue: deque[tuple[int, bytes]] = deque()
        """(time ready to send, bytes) in order; bytes leave at the line rate."""
        self._line_free_ns = 0
        self._pending = bytearray()
        self._next_epoch_ns = 0
        self._pos_err = np.zeros(3)
        self._last_err_ns: int | None = None
        self._rng = np.random.default_rng(self.model.seed)
        self.epochs_sent = 0
        self.messages_dropped = 0
        """Epochs' output and answers dropped because the transmit buffer was full."""
        self._corrupt = 0
        self._cut = False
        self._solution: tuple[float, float, float, np.ndarray] | None = None
        """The last navigation solution computed (latitude, longitude, MSL height, NED
        velocity): what a hung navigation engine (``frozen``) keeps sending."""
        self._last_utc: datetime | None = None
        """The UTC of the last epoch sent."""
        self._stale: tuple[str, datetime, tuple[float, float, float, np.ndarray]] | None = None
        """Fault ``stale_navigation``: its time mode, and the UTC and solution of the last
        epoch before it, sent again each epoch."""

    # -- settings -----------------------------------------------------------------------

    def lose_fix(self, start_s: float, end_s: float) -> None:
        """Fault: no fix between ``start_s`` and ``end_s`` of simulated time (sky blocked)."""
        self._fix_lost.append((start_s, end_s))

    def corrupt_checksums(self, count: int) -> None:
        """Fault: the next ``count`` sentences or frames go out with a wrong checksum (a
        flipped bit on the wire after the checksum was computed)."""
        self._corrupt += count

    def cut_next_frame(self) -> None:
        """Fault: the second half of the next epoch's first UBX frame is lost on the line."""
        self._cut = True

    def silent_reset(self) -> None:
        """Fault: the receiver restarts with its factory configuration (NMEA at 1 Hz), as a
        u-blox without a saved configuration does after a brown-out."""
        self.rate_hz = 1.0
        self.nmea_enabled = set(NMEA_DEFAULT)
        self.nav_pvt = False

    def stale_solution(self, time: str | None) -> None:
        """Fault ``stale_navigation``: from the next epoch on, the last epoch's solution is
        sent again each epoch, claiming a 3D fix, with that epoch's UTC (``"repeated"``) or
        the running UTC with NAV-PVT's validDate, validTime and fullyResolved cleared
        (``"unresolved"``); None ends it. Before any epoch with a fix there is nothing
        stale to send: the receiver navigates as before."""
        if time is None or self._solution is None or self._last_utc is None:
            self._stale = None
            return
        self._stale = (time, self._last_utc, self._solution)

    def use_model(self, model: GnssErrorModel) -> None:
        self.model = model
        self._rng = np.random.default_rng(model.seed)

    # -- physics face -------------------------------------------------------------------

    def set_physics(self, inputs: PhysicalInputs) -> None:
        super().set_physics(inputs)
        # Stamped with the time the inputs are true at (a late poll's due time), not the
        # time they arrived: the epochs are computed at their own times.
        at = self.physics_t_ns if self.physics_t_ns is not None else self.now_ns()
        self.physics_t_ns = None
        if self._history and at < self._history[-1][0]:
            self._history = deque(((t, i) for t, i in self._history if t <= at), maxlen=64)
        self._history.append((at, inputs))

    def _truth_at(self, t_ns: int) -> tuple[np.ndarray, np.ndarray] | None:
        # The receiver computes its fixes whether or not the host reads them: while its
        # device is not polled (recovering, its bus failing) the physics handed over at the
        # polls grow old, so it asks the world for the epoch's own (a stale velocity kept
        # for seconds came out as a valid fix after the recovery). What counts is the age of
        # the physics the epoch would use, not of the newest: physics handed over after the
        # epoch (a poll just after a recovery) must not hide a gap before it (3.9 m/s
        # valid at a takeoff's 7.6 m/s: the fault matrix, seed-gps-vario, I/O errors).
        chosen = self._latest_physics(t_ns)
        if self.physics_at is not None and (chosen is None
                                            or chosen[0] < t_ns - _FRESH_PHYSICS_NS):
            self.physics_at(t_ns)
            chosen = self._latest_physics(t_ns)
        if chosen is None and self._history:
            chosen = self._history[0]
        if chosen is None or chosen[1].position_ned_m is None:
            return None
        t, inputs = chosen
        vel = np.array(inputs.velocity_ned_m_s or (0.0, 0.0, 0.0))
        pos = np.array(inputs.position_ned_m) + vel * ((t_ns - t) / 1e9)
        return pos, vel

    def _latest_physics(self, t_ns: int) -> tuple[int, PhysicalInputs] | None:
        """The newest physics true at or before ``t_ns``."""
        chosen = None
        for t, inputs in self._history:
            if t <= t_ns:
                chosen = (t, inputs)
        return chosen

    # -- bus face -----------------------------------------------------------------------

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self._pending += write
        self._handle_input()
        return b"\x00" * read_len  # nothing is clocked back on a UART write

    def bus_receive(self, kind: BusKind, max_len: int) -> bytes:
        """What has come down the line by now: each queued message starts when it is ready
        and the line is free, and its bytes arrive at the line rate (10 bits per byte), so
        a long burst at 9600 baud spans several reads, as on a real UART."""
        now = self.now_ns()
        self._generate(now)
        out = bytearray()
        ns_per_byte = 10 * 10**9 // self.baudrate
        while self._queue and len(out) < max_len:
            ready, data = self._queue[0]
            start = max(ready, self._line_free_ns)
            if start > now:
                break
            arrived = min(len(data), (now - start) // ns_per_byte, max_len - len(out))
            if arrived <= 0:
                break
            out += data[:arrived]
            self._line_free_ns = start + arrived * ns_per_byte
            if arrived < len(data):
                self._queue[0] = (self._line_free_ns, data[arrived:])
                break
            self._queue.popleft()
        if self.host_baudrate and self.host_baudrate != self.baudrate:
            return self._garble(bytes(out))
        return bytes(out)

    def _garble(self, data: bytes) -> bytes:
        """What a UART at the wrong speed makes of ``data``: the same time on the line cut
        into the wrong number of characters, none of them the ones sent."""
        n = max(1, round(len(data) * self.host_baudrate / self.baudrate)) if data else 0
        return bytes(self._rng.integers(0x80, 0x100, n).astype(np.uint8).tolist())

    def _handle_input(self) -> None:
        buf = self._pending
        while True:
            i = buf.find(b"\xb5\x62")
            if i < 0:
                buf.clear()
                return
            del buf[:i]
            if len(buf) < 8:
                return
            length = buf[4] | buf[5] << 8
            if len(buf) < 8 + length:
                return
            frame = bytes(buf[:8 + length])
            del buf[:8 + length]
            if _ubx_checksum(frame[2:-2]) != frame[-2:]:
                continue  # a real receiver ignores a corrupt frame silently
            self._apply(frame[2], frame[3], frame[6:-2])

    def _apply(self, cls: int, mid: int, payload: bytes) -> None:
        ok = False
        if (cls, mid) == (0x06, 0x08) and len(payload) == 6:  # CFG-RATE
            meas_ms = payload[0] | payload[1] << 8
            nav = payload[2] | payload[3] << 8
            if meas_ms >= 25 and nav >= 1:
                self.rate_hz = 1000.0 / (meas_ms * nav)
                ok = True
        elif (cls, mid) == (0x06, 0x01) and len(payload) in (3, 8):  # CFG-MSG
            mcls, mmid = payload[0], payload[1]
            # short form: one rate for the current port; long form: UART1 is the second
            rate = payload[2] if len(payload) == 3 else payload[3]
            if (mcls, mmid) == (0x01, 0x07):
                self.nav_pvt, ok = rate > 0, True
            elif (mcls, mmid) in _NMEA_BY_ID:
                name = _NMEA_BY_ID[(mcls, mmid)]
                (self.nmea_enabled.add if rate else self.nmea_enabled.discard)(name)
                ok = True
        if cls == 0x06:
            ack = 0x01 if ok else 0x00
            self._send(self.now_ns(), _ubx_frame(0x05, ack, bytes((cls, mid))))

    @property
    def backlog_bytes(self) -> int:
        """Bytes queued in the transmit buffer and not yet on the line."""
        return sum(len(d) for _, d in self._queue)

    def _send(self, ready_ns: int, data: bytes) -> bool:
        """Queue ``data`` for the line at ``ready_ns``, unless the transmit buffer (what is
        queued and not yet sent) has no room for it: then it is dropped (False)."""
        if self.backlog_bytes + len(data) > TX_BUFFER_BYTES:
            self.messages_dropped += 1
            return False
        self._queue.append((ready_ns, data))
        return True

    # -- output -------------------------------------------------------------------------

    def _generate(self, now: int) -> None:
        m = self.model
        latency = round(m.latency_s * 1e9)
        period = round(1e9 / self.rate_hz)
        while self._next_epoch_ns + latency <= now:
            te = self._next_epoch_ns
            self._next_epoch_ns += period
            if m.dropout_probability and self._rng.random() < m.dropout_probability:
                continue
            data = self._epoch_bytes(te)
            if data and self._send(te + latency, data):
                self.epochs_sent += 1

    def _has_fix(self, t_s: float) -> bool:
        if t_s < self.model.time_to_first_fix_s:
            return False
        return not any(a <= t_s < b for a, b in self._fix_lost)

    def _epoch_bytes(self, te_ns: int) -> bytes:
        m = self.model
        utc, fix, time_valid, (lat, lon, h_msl, vel) = self._epoch_solution(te_ns)
        course, speed = nmea.course_and_speed((float(vel[0]), float(vel[1]), float(vel[2])))
        out = bytearray()
        sats = m.satellites if fix else 0
        hdop = 0.9 if fix else 99.9
        for name in ("RMC", "VTG", "GGA", "GSA"):
            if name not in self.nmea_enabled:
                continue
            if name == "RMC":
                text = nmea.rmc(utc=utc, valid=fix, latitude_deg=lat, longitude_deg=lon,
                                ground_speed_m_s=speed if fix else 0.0,
                                course_deg=course if fix else 0.0)
            elif name == "VTG":
                text = nmea.vtg(ground_speed_m_s=speed if fix else 0.0,
                                course_deg=course if fix else 0.0)
            elif name == "GGA":
                text = nmea.gga(utc=utc, latitude_deg=lat, longitude_deg=lon,
                                quality=1 if fix else 0, satellites=sats,
                                hdop=hdop, altitude_msl_m=h_msl,
                                geoid_separation_m=m.geoid_separation_m)
            else:
                text = nmea.gsa(fix=3 if fix else 1,
                                satellite_ids=list(range(2, 2 + sats)),
                                pdop=1.6 if fix else 99.9, hdop=hdop,
                                vdop=1.3 if fix else 99.9)
            out += self._faulty(text.encode("ascii"))
        if self.nav_pvt:
            frame = self._faulty(self._nav_pvt(utc, fix, lat, lon, h_msl, vel, speed,
                                               course, sats, time_valid))
            if self._cut:
                self._cut = False
                frame = frame[:len(frame) // 2]
            out += frame
        return bytes(out)

    def _epoch_solution(self, te_ns: int) -> tuple[datetime, bool, bool,
                                                   tuple[float, float, float, np.ndarray]]:
        """The epoch's UTC, whether it has a fix, whether its time is valid, and its solution
        (latitude, longitude, MSL height, NED velocity). Under ``stale_navigation`` the old
        solution claiming a fix, with the old UTC (``repeated``) or the running one marked
        not valid (``unresolved``)."""
        utc = self.model.utc_start + timedelta(microseconds=round(te_ns / 1000))
        if self._stale is not None:
            mode, stale_utc, solution = self._stale
            return (stale_utc if mode == "repeated" else utc), True, mode != "unresolved", \
                solution
        truth = self._truth_at(te_ns)
        fix = truth is not None and self._has_fix(te_ns / 1e9)
        solution = self._navigate(te_ns, truth)
        if fix:
            self._last_utc = utc
        return utc, fix, True, solution

    def _navigate(self, te_ns: int, truth: tuple[np.ndarray, np.ndarray] | None
                  ) -> tuple[float, float, float, np.ndarray]:
        """The epoch's solution (latitude, longitude, MSL height, NED velocity) from the
        truth through the error model; zeros without a truth."""
        if self.frozen and self._solution is not None:
            # Fault ``frozen``: the navigation engine hangs and the receiver keeps sending
            # its last solution with each epoch's time, as a register chip whose conversion
            # hung keeps its last words (the receiver's clock and its output run on).
            return self._solution
        if truth is None:
            return 0.0, 0.0, 0.0, np.zeros(3)
        pos, vel_true = truth
        err = self._position_error(te_ns)
        lat, lon, h_msl = self._geodetic(pos + err)
        vel = vel_true + self._rng.normal(0.0, self.model.speed_accuracy_m_s, 3)
        self._solution = (lat, lon, h_msl, vel)
        return self._solution

    def _faulty(self, data: bytes) -> bytes:
        if not self._corrupt:
            return data
        self._corrupt -= 1
        if data[:1] == b"$":  # change one checksum digit
            star = data.rindex(b"*")
            digit = data[star + 2:star + 3]
            return data[:star + 2] + (b"0" if digit != b"0" else b"1") + data[star + 3:]
        return data[:-1] + bytes(((data[-1] + 1) & 0xFF,))

    def _position_error(self, t_ns: int) -> np.ndarray:
        m = self.model
        sigma = np.array([m.horizontal_accuracy_m / math.sqrt(2),
                          m.horizontal_accuracy_m / math.sqrt(2), m.vertical_accuracy_m])
        if self._last_err_ns is None:
            self._pos_err = self._rng.normal(0.0, 1.0, 3) * sigma
        else:
            a = math.exp(-((t_ns - self._last_err_ns) / 1e9) / m.position_tau_s)
            self._pos_err = a * self._pos_err + math.sqrt(1 - a * a) * \
                self._rng.normal(0.0, 1.0, 3) * sigma
        self._last_err_ns = t_ns
        return self._pos_err

    def _geodetic(self, ned: np.ndarray) -> tuple[float, float, float]:
        """Latitude, longitude (deg) and MSL height of an NED offset from the origin, on the
        WGS-84 ellipsoid's local radii (exact enough over a flight's few tens of km)."""
        m = self.model
        lat0 = math.radians(m.origin_latitude_deg)
        s = math.sin(lat0)
        w = math.sqrt(1 - EARTH_E2 * s * s)
        r_meridian = EARTH_A_M * (1 - EARTH_E2) / w**3
        r_normal = EARTH_A_M / w
        h = m.origin_height_msl_m - float(ned[2])
        lat = m.origin_latitude_deg + math.degrees(float(ned[0]) / (r_meridian + h))
        lon = m.origin_longitude_deg + math.degrees(
            float(ned[1]) / ((r_normal + h) * math.cos(lat0)))
        return lat, lon, h

    def _nav_pvt(self, utc: datetime, fix: bool, lat: float, lon: float, h_msl: float,
                 vel: np.ndarray, speed: float, course: float, sats: int,
                 time_valid: bool = True) -> bytes:
        import pyubx2

        m = self.model
        gps = utc + timedelta(seconds=GPS_LEAP_S)
        week_start = (gps - timedelta(days=(gps.weekday() + 1) % 7)).replace(
            hour=0, minute=0, second=0, microsecond=0)
        itow = round((gps - week_start).total_seconds() * 1000)
        big = 9_999_999
        msg = pyubx2.UBXMessage(
            "NAV", "NAV-PVT", pyubx2.GET,
            iTOW=itow, year=utc.year, month=utc.month, day=utc.day, hour=utc.hour,
            min=utc.minute, second=utc.second, validDate=int(time_valid),
            validTime=int(time_valid), fullyResolved=int(time_valid),
            nano=utc.microsecond * 1000, tAcc=30, fixType=3 if fix else 0,
            gnssFixOk=1 if fix else 0, numSV=sats, lon=lon if fix else 0.0,
            lat=lat if fix else 0.0,
            height=round((h_msl + m.geoid_separation_m) * 1000) if fix else 0,
            hMSL=round(h_msl * 1000) if fix else 0,
            hAcc=round(m.horizontal_accuracy_m * 1000) if fix else big,
            vAcc=round(m.vertical_accuracy_m * 1000) if fix else big,
            velN=round(vel[0] * 1000) if fix else 0, velE=round(vel[1] * 1000) if fix else 0,
            velD=round(vel[2] * 1000) if fix else 0, gSpeed=round(speed * 1000) if fix else 0,
            headMot=course if fix else 0.0,
            sAcc=round(m.speed_accuracy_m_s * 1000) if fix else big,
            headAcc=5.0 if fix else 180.0, pDOP=1.6 if fix else 99.99)
        return msg.serialize()


def _ubx_checksum(body: bytes) -> bytes:
    """The 8-bit Fletcher checksum over class, id, length and payload."""
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return bytes((a, b))


def _ubx_frame(cls: int, mid: int, payload: bytes) -> bytes:
    body = bytes((cls, mid, len(payload) & 0xFF, len(payload) >> 8)) + payload
    return b"\xb5\x62" + body + _ubx_checksum(body)
