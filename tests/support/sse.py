"""A minimal server-sent-events reader for the live view's tests (standard library)."""

from __future__ import annotations

import http.client
import json
import time
from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit


def sse_messages(url: str, *, timeout_s: float = 10.0) -> Iterator[dict[str, Any]]:
    """Each ``data:`` message of the event stream at ``url`` (``.../events``), parsed as
    JSON, as the browser's EventSource would deliver it; stops after ``timeout_s``."""
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=timeout_s)
    deadline = time.monotonic() + timeout_s
    try:
        conn.request("GET", parts.path or "/")
        resp = conn.getresponse()
        if resp.status != 200:
            raise AssertionError(f"GET {url}: {resp.status} {resp.reason}")
        data: list[str] = []
        while time.monotonic() < deadline:
            line = resp.fp.readline().decode()
            if not line:
                return
            line = line.rstrip("\n")
            if line.startswith("data:"):
                data.append(line[5:].lstrip())
            elif line == "" and data:
                yield json.loads("\n".join(data))
                data = []
    finally:
        conn.close()
