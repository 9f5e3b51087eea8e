"""A browser that stops reading never slows the pipeline: it is skipped, then dropped."""

from __future__ import annotations

import socket
import time
from contextlib import contextmanager
from urllib.parse import urlsplit

from tests.support.sse import sse_messages

from imuhal.emulation import open_emulated
from imuhal.live import LiveView


@contextmanager
def stalled_client(url: str):
    """Opens the event stream and never reads from it (a frozen phone on bad Wi-Fi)."""
    parts = urlsplit(url)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((parts.hostname, parts.port))
    sock.sendall(f"GET /events HTTP/1.1\r\nHost: {parts.hostname}\r\n\r\n".encode())
    try:
        yield sock
    finally:
        sock.close()


def _samples_per_s(plugins, board, live_kwargs: dict | None) -> float:
    """Samples per wall second of a free-running emulated run (as fast as it can go), with
    a live view and a client stalled for the whole run when ``live_kwargs`` is given."""
    with open_emulated(board, plugins, scenario="thermal", seed=5) as pipeline:
        if live_kwargs is None:
            pipeline.run(0.5, [])
            summary = pipeline.run(2.0, [])
        else:
            with LiveView.for_pipeline(pipeline, **live_kwargs) as live, \
                    stalled_client(live.url):
                pipeline.run(0.5, [live.sink])  # full-size messages from here on
                # 40 messages of about 5 kB fill the client's and the server's buffers:
                # from then on the client's thread is stuck in its send.
                built = live.messages_built
                while live.messages_built < built + 40:
                    time.sleep(0.02)
                summary = pipeline.run(2.0, [live.sink])
                assert live.clients == 1  # still connected: stalled, not yet dropped
    return sum(summary.samples.values()) / summary.wall_s


def test_a_stalled_client_does_not_slow_the_pipeline(plugins, seed_board):
    """Samples per wall second with and without the view and a client that never reads,
    interleaved, best of two. The bound is generous (timing on a shared machine): a
    pipeline waiting for the client would stall for the whole 60 s send timeout. The 5 %
    figure is measured by tests/benchmarks/bench_live_view.py (docs/live-view.md)."""
    _samples_per_s(plugins, seed_board, None)  # warm-up: imports, caches
    alone = watched = 0.0
    for _ in range(2):
        alone = max(alone, _samples_per_s(plugins, seed_board, None))
        watched = max(watched, _samples_per_s(plugins, seed_board, {
            "rate_hz": 60.0, "client_timeout_s": 60.0}))
    assert watched > 0.5 * alone, (watched, alone)


def test_a_client_that_stops_reading_is_dropped_and_the_others_keep_their_stream(
        plugins, seed_board):
    with open_emulated(seed_board, plugins, scenario="static", seed=5) as pipeline, \
            LiveView.for_pipeline(pipeline, rate_hz=30.0, client_timeout_s=0.3) as live, \
            stalled_client(live.url):
        deadline = time.monotonic() + 15.0
        while live.dropped_clients == 0 and time.monotonic() < deadline:
            pipeline.run(0.2, [live.sink])  # keeps producing while the client is stuck
        assert live.dropped_clients == 1
        assert live.clients == 0
        reader = sse_messages(live.url + "events", timeout_s=5)
        got = []
        for msg in reader:
            got.append(msg["seq"])
            pipeline.run(0.05, [live.sink])
            if len(got) == 3:
                break
        assert got == sorted(got) and len(set(got)) == 3  # a reading client is served
