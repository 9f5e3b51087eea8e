"""The NMEA TCP server is bounded (issue 26 item 4): a client limit, stalled clients
dropped, a process out of descriptors refusing clients instead of ending the run, and a
warning when it listens beyond this machine. 1,000 connections: tests/benchmarks/
server_flood.py."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from imuhal.sinks.flight.transports import MAX_TCP_CLIENTS, TcpTransport

SENTENCE = b"$LK8EX1,101325,99999,0,25,999,*0A\r\n"


def _connect(port: int, n: int) -> list[socket.socket]:
    out = []
    for _ in range(n):
        s = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        out.append(s)
    return out


def _open_descriptors() -> int:
    return len(os.listdir("/proc/self/fd"))


def test_three_hundred_connections_get_at_most_the_client_limit_and_the_rest_are_refused(
        ) -> None:
    tcp = TcpTransport(0)
    base = _open_descriptors()
    sockets: list[socket.socket] = []
    try:
        for _ in range(75):  # the backlog holds 4 waiting connections: accept as they come
            sockets += _connect(tcp.port, 4)
            tcp.write(SENTENCE)
        assert tcp.clients == MAX_TCP_CLIENTS
        assert tcp.refused_clients == 300 - MAX_TCP_CLIENTS
        # the server's own descriptors: the clients it kept, nothing for the refused ones
        assert _open_descriptors() - base - len(sockets) == MAX_TCP_CLIENTS
        for s in sockets[:MAX_TCP_CLIENTS]:
            assert s.recv(4096).startswith(SENTENCE)
        sockets[-1].settimeout(1.0)
        assert sockets[-1].recv(4096) == b""  # refused: closed at once
    finally:
        for s in sockets:
            s.close()
        tcp.close()


def test_a_client_that_stops_reading_is_dropped_after_the_stall_time() -> None:
    tcp = TcpTransport(0, stall_s=0.2)
    (stuck,) = _connect(tcp.port, 1)
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    try:
        deadline = time.monotonic() + 20.0
        while tcp.clients and time.monotonic() < deadline:
            tcp.write(SENTENCE * 1000)
        assert tcp.clients == 0 and tcp.stalled_clients == 1
    finally:
        stuck.close()
        tcp.close()


def test_a_process_out_of_descriptors_refuses_clients_and_keeps_writing(tmp_path: Path) -> None:
    """60 connections under a limit of 64 descriptors: accept() fails with EMFILE, which
    used to end the run with exit 70."""
    script = tmp_path / "emfile.py"
    script.write_text(textwrap.dedent("""
        import resource, socket, sys
        resource.setrlimit(resource.RLIMIT_NOFILE, (64, 64))
        from imuhal.sinks.flight.transports import TcpTransport
        tcp = TcpTransport(0, max_clients=1000)
        clients = []
        for _ in range(60):
            try:
                clients.append(socket.create_connection(("127.0.0.1", tcp.port), timeout=1))
            except OSError:
                break
            tcp.write(b"$X*00\\r\\n")
        for _ in range(10):
            tcp.write(b"$X*00\\r\\n")
        print(tcp.clients, tcp.refused_clients)
    """))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    kept, refused = map(int, done.stdout.split())
    assert kept > 0 and refused > 0


def test_listening_beyond_loopback_comes_with_a_warning() -> None:
    loopback, wide = TcpTransport(0), TcpTransport(0, "0.0.0.0")
    try:
        assert loopback.exposure is None
        assert wide.exposure is not None and "reachable from the network" in wide.exposure
    finally:
        loopback.close()
        wide.close()
