"""The live view's web server: standard library only (http.server + server-sent events).

Why the standard library: the page needs a handful of GET routes and a one-way stream of
JSON at 10-30 Hz. Server-sent events are plain HTTP (``text/event-stream``) that every
browser reconnects by itself, so ``ThreadingHTTPServer`` covers it with no dependency to
install on a Raspberry Pi in a field, and nothing to keep patched (docs/live-view.md).

Threads: the pipeline thread only calls :meth:`LiveSink.handle`. One publisher thread builds
a snapshot every ``1 / rate_hz`` s, encodes it once and wakes the clients. Each client has its
own thread that sends the newest message when it is ready for one (older ones are skipped,
never queued) with a send timeout: a client that stops reading is dropped after
``client_timeout_s`` and never holds anyone else up.

Bounded: at most ``MAX_CONNECTIONS`` handler threads (more connections are closed at once),
an idle connection is closed after ``IDLE_TIMEOUT_S``, and a process out of descriptors
refuses clients rather than failing.

Read-only: GET is the only method (anything else is 405), no route changes the board or
writes a file, and the server answers only to Host names that are its own: loopback names
when bound to the loopback, and beyond it IP addresses, this machine's host name or names
the caller allows (a web page elsewhere cannot reach it through DNS rebinding).
"""

from __future__ import annotations

import errno
import ipaddress
import json
import math
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from imuhal.core.errors import ImuhalError
from imuhal.live.sink import LiveSink
from imuhal.live.snapshot import Snapshotter, Truth
from imuhal.pipeline import Pipeline

DEFAULT_HOST = "127.0.0.1"
DEFAULT_RATE_HZ = 20.0
MAX_CLIENTS = 16
SEND_BUFFER_BYTES = 64 * 1024
STATIC = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/app.js": ("app.js", "text/javascript; charset=utf-8"),
    "/style.css": ("style.css", "text/css; charset=utf-8"),
    "/favicon.svg": ("favicon.svg", "image/svg+xml"),
    "/favicon.ico": ("favicon.svg", "image/svg+xml"),
}
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'none'; script-src 'self'; style-src 'self'; "
                               "connect-src 'self'; img-src 'self'; form-action 'none'; "
                               "frame-ancestors 'none'; base-uri 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}
LOOPBACK_NAMES = {"localhost", "127.0.0.1", "::1", "[::1]"}
MAX_CONNECTIONS = MAX_CLIENTS + 8
"""Connections served at once, each on its own thread: the event streams plus a few page
and state requests. More are closed at once (counted in ``LiveView.refused_connections``),
so a flood of sockets costs no more threads than this."""
IDLE_TIMEOUT_S = 5.0
"""A connection that sends no (next) request for this long is closed, freeing its thread."""
_NO_DESCRIPTOR = (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM)


class _BoundedHTTPServer(ThreadingHTTPServer):
    """``ThreadingHTTPServer`` with at most ``max_connections`` handler threads, and a
    process out of descriptors (EMFILE at accept) refusing clients without spinning."""

    daemon_threads = True
    allow_reuse_address = True
    max_connections = MAX_CONNECTIONS
    request_queue_size = 64  # a burst waits to be served or refused, not SYN-retried

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._slots = threading.BoundedSemaphore(self.max_connections)
        self.refused = 0

    def get_request(self) -> tuple[socket.socket, Any]:
        try:
            return super().get_request()
        except OSError as exc:
            if exc.errno in _NO_DESCRIPTOR:
                # The client stays in the backlog; socketserver drops this OSError, and the
                # pause keeps the listening socket's readiness from spinning the thread.
                self.refused += 1
                time.sleep(0.05)
            raise

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            self.refused += 1
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()


@dataclass(frozen=True)
class BindAddress:
    host: str
    port: int

    @property
    def loopback(self) -> bool:
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False


def parse_bind(spec: str | int) -> BindAddress:
    """``"8080"`` -> 127.0.0.1:8080; ``"0.0.0.0:8080"``, ``"192.168.1.5:8080"``,
    ``"[::]:8080"`` bind that interface. Port 0 picks a free port."""
    text = str(spec).strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = DEFAULT_HOST, text
    host = host.strip("[]") or DEFAULT_HOST
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise ImuhalError(f"--web {spec!r}: give [HOST:]PORT with a port from 0 to 65535, "
                          f"e.g. --web 8080 (this machine only) or --web 0.0.0.0:8080 "
                          f"(reachable from the network)")
    return BindAddress(host, port)


class LiveView:
    """A dashboard for a running pipeline, served over HTTP.

    Feed ``live.sink`` every event (``pipeline.run(duration, [live.sink])``, or call
    ``live.sink.handle(event)`` in your own loop). Use as a context manager, or call
    :meth:`start` and :meth:`close`.
    """

    def __init__(self, pipeline: Pipeline | None = None, *, host: str = DEFAULT_HOST,
                 port: int = 0, rate_hz: float = DEFAULT_RATE_HZ,
                 truth: Callable[[], Truth | None] | None = None,
                 scenario: str | None = None, client_timeout_s: float = 2.0,
                 sink: LiveSink | None = None, idle_timeout_s: float = IDLE_TIMEOUT_S,
                 max_connections: int = MAX_CONNECTIONS,
                 allowed_hosts: tuple[str, ...] = ()) -> None:
        if not 1.0 <= rate_hz <= 60.0:
            raise ImuhalError(f"live view rate {rate_hz:g} Hz: use 1 to 60 Hz (10-30 is a "
                              f"display rate)")
        self.sink = sink if sink is not None else LiveSink()
        self.snapshotter = Snapshotter(self.sink, pipeline, truth=truth, scenario=scenario)
        self.bind = BindAddress(host, port)
        self.period_s = 1.0 / rate_hz
        self.client_timeout_s = client_timeout_s
        self.idle_timeout_s = idle_timeout_s
        self.max_connections = max_connections
        self.allowed_hosts = {h.lower() for h in allowed_hosts}
        """Host names the view answers to beyond IP literals (bound beyond loopback: this
        machine's host name and NAME.local are added)."""
        self.clients = 0
        self.dropped_clients = 0
        self.messages_built = 0
        self.publish_errors = 0
        self._cond = threading.Condition()
        self._message: bytes = b""
        self._state: dict[str, Any] = {}
        self._seq = 0
        self._stop = threading.Event()
        self._server: ThreadingHTTPServer | None = None
        self._threads: list[threading.Thread] = []
        self._delivered: dict[int, int] = {}  # client -> last sequence number written to it

    @classmethod
    def for_pipeline(cls, pipeline: Pipeline, **kwargs: Any) -> LiveView:
        """A live view of ``pipeline``; an emulated board's truth is shown beside the
        estimates."""
        from imuhal.emulation import EmulatedBoard

        board = pipeline.board
        if isinstance(board, EmulatedBoard):
            kwargs.setdefault("truth", lambda: board.truth)
            kwargs.setdefault("scenario", board.scenario.name)
        return cls(pipeline, **kwargs)

    # -- lifecycle ------------------------------------------------------------------------

    @property
    def refused_connections(self) -> int:
        """Connections closed unserved: over ``max_connections``, or no descriptor left."""
        return self._server.refused if isinstance(self._server, _BoundedHTTPServer) else 0

    @property
    def exposure(self) -> str | None:
        """A warning when the view is reachable beyond this machine, else None."""
        if self.bind.loopback:
            return None
        return (f"the live view on {self.bind.host}:{self.bind.port} is reachable from the "
                "network: anyone on it can watch the flight (read-only, at most "
                f"{MAX_CLIENTS} viewers); bind 127.0.0.1 unless a phone or tablet needs it")

    def answers_to(self, host_header: str) -> bool:
        """Whether a request's ``Host`` names this view. Bound to loopback: loopback names
        only. Beyond: an IP address, a loopback name, this machine's host name (also with
        ``.local``) or an ``allowed_hosts`` name; never an unknown DNS name, which is what
        a page using DNS rebinding sends."""
        name = (urlsplit(f"//{host_header}").hostname or "").lower() if host_header else ""
        if not name:
            return False
        if name in LOOPBACK_NAMES:
            return True
        if self.bind.loopback:
            return False
        try:
            ipaddress.ip_address(name)
            return True
        except ValueError:
            pass
        own = socket.gethostname().lower()
        return name in self.allowed_hosts or name in (own, f"{own}.local")

    @property
    def url(self) -> str:
        if self._server is None:
            raise ImuhalError("the live view is not started")
        host, port = self._server.server_address[:2]
        shown = str(host)
        if ":" in shown:
            shown = f"[{shown}]"
        return f"http://{shown}:{port}/"

    def start(self) -> LiveView:
        handler = _handler_for(self)
        try:
            family = socket.AF_INET6 if ":" in self.bind.host else socket.AF_INET
            server_cls = type("LiveHTTPServer", (_BoundedHTTPServer,),
                              {"address_family": family,
                               "max_connections": self.max_connections})
            self._server = server_cls((self.bind.host, self.bind.port), handler)
        except OSError as exc:
            raise ImuhalError(f"live view: cannot listen on {self.bind.host}:{self.bind.port} "
                              f"({exc.strerror or exc}); pick another port with --web PORT "
                              f"or name an address this machine has") from None
        self._publish()
        server = self._server
        for target, name in ((lambda: server.serve_forever(poll_interval=0.1),
                              "imuhal-live-http"),
                             (self._publisher, "imuhal-live-publisher")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def close(self, *, linger_s: float = 2.0) -> None:
        """Stop serving. After a run that ended (the sink closed), the snapshot saying so,
        with the run's summary, is published first and every connected page is given up to
        ``linger_s`` to receive it: the page then shows the end and the summary, not a lost
        connection."""
        if self._server is not None and self.sink.closed and not self._stop.is_set():
            self._publish()
            with self._cond:
                final = self._seq
                self._cond.wait_for(
                    lambda: all(seq >= final for seq in self._delivered.values()),
                    timeout=linger_s)
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._threads.clear()

    def __enter__(self) -> LiveView:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- publishing -----------------------------------------------------------------------

    def _publisher(self) -> None:
        while not self._stop.wait(self.period_s):
            try:
                self._publish()
            except Exception as exc:  # the view must outlive any one bad snapshot
                self.publish_errors += 1
                if self.publish_errors == 1:
                    print(f"imuhal live view: a snapshot failed ({type(exc).__name__}: "
                          f"{exc}); the page keeps the last good one", file=sys.stderr)

    def _publish(self) -> None:
        state = self.snapshotter.snapshot()
        try:
            data = json.dumps(state, separators=(",", ":"), allow_nan=False)
        except ValueError:
            # A diverged estimator's NaN: JSON has no NaN, the page shows "-" for null.
            state = _finite_only(state)
            data = json.dumps(state, separators=(",", ":"), allow_nan=False)
        message = f"id: {state['seq']}\ndata: {data}\n\n".encode()
        with self._cond:
            self._state = state
            self._message = message
            self._seq = state["seq"]
            self.messages_built += 1
            self._cond.notify_all()

    def latest(self) -> dict[str, Any]:
        """The last snapshot sent to the clients."""
        with self._cond:
            return self._state

    def next_message(self, after: int, timeout: float) -> tuple[int, bytes] | None:
        """The newest message after sequence number ``after`` (waiting up to ``timeout``
        s for one); messages a client was too slow for are skipped, not queued."""
        with self._cond:
            if self._seq <= after and not self._stop.is_set():
                self._cond.wait(timeout)
            if self._seq <= after or self._stop.is_set():
                return None
            return self._seq, self._message

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()


def _finite_only(value: Any) -> Any:
    """``value`` with every NaN or infinite float replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_only(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_only(v) for v in value]
    return value


def _static(name: str) -> bytes:
    return resources.files("imuhal.live").joinpath("static").joinpath(name).read_bytes()


def _handler_for(view: LiveView) -> type[BaseHTTPRequestHandler]:
    class Handler(_LiveHandler):
        live = view

    return Handler


class _LiveHandler(BaseHTTPRequestHandler):
    live: LiveView
    server_version = "imuhal-live"
    protocol_version = "HTTP/1.1"

    def setup(self) -> None:
        # StreamRequestHandler applies ``timeout`` to the connection: an idle client (no
        # request, or no next one on a kept-alive connection) is closed after it.
        self.timeout = self.live.idle_timeout_s  # type: ignore[misc]  # socketserver reads the handler's timeout per instance (StreamRequestHandler.setup)
        super().setup()

    def log_message(self, format: str, *args: Any) -> None:
        return None  # the dashboard's requests are not news on the console

    def parse_request(self) -> bool:
        if not super().parse_request():
            return False
        if self.command != "GET":
            # Read-only by construction: one method, whatever the request.
            self.close_connection = True
            self._reply(HTTPStatus.METHOD_NOT_ALLOWED, b"GET only: this view is read-only\n",
                        "text/plain; charset=utf-8", {"Allow": "GET"})
            return False
        if not self.live.answers_to(self.headers.get("Host", "")):
            self.close_connection = True
            body = (b"this view answers to localhost only\n" if self.live.bind.loopback else
                    b"this view answers to its address or host name only\n")
            self._reply(HTTPStatus.FORBIDDEN, body, "text/plain; charset=utf-8")
            return False
        return True

    def _reply(self, status: HTTPStatus, body: bytes, ctype: str,
               extra: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        for key, value in {**SECURITY_HEADERS, **(extra or {})}.items():
            self.send_header(key, value)
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:
        path = urlsplit(self.path).path
        if path in STATIC:
            name, ctype = STATIC[path]
            self._reply(HTTPStatus.OK, _static(name), ctype)
        elif path == "/state.json":
            body = json.dumps(self.live.latest(), allow_nan=False).encode()
            self._reply(HTTPStatus.OK, body, "application/json")
        elif path == "/events":
            self._events()
        else:
            self._reply(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain; charset=utf-8")

    def _events(self) -> None:
        live = self.live
        with live._cond:
            full = live.clients >= MAX_CLIENTS
            if not full:
                live.clients += 1
        if full:
            self._reply(HTTPStatus.SERVICE_UNAVAILABLE, b"too many viewers\n",
                        "text/plain; charset=utf-8", {"Retry-After": "5"})
            return
        self.close_connection = True
        try:
            # A small send buffer bounds what a stuck client costs and makes it time out
            # within seconds rather than after megabytes.
            self.connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
            self.connection.settimeout(live.client_timeout_s)
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            for key, value in SECURITY_HEADERS.items():
                self.send_header(key, value)
            self.end_headers()
            self.wfile.write(b"retry: 1000\n\n")
            seq = 0
            with live._cond:
                live._delivered[id(self)] = seq
            idle = 0.0
            while not live.stopping:
                got = live.next_message(seq, timeout=1.0)
                if got is None:
                    idle += 1.0
                    if idle >= 15.0:  # a comment keeps proxies from closing a quiet stream
                        self.wfile.write(b": keep-alive\n\n")
                        idle = 0.0
                    continue
                idle = 0.0
                seq, message = got
                self.wfile.write(message)
                self.wfile.flush()
                with live._cond:
                    live._delivered[id(self)] = seq
                    live._cond.notify_all()
        except TimeoutError:
            # The client stopped reading for client_timeout_s: drop it.
            with live._cond:
                live.dropped_clients += 1
        except OSError:
            pass  # the browser went away
        finally:
            with live._cond:
                live.clients -= 1
                live._delivered.pop(id(self), None)
                live._cond.notify_all()
