"""A real mosquitto broker for the MQTT tests and benchmarks, and a subscriber that records
what it receives.

The broker runs as a child process on a free loopback port with its own configuration in a
temporary directory. It persists its sessions (saved when it stops, restored when it starts
again on the same port), so a subscriber with a persistent session misses nothing while the
broker is down and the publisher's queue fills.
"""

from __future__ import annotations

import getpass
import json
import os
import shutil
import socket
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

MOSQUITTO_PATHS = ("/usr/sbin/mosquitto", "/usr/bin/mosquitto")


def mosquitto_binary() -> str | None:
    """The mosquitto program (Debian puts it in /usr/sbin, often not on a user's PATH)."""
    found = shutil.which("mosquitto")
    if found:
        return found
    return next((p for p in MOSQUITTO_PATHS if os.access(p, os.X_OK)), None)


def self_signed_certificate(directory: Path) -> tuple[Path, Path] | None:
    """A certificate and key (PEM) for 127.0.0.1, made with the openssl program; None when
    it is not installed."""
    openssl = shutil.which("openssl")
    if openssl is None:
        return None
    cert, key = directory / "broker.crt", directory / "broker.key"
    subprocess.run([openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                    "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1",
                    "-keyout", str(key), "-out", str(cert)], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return cert, key


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Mosquitto:
    """``start()`` / ``stop()`` (SIGTERM: it saves its sessions) on one port, any number of
    times."""

    def __init__(self, directory: Path, port: int | None = None, *,
                 users: dict[str, str] | None = None,
                 tls: tuple[Path, Path] | None = None) -> None:
        """``users`` (name -> password): anonymous clients are refused; ``tls`` (certificate,
        key, PEM): the listener speaks TLS only."""
        binary = mosquitto_binary()
        if binary is None:
            raise FileNotFoundError("mosquitto")
        self.binary = binary
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.port = port if port is not None else free_port()
        self.config = self.directory / "mosquitto.conf"
        access = "allow_anonymous true\n"
        if users:
            passwords = self.directory / "passwords"
            passwords.touch(mode=0o600)
            for name, password in users.items():
                # mosquitto_passwd comes with the broker (same Debian package)
                subprocess.run([shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd",
                                "-b", str(passwords), name, password], check=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            access = f"allow_anonymous false\npassword_file {passwords}\n"
        if tls:
            access += f"certfile {tls[0]}\nkeyfile {tls[1]}\n"
        self.scheme = "mqtts" if tls else "mqtt"
        # max_queued_messages 0: a persistent subscriber's backlog is never cut by the broker
        # user: started by root, mosquitto would switch to the user "mosquitto", which
        # cannot read this directory (its sessions would then be lost when it stops)
        self.config.write_text(
            f"user {getpass.getuser()}\n"
            f"listener {self.port} 127.0.0.1\n"
            f"{access}"
            "persistence true\n"
            f"persistence_location {self.directory}/\n"
            "autosave_interval 0\n"
            "max_queued_messages 0\n"
            "max_inflight_messages 0\n"
            f"log_dest file {self.directory}/mosquitto.log\n",
            encoding="utf-8")
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"{self.scheme}://127.0.0.1:{self.port}"

    def start(self, timeout_s: float = 10.0) -> None:
        self.process = subprocess.Popen([self.binary, "-c", str(self.config)],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if self.process.poll() is not None:
                raise RuntimeError(f"mosquitto exited ({self.process.returncode}); see "
                                   f"{self.directory}/mosquitto.log")
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return
            except OSError:
                time.sleep(0.05)
        raise RuntimeError(f"mosquitto did not listen on port {self.port} in {timeout_s} s")

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)
        self.process = None

    def __enter__(self) -> Mosquitto:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


@dataclass
class Received:
    topic: str
    payload: dict[str, Any]
    received_unix_s: float


@dataclass
class Subscriber:
    """Subscribes to ``topic`` with QoS 1 and a persistent session (it gets what was
    published while it was away, once the broker is back); ``messages`` in arrival order."""

    port: int
    topic: str = "imuhal/#"
    client_id: str = "imuhal-test-subscriber"
    messages: list[Received] = field(default_factory=list)
    username: str | None = None
    password: str | None = None
    ca_file: Path | None = None
    """TLS: the broker's certificate (or its CA), PEM."""

    def __post_init__(self) -> None:
        import paho.mqtt.client as mqtt

        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=self.client_id,
                             clean_session=False, protocol=mqtt.MQTTv311)
        client.reconnect_delay_set(1, 1)
        if self.username is not None:
            client.username_pw_set(self.username, self.password)
        if self.ca_file is not None:
            client.tls_set(ca_certs=str(self.ca_file))
        client.max_inflight_messages_set(0)
        client.on_connect = lambda c, *_: c.subscribe(self.topic, qos=1)
        client.on_subscribe = lambda *_: self._subscribed.set()
        client.on_message = self._on_message
        self._client = client

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        item = Received(message.topic, json.loads(message.payload), time.time())
        with self._lock:
            self.messages.append(item)

    def start(self, timeout_s: float = 10.0) -> None:
        self._client.connect("127.0.0.1", self.port, keepalive=5)
        self._client.loop_start()
        if not self._subscribed.wait(timeout_s):
            raise RuntimeError("the subscriber was not subscribed in time")

    def stop(self) -> None:
        self._client.disconnect()
        self._client.loop_stop()

    def wait_for(self, count: int, timeout_s: float = 15.0) -> list[Received]:
        """The messages once ``count`` have arrived (or all so far after ``timeout_s``)."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and len(self.messages) < count:
            time.sleep(0.05)
        with self._lock:
            return list(self.messages)


def deduplicated(messages: list[Received]) -> dict[str, list[Received]]:
    """Per topic, the messages a receiver keeps (docs/outputs.md): a message whose (run,
    seq) is not after the last one kept on its topic is a duplicate."""
    out: dict[str, list[Received]] = {}
    last: dict[str, tuple[int, int]] = {}
    for m in messages:
        key = (m.payload["run"], m.payload["seq"])
        if m.topic in last and key <= last[m.topic]:
            continue
        last[m.topic] = key
        out.setdefault(m.topic, []).append(m)
    return out
