"""Finding and configuring the receiver one step at a time.

A step reads what the line brought and acts on it: the search (:class:`Search`) listens at
one baud rate, the configuration (:class:`Configuration`) sends a UBX CFG message or looks
for its ACK. Neither waits on the clock. Start-up (``probe``, ``configure``) runs the steps
back to back and sleeps between them; a recovery in the middle of a run takes one step per
poll of the device, so the pipeline polls the board's other devices between them. At 9600
baud a receiver that restarted needs 1.3 to 2.1 s to be heard and reconfigured (it speaks
its factory NMEA once a second, and each ACK queues behind what it is sending), which a
blocking recovery took from every other device of the board (issue 26: the IMU went
unread that long).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from imuhal.bus.base import Link
from imuhal.core.errors import BusError, ConfigurationError
from imuhal_chips.gnss.decode import DecodeError, decode_nmea, decode_ubx
from imuhal_chips.gnss.framing import StreamSplitter

READ_CHUNK = 4096
ACK_TIMEOUT_NS = 10**9
"""How long configure waits for one CFG message's ACK (a full 9600-baud burst ahead of it
takes up to 1 s)."""
CFG_SENDS = 3
"""Sends of one CFG message before configure gives up on its ACK."""


class Listener:
    """One listening window at one baud rate: fed what the line brought, it says which
    protocol it heard with a valid checksum (UBX preferred) and, at the end of the window,
    what it heard, in words."""

    def __init__(self) -> None:
        self.splitter = StreamSplitter()
        self.received = 0
        self.valid = {"nmea": 0, "ubx": 0}
        self.bad = 0

    def feed(self, data: bytes) -> str:
        """The protocol heard so far with a valid checksum ('' if none)."""
        self.received += len(data)
        for kind, item in self.splitter.feed(data):
            try:
                frag = decode_nmea(item) if kind == "nmea" else decode_ubx(item)
            except DecodeError:
                self.bad += 1
                continue
            if frag.checksum_ok:
                self.valid[kind] += 1
            else:
                self.bad += 1
        if self.valid["ubx"]:
            return "ubx"
        return "nmea" if self.valid["nmea"] else ""

    def heard(self) -> str:
        """What came in a window in which nothing valid did, in words."""
        if not self.received:
            return "nothing received"
        what = f"{self.received} bytes, no sentence or frame with a valid checksum"
        if self.splitter.garbage_bytes > self.received // 2:
            return what + " (unreadable: wrong baud rate?)"
        return what + (f" ({self.bad} with bad checksums)" if self.bad else "")


class Search:
    """Probe's search for the receiver: each of ``baud_rates`` in turn for ``window_ns``
    until a sentence or frame with a valid checksum comes. A window that heard only bad
    checksums (the receiver speaks at that speed, the line garbled it) is listened to once
    more before the next rate. A bus that cannot change speed is listened to at its own."""

    def __init__(self, link: Link, baud_rates: Sequence[int], window_ns: int,
                 now_ns: int) -> None:
        self.link = link
        self.window_ns = window_ns
        self.set_baud: Callable[[int], None] | None = getattr(link.bus, "set_baudrate", None)
        self.rates = tuple(baud_rates)
        self.seen: list[str] = []
        """What each baud rate tried gave, in words ("9600: nothing received")."""
        self._index = 0
        self._again = False
        self.listener = Listener()
        self.end_ns = now_ns + window_ns
        self._begin(now_ns)

    @property
    def baud(self) -> int:
        return self.rates[self._index]

    def _begin(self, now_ns: int) -> None:
        if self.set_baud is not None:
            self.set_baud(self.baud)
        self.listener = Listener()
        self.end_ns = now_ns + self.window_ns

    def step(self, now_ns: int) -> str | None:
        """Read what arrived: the protocol heard (the search is over), '' to listen on, or
        None when every rate was tried (``seen`` says what each gave)."""
        found = self.listener.feed(self.link.receive(READ_CHUNK))
        if found or now_ns < self.end_ns:
            return found
        what = self.listener.heard()
        if not self._again and what.endswith("with bad checksums)"):
            self._again = True
            self.listener = Listener()
            self.end_ns = now_ns + self.window_ns
            return ""
        self.seen.append(f"{self.baud}: {what}")
        self._index += 1
        self._again = False
        if self.set_baud is None or self._index >= len(self.rates):
            return None
        self._begin(now_ns)
        return ""


@dataclass(frozen=True)
class CfgMessage:
    """One UBX CFG message to send and the (class, id) its ACK names."""

    frame: bytes
    ident: tuple[int, int]
    what: str
    """In words, for errors: ``CFG-MSG NAV-PVT``."""


class Configuration:
    """UBX CFG messages sent in order, each once its predecessor was acknowledged (ACK-ACK).
    One whose ACK does not come within ``ACK_TIMEOUT_NS`` is sent again, up to
    ``CFG_SENDS`` times in all (a frame garbled or cut on the line is dropped silently by
    the receiver); a write the port reports failed counts as a send whose ACK did not come.
    Each CFG message sets a value, so sending it twice is harmless."""

    def __init__(self, link: Link, splitter: StreamSplitter, messages: Sequence[CfgMessage],
                 describe: str) -> None:
        self.link = link
        self.splitter = splitter
        self.messages = tuple(messages)
        self.describe = describe
        self.index = 0
        """The message being sent or awaited; ``len(messages)``: all acknowledged."""
        self._sends = 0
        self._deadline_ns: int | None = None

    @property
    def done(self) -> bool:
        return self.index >= len(self.messages)

    def step(self, now_ns: int) -> bool:
        """Send the current message if it is not on its way, read what arrived and take
        its ACK: True once every message was acknowledged. Raises ConfigurationError on an
        ACK-NAK or when the last send's ACK did not come, BusError when the last send's
        write failed."""
        if self.done:
            return True
        if self._deadline_ns is None:
            self._send(now_ns)
        answer = self._answer(self.link.receive(READ_CHUNK))
        message = self.messages[self.index]
        if answer == "ACK-NAK":
            raise ConfigurationError(f"{self.describe}: the receiver refused {message.what} "
                                     "(ACK-NAK); is it a u-blox receiver? Set "
                                     "configure_receiver: false for others")
        if answer == "ACK-ACK":
            self.index += 1
            self._sends = 0
            self._deadline_ns = None
            if not self.done:
                self._send(now_ns)
            return self.done
        assert self._deadline_ns is not None
        if now_ns >= self._deadline_ns:
            if self._sends >= CFG_SENDS:
                raise ConfigurationError(
                    f"{self.describe}: no ACK for {message.what} within 1 s after "
                    f"{CFG_SENDS} sends; a receiver that does not speak UBX needs "
                    "configure_receiver: false")
            self._send(now_ns)
        return False

    def _send(self, now_ns: int) -> None:
        frame = self.messages[self.index].frame
        while True:
            self._sends += 1
            try:
                self.link.transfer(frame, 0)
            except BusError:
                if self._sends >= CFG_SENDS:
                    raise
                continue
            self._deadline_ns = now_ns + ACK_TIMEOUT_NS
            return

    def _answer(self, data: bytes) -> str:
        """'ACK-ACK' or 'ACK-NAK' when ``data`` completed the current message's answer,
        else ''."""
        ident = self.messages[self.index].ident
        for kind, item in self.splitter.feed(data):
            if kind != "ubx":
                continue
            try:
                frag = decode_ubx(item)
            except DecodeError:
                continue
            if frag.acked == ident and frag.kind in ("ACK-ACK", "ACK-NAK"):
                return frag.kind
        return ""
