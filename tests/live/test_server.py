"""The live view's server: loopback by default, GET only, read-only headers, its files."""

from __future__ import annotations

import http.client
import socket
from urllib.parse import urlsplit

import pytest

from imuhal.core.errors import ImuhalError
from imuhal.live import LiveView, parse_bind
from imuhal.live.server import DEFAULT_HOST


def _request(url: str, method: str = "GET", path: str = "/", host: str | None = None
             ) -> http.client.HTTPResponse:
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=5)
    headers = {"Host": host} if host is not None else {}
    conn.request(method, path, body=b"x" if method in ("POST", "PUT", "PATCH") else None,
                 headers=headers)
    resp = conn.getresponse()
    resp.read()
    conn.close()
    return resp


@pytest.fixture(scope="module")
def live():
    with LiveView() as view:
        yield view


def test_a_port_alone_binds_the_loopback_only():
    bind = parse_bind("8080")
    assert (bind.host, bind.port) == ("127.0.0.1", 8080)
    assert bind.loopback


def test_another_interface_only_when_named():
    assert parse_bind("0.0.0.0:8080").host == "0.0.0.0"
    assert not parse_bind("0.0.0.0:8080").loopback
    assert parse_bind("[::1]:9000").host == "::1"
    assert parse_bind("[::1]:9000").loopback


@pytest.mark.parametrize("spec", ["http", "70000", "host:", "-1"])
def test_a_bad_web_address_is_a_one_line_error_naming_the_fix(spec):
    with pytest.raises(ImuhalError, match=r"\[HOST:\]PORT"):
        parse_bind(spec)


def test_the_live_view_listens_on_the_loopback_by_default(live):
    assert DEFAULT_HOST == "127.0.0.1"
    assert live._server is not None
    assert live._server.server_address[0] == "127.0.0.1"
    assert live.url.startswith("http://127.0.0.1:")


def test_the_default_bind_is_unreachable_from_another_interface(live):
    """Connecting through a non-loopback address of this machine is refused."""
    port = live._server.server_address[1]
    try:
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        probe.connect(("192.0.2.1", 9))  # no packet is sent: this only picks a route
        own = probe.getsockname()[0]
        probe.close()
    except OSError:
        pytest.skip("this machine has no non-loopback IPv4 address to test from")
    if own.startswith("127."):
        pytest.skip("this machine has no non-loopback IPv4 address to test from")
    with pytest.raises(OSError):
        socket.create_connection((own, port), timeout=2).close()


@pytest.mark.parametrize("method", ["POST", "PUT", "DELETE", "PATCH", "HEAD", "OPTIONS",
                                    "TRACE", "FROB"])
def test_every_method_but_get_is_refused_with_405(live, method):
    for path in ("/", "/events", "/state.json", "/nothing"):
        resp = _request(live.url, method, path)
        assert resp.status == 405, (method, path)
        assert resp.getheader("Allow") == "GET"


def test_the_page_and_its_files_are_served_with_a_policy_that_forbids_forms(live):
    for path, kind in (("/", "text/html"), ("/app.js", "text/javascript"),
                       ("/style.css", "text/css")):
        resp = _request(live.url, "GET", path)
        assert resp.status == 200
        assert resp.getheader("Content-Type").startswith(kind)
        policy = resp.getheader("Content-Security-Policy")
        assert "form-action 'none'" in policy
        assert "default-src 'none'" in policy  # nothing from anywhere else (no CDN)
    assert _request(live.url, "GET", "/etc/passwd").status == 404


def test_a_loopback_view_refuses_foreign_host_names(live):
    """A web page elsewhere cannot read the view through DNS rebinding."""
    assert _request(live.url, "GET", "/", host="attacker.example").status == 403
    assert _request(live.url, "GET", "/", host="localhost").status == 200


def test_the_page_loads_nothing_from_outside_the_package():
    from importlib import resources

    static = resources.files("imuhal.live").joinpath("static")
    for name in ("index.html", "app.js", "style.css"):
        text = static.joinpath(name).read_text()
        assert "http://" not in text and "https://" not in text and "//cdn" not in text, name
    html = static.joinpath("index.html").read_text().lower()
    assert "<form" not in html and "<input" not in html


def test_a_port_in_use_is_a_one_line_error_naming_the_fix(live):
    port = live._server.server_address[1]
    with pytest.raises(ImuhalError, match="pick another port with --web PORT"):
        LiveView(port=port).start()
