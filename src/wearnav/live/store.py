"""The receiver's on-disk session store: SQLite, one row per accepted message.

Rows are keyed by (session_id, device_id, message_id), so a message sent twice is stored once
(``INSERT OR IGNORE``); each insert is committed (WAL journal, ``synchronous=FULL``: on disk
before the call returns) before the receiver answers 200, so nothing acknowledged is lost when
the process is killed. The body is kept as received (UTF-8 JSON text), and a session's
settings (platform, standardisation: what Sensor Logger does not send) beside it; the live
buffers are rebuilt from here on restart.
"""

from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

SCHEMA = """
CREATE TABLE IF NOT EXISTS messages (
    session_id TEXT NOT NULL,
    device_id TEXT NOT NULL,
    message_id INTEGER NOT NULL,
    received_ns INTEGER NOT NULL,
    body TEXT NOT NULL,
    PRIMARY KEY (session_id, device_id, message_id)
);
CREATE TABLE IF NOT EXISTS sessions (
    session_id TEXT PRIMARY KEY,
    platform TEXT NOT NULL,
    standardised INTEGER NOT NULL,
    created_ns INTEGER NOT NULL
);
"""


class Store:
    """One SQLite file; safe to call from several threads (one connection, one lock)."""

    def __init__(self, path: str | Path, readonly: bool = False):
        self.path = Path(path)
        if readonly:
            self._db = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, check_same_thread=False)
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.executescript(SCHEMA)
        self._lock = threading.Lock()

    def add(
        self, session_id: str, device_id: str, message_id: int, body: str, platform: str, standardised: bool
    ) -> bool:
        """Store one message (and its session's settings, the first time); True when new, False
        for a repeat (nothing changes). Committed to disk when this returns."""
        now = time.time_ns()
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                cur = self._db.execute(
                    "INSERT OR IGNORE INTO messages VALUES (?, ?, ?, ?, ?)",
                    (session_id, device_id, message_id, now, body),
                )
                new = cur.rowcount == 1
                if new:
                    self._db.execute(
                        "INSERT OR IGNORE INTO sessions VALUES (?, ?, ?, ?)",
                        (session_id, platform, int(standardised), now),
                    )
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
        return new

    def sessions(self) -> dict[str, dict]:
        """{session_id: {"platform", "standardised", "created_ns", "messages"}} in creation order."""
        with self._lock:
            rows = self._db.execute(
                "SELECT s.session_id, s.platform, s.standardised, s.created_ns, "
                "(SELECT COUNT(*) FROM messages m WHERE m.session_id = s.session_id) "
                "FROM sessions s ORDER BY s.created_ns, s.session_id"
            ).fetchall()
        return {
            r[0]: {"platform": r[1], "standardised": bool(r[2]), "created_ns": r[3], "messages": r[4]} for r in rows
        }

    def messages(self, session_id: str) -> Iterator[tuple[str, int, int, str]]:
        """(device_id, message_id, received_ns, body) of a session in the order they were stored."""
        with self._lock:
            rows = self._db.execute(
                "SELECT device_id, message_id, received_ns, body FROM messages WHERE session_id = ? ORDER BY rowid",
                (session_id,),
            ).fetchall()
        yield from rows

    def message_ids(self, session_id: str) -> set[tuple[str, int]]:
        with self._lock:
            rows = self._db.execute(
                "SELECT device_id, message_id FROM messages WHERE session_id = ?", (session_id,)
            ).fetchall()
        return {(d, m) for d, m in rows}

    def count(self) -> int:
        with self._lock:
            return self._db.execute("SELECT COUNT(*) FROM messages").fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()


__all__ = ["Store"]
