"""The MQTT sink's on-disk queue: every message waits here, in order, until the broker
acknowledges it (QoS 1 PUBACK).

A SQLite file (the standard library's ``sqlite3``; WAL journal, so a commit costs no fsync
and a crash loses at most the last commits, never the file). Bounded by a message count and
an age: when either is exceeded the OLDEST messages not yet handed to the broker are deleted
and counted (``dropped``). Messages left at the end of a run stay in the file and go out
first on the next run with the same queue file.

Only one thread uses a queue (the sink's publisher thread); it is opened by the caller's
thread so that a bad path fails before the run starts.
"""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Iterable
from pathlib import Path

from imuhal.core.errors import ImuhalError


class DiskQueue:
    """Messages ``(topic, payload)`` in arrival order, each with the wall time (UNIX
    seconds) it arrived; ids increase with arrival order."""

    def __init__(self, path: str | os.PathLike[str], *, max_messages: int,
                 max_age_s: float) -> None:
        if max_messages < 1 or not max_age_s > 0:
            raise ValueError("a queue holds at least one message for a positive time")
        self.path = Path(path)
        self.max_messages = max_messages
        self.max_age_s = max_age_s
        self.dropped = 0
        """Messages deleted by the limits (oldest first) since this object was opened."""
        self._age_checked_unix_s = -float("inf")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(self.path, check_same_thread=False,
                                       isolation_level=None)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.execute("CREATE TABLE IF NOT EXISTS messages (id INTEGER PRIMARY KEY "
                             "AUTOINCREMENT, topic TEXT NOT NULL, payload BLOB NOT NULL, "
                             "arrived_unix_s REAL NOT NULL)")
            self._count = self._db.execute("SELECT count(*) FROM messages").fetchone()[0]
        except (OSError, sqlite3.Error) as exc:
            raise ImuhalError(f"MQTT queue {self.path}: cannot open it as a SQLite file "
                              f"({exc}); give a writable path in queue_path") from None

    def __len__(self) -> int:
        return self._count

    def append(self, messages: Iterable[tuple[str, bytes, float]]) -> int:
        """Store ``(topic, payload, arrived_unix_s)`` messages at the end; returns how many."""
        rows = list(messages)
        if rows:
            with self._transaction():
                self._db.executemany("INSERT INTO messages (topic, payload, arrived_unix_s) "
                                     "VALUES (?, ?, ?)", rows)
            self._count += len(rows)
        return len(rows)

    def enforce_limits(self, now_unix_s: float, *, keep_through_id: int = 0) -> int:
        """Delete, oldest first, messages older than ``max_age_s`` and those beyond
        ``max_messages``, sparing ids up to ``keep_through_id`` (handed to the broker, their
        acknowledgement pending); returns how many were deleted (also added to ``dropped``)."""
        if self._count == 0:
            return 0
        # the age limit is checked at most once a second (a query per call costs more than
        # the publishing itself at low rates); the count limit whenever it is exceeded
        check_age = now_unix_s - self._age_checked_unix_s >= 1.0
        if not check_age and self._count <= self.max_messages:
            return 0
        with self._transaction():
            gone = 0
            if check_age:
                self._age_checked_unix_s = now_unix_s
                gone = self._db.execute(
                    "DELETE FROM messages WHERE id > ? AND arrived_unix_s < ?",
                    (keep_through_id, now_unix_s - self.max_age_s)).rowcount
            excess = self._count - gone - self.max_messages
            if excess > 0:
                gone += self._db.execute(
                    "DELETE FROM messages WHERE id IN (SELECT id FROM messages WHERE id > ? "
                    "ORDER BY id LIMIT ?)", (keep_through_id, excess)).rowcount
        self._count -= gone
        self.dropped += gone
        return gone

    def after(self, last_id: int, limit: int) -> list[tuple[int, str, bytes]]:
        """Up to ``limit`` messages ``(id, topic, payload)`` with ids above ``last_id``, in
        order."""
        return self._db.execute("SELECT id, topic, payload FROM messages WHERE id > ? "
                                "ORDER BY id LIMIT ?", (last_id, limit)).fetchall()

    def remove(self, ids: Iterable[int]) -> int:
        """Delete the messages with these ids (acknowledged); returns how many there were."""
        keys = [(i,) for i in ids]
        if not keys:
            return 0
        with self._transaction():
            before = self._db.total_changes
            self._db.executemany("DELETE FROM messages WHERE id = ?", keys)
            gone = self._db.total_changes - before
        self._count -= gone
        return gone

    def close(self) -> None:
        self._db.close()

    def _transaction(self) -> _Transaction:
        return _Transaction(self._db)


class _Transaction:
    """BEGIN ... COMMIT (ROLLBACK on an exception): one journal write per batch."""

    def __init__(self, db: sqlite3.Connection) -> None:
        self._db = db

    def __enter__(self) -> None:
        self._db.execute("BEGIN")

    def __exit__(self, exc_type: object, *rest: object) -> None:
        self._db.execute("ROLLBACK" if exc_type is not None else "COMMIT")
