"""A flight app that reads too slowly loses whole sentences, never part of one.

A non-blocking write to a full socket or pty is taken in part; before this, the rest was
dropped and the next sentence followed the torn one on the same line, so the app's parser
saw one line failing its checksum and lost both. The transports now send a torn write's
tail before anything newer and drop newer sentences whole while it waits (and count them).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import termios
import tty
from pathlib import Path

from imuhal.sinks.flight.transports import PtyTransport, TcpTransport, WholeWrites


def _sentences(n: int) -> list[bytes]:
    """``n`` distinct sentences of 60 bytes, so any torn or glued line shows."""
    return [f"$PTEST,{i:06d},{'x' * 40}*00\r\n".encode("ascii") for i in range(n)]


def _lines(data: bytes) -> list[bytes]:
    lines = data.split(b"\r\n")
    return [line + b"\r\n" for line in lines[:-1]]


def _in_order(got: list[bytes], sent: list[bytes]) -> bool:
    """Whether ``got`` is ``sent`` with some sentences left out (none torn, none added)."""
    position = {s: i for i, s in enumerate(sent)}
    indices = [position.get(line, -1) for line in got]
    return -1 not in indices and indices == sorted(set(indices))


class _Pipe:
    """A reader taking at most ``room`` bytes per write, for WholeWrites alone."""

    def __init__(self) -> None:
        self.room = 0
        self.received = b""

    def send(self, data: bytes) -> int:
        if self.room == 0:
            raise BlockingIOError
        taken = data[:self.room]
        self.room -= len(taken)
        self.received += taken
        return len(taken)


def test_a_torn_writes_tail_goes_out_before_the_next_sentence() -> None:
    pipe = _Pipe()
    out = WholeWrites(pipe.send)
    a, b, c = _sentences(3)
    pipe.room = 10
    out.write(a)  # the kernel takes 10 bytes of 60
    out.write(b)  # nothing taken: b is dropped whole, a's tail still waits
    pipe.room = 1000
    out.write(c)
    assert pipe.received == a + c
    assert out.dropped_bytes == len(b)


def test_a_tail_still_unsent_when_the_reader_goes_is_counted() -> None:
    pipe = _Pipe()
    out = WholeWrites(pipe.send)
    (a,) = _sentences(1)
    pipe.room = 25
    out.write(a)
    out.close()
    assert out.dropped_bytes == len(a) - 25


def test_a_slow_tcp_client_gets_whole_sentences_in_order_and_the_rest_is_counted() -> None:
    tcp = TcpTransport(0, stall_s=60.0)
    client = socket.create_connection(("127.0.0.1", tcp.port), timeout=5.0)
    sent = _sentences(150_000)
    received = bytearray()
    try:
        for i, sentence in enumerate(sent):
            tcp.write(sentence)
            # the app reads once half way: the 4.5 MB before that overflow loopback's
            # buffers (at most 4 MB of send buffer by default)
            if i == len(sent) // 2:
                client.settimeout(0.2)
                try:
                    while chunk := client.recv(65536):
                        received += chunk
                except TimeoutError:
                    pass
        dropped_while_connected = tcp.dropped_bytes
        tcp.close()  # a tail still waiting is dropped and counted here
        client.settimeout(5.0)
        while chunk := client.recv(65536):
            received += chunk
    finally:
        client.close()
    got = _lines(bytes(received))
    assert dropped_while_connected > 0  # the client was slow enough to lose some
    assert _in_order(got, sent)
    # every byte written either reached the client or is counted (a tail cut off by the
    # close included: its head is the last, unterminated bytes received)
    assert len(received) + tcp.dropped_bytes == sum(len(s) for s in sent)


def test_a_pty_reader_that_lags_gets_whole_sentences_in_order(tmp_path: Path) -> None:
    pty = PtyTransport()
    reader = os.open(pty.slave_path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(reader, termios.TCSANOW)
    sent = _sentences(2000)
    received = b""

    def drain() -> bytes:
        out = b""
        while True:
            try:
                chunk = os.read(reader, 65536)
            except BlockingIOError:
                return out
            if not chunk:
                return out
            out += chunk

    try:
        for i, sentence in enumerate(sent):
            pty.write(sentence)
            if i % 400 == 399:
                received += drain()
        received += drain()
    finally:
        pty.close()
        os.close(reader)
    got = _lines(received)
    assert pty.dropped_bytes > 0
    assert _in_order(got, sent)
    assert len(received) + pty.dropped_bytes == sum(len(s) for s in sent)


def test_a_run_says_how_many_bytes_its_nmea_reader_did_not_take() -> None:
    # nobody reads the pty: once its buffer (64 KiB in Linux) is full every sentence is
    # dropped; 40 s of the default sentences are about 90 kB
    run = subprocess.run(
        [sys.executable, "-m", "imuhal.cli.main", "run", "--emulate", "thermal",
         "--skip-calibration", "--duration", "40", "--nmea", "pty"],
        capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stderr
    said = [line for line in run.stderr.splitlines() if "bytes dropped" in line]
    assert len(said) == 1 and said[0].startswith("nmea: pseudo-terminal /dev/pts/"), run.stderr
