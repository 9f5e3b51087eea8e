"""The broker address of ``--mqtt URL``: ``mqtt://`` (plain TCP, port 1883) or ``mqtts://``
(TLS, port 8883), with credentials from the URL or the environment.

Credentials are never shown: :meth:`Broker.display` (what the run prints) has neither the user
name nor the password, and the errors here never repeat the URL.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from urllib.parse import unquote, urlsplit

from imuhal.core.errors import ImuhalError

USERNAME_ENV = "IMUHAL_MQTT_USERNAME"
PASSWORD_ENV = "IMUHAL_MQTT_PASSWORD"
"""Where the credentials come from when the URL has none (keeps them out of shell history
and process lists)."""

_PORTS = {"mqtt": 1883, "mqtts": 8883}


@dataclass(frozen=True)
class Broker:
    host: str
    port: int
    tls: bool
    username: str | None = field(default=None, repr=False)
    password: str | None = field(default=None, repr=False)

    def display(self) -> str:
        """The address without credentials (``mqtts://host:8883``)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'mqtts' if self.tls else 'mqtt'}://{host}:{self.port}"


def parse_broker_url(url: str, env: Mapping[str, str], what: str = "--mqtt") -> Broker:
    """``mqtt[s]://[USER[:PASSWORD]@]HOST[:PORT]``; without USER in the URL, the user name
    and password come from IMUHAL_MQTT_USERNAME / IMUHAL_MQTT_PASSWORD when set."""
    try:
        parts = urlsplit(url.strip())
        port = parts.port
    except ValueError:
        raise ImuhalError(f"{what}: the broker URL's port is not a number from 0 to 65535; "
                          "write mqtt://HOST:PORT") from None
    scheme = parts.scheme.lower()
    if scheme not in _PORTS:
        raise ImuhalError(f"{what}: the broker URL must start with mqtt:// or mqtts:// (TLS), "
                          f"not {scheme + '://' if scheme else 'nothing'}; e.g. "
                          "mqtt://localhost:1883")
    if not parts.hostname:
        raise ImuhalError(f"{what}: the broker URL names no host; write {scheme}://HOST[:PORT]")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ImuhalError(f"{what}: the broker URL has a path or query; write "
                          f"{scheme}://HOST[:PORT] (topics come from the profile's board name)")
    if parts.username is not None:
        username: str | None = unquote(parts.username)
        password = unquote(parts.password) if parts.password is not None else None
    else:
        username = env.get(USERNAME_ENV) or None
        password = env.get(PASSWORD_ENV) or None
        if password is not None and username is None:
            raise ImuhalError(f"{PASSWORD_ENV} is set but {USERNAME_ENV} is not; set both "
                              "(or put USER:PASSWORD@ in the URL)")
    return Broker(host=parts.hostname, port=port or _PORTS[scheme], tls=scheme == "mqtts",
                  username=username, password=password)
