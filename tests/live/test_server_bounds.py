"""The live view's server is bounded (issue 26 item 4): a flood of connections costs at most
MAX_CONNECTIONS threads, idle ones are closed, and the Host header is checked on any bind
(1,000 connections with a running board: tests/benchmarks/server_flood.py)."""

from __future__ import annotations

import http.client
import socket
import threading
import time

from imuhal.live import LiveView
from imuhal.live.server import MAX_CONNECTIONS


def _get(port: int, host: str, path: str = "/state.json") -> int:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5.0)
    try:
        conn.putrequest("GET", path, skip_host=True)
        conn.putheader("Host", host)
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def test_three_hundred_idle_connections_cost_at_most_the_connection_limit_in_threads() -> None:
    """Issue 26 item 4: 1,000 idle sockets used to start 653 threads. The view keeps
    answering meanwhile, and the idle ones are closed after the idle timeout."""
    with LiveView(idle_timeout_s=1.0) as live:
        port = live._server.server_address[1]  # type: ignore[union-attr]
        before = threading.active_count()
        most = 0
        idle = []
        try:
            for _ in range(300):
                idle.append(socket.create_connection(("127.0.0.1", port), timeout=5.0))
                most = max(most, threading.active_count() - before)
            deadline = time.monotonic() + 3.0
            while time.monotonic() < deadline:
                most = max(most, threading.active_count() - before)
                time.sleep(0.01)
            assert most <= MAX_CONNECTIONS
            assert live.refused_connections > 0
            assert _get(port, "127.0.0.1") == 200  # still answering
            for s in idle:  # every idle socket was closed: refused, or timed out
                s.settimeout(5.0)
                assert s.recv(16) == b""
            time.sleep(0.5)
            assert threading.active_count() - before <= 1
        finally:
            for s in idle:
                s.close()


def test_a_view_bound_beyond_loopback_refuses_a_foreign_host_name() -> None:
    """DNS rebinding: a page on evil.example whose name now points at this machine sends
    Host: evil.example. Addresses and this machine's name are still served."""
    with LiveView(host="0.0.0.0") as live:
        port = live._server.server_address[1]  # type: ignore[union-attr]
        assert _get(port, f"evil.example:{port}") == 403
        assert _get(port, "") == 403
        assert _get(port, f"192.168.1.5:{port}") == 200
        assert _get(port, f"{socket.gethostname()}.local:{port}") == 200
        assert live.exposure is not None and "reachable from the network" in live.exposure


def test_a_loopback_view_still_answers_to_loopback_names_only() -> None:
    with LiveView() as live:
        port = live._server.server_address[1]  # type: ignore[union-attr]
        assert _get(port, f"localhost:{port}") == 200
        assert _get(port, f"192.168.1.5:{port}") == 403
        assert live.exposure is None
