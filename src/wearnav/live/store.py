"""The receiver's on-disk session store: SQLite, one row per accepted message.

Rows are keyed by (session_id, device_id, message_id), so a message sent twice is stored once
(``INSERT OR IGNORE``); each insert is committed (WAL journal, ``synchronous=FULL``: on disk
before the call returns) before the receiver answers 200, so nothing acknowledged is lost when
the process is killed. The body is kept as received (UTF-8 JSON text), and a session's
settings (platform, standardisation: what Sensor Logger does not send) beside it; the live
buffers are rebuilt from here on restart.

Group commit (issue 37): messages that arrive while a transaction is being committed wait and go
into the next one together (:class:`GroupCommit`), so many sessions' pushes cost one ``fsync``
(measured on this machine: 3.4 ms a commit, which alone capped one receiver near 290 messages a
second), and each is still on disk before its 200.

Tracker processes (``wearnav live track``) read the messages by row id as they arrive
(:meth:`Store.messages_after`) and write each session's page state into ``states``, which a
receiver that does not track itself serves (:meth:`Store.state`).

Decision: docs/decisions/0028-live-crowd.md.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Callable, Iterator
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
CREATE TABLE IF NOT EXISTS states (
    session_id TEXT PRIMARY KEY,
    updated_ns INTEGER NOT NULL,
    state TEXT NOT NULL
);
"""
BUSY_TIMEOUT_S = 30.0  # several processes share the file: a writer waits this long for another's lock


class _Pending:
    __slots__ = ("item", "result", "error", "done")

    def __init__(self, item):
        self.item, self.result, self.error, self.done = item, None, None, False


class GroupCommit:
    """``submit(item)`` from many threads: items that arrive while ``flush`` runs on a batch wait
    and are flushed together by the next caller (one leader at a time, no thread of its own);
    each ``submit`` returns its own item's result once the batch holding it is flushed, or raises
    the batch's error. ``flush(items) -> results`` (in order) commits them in one transaction."""

    def __init__(self, flush: Callable[[list], list]):
        self._flush = flush
        self._queue: list[_Pending] = []
        self._queue_lock = threading.Lock()
        self._leader = threading.Lock()
        self.batches = 0
        self.items = 0

    def submit(self, item):
        p = _Pending(item)
        with self._queue_lock:
            self._queue.append(p)
        with self._leader:
            if not p.done:  # not flushed by the previous leader: flush everything waiting
                with self._queue_lock:
                    batch, self._queue = self._queue, []
                try:
                    results = self._flush([q.item for q in batch])
                except BaseException as exc:
                    for q in batch:
                        q.error, q.done = exc, True
                else:
                    for q, r in zip(batch, results):
                        q.result, q.done = r, True
                self.batches += 1
                self.items += len(batch)
        if p.error is not None:
            raise p.error
        return p.result


class Store:
    """One SQLite file; safe to call from several threads (one connection, one lock)."""

    def __init__(self, path: str | Path, readonly: bool = False):
        self.path = Path(path)
        if readonly:
            self._db = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, check_same_thread=False)
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
            self._db.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.executescript(SCHEMA)
        self._lock = threading.Lock()

    def add(
        self, session_id: str, device_id: str, message_id: int, body: str, platform: str, standardised: bool
    ) -> bool:
        """Store one message (and its session's settings, the first time); True when new, False
        for a repeat (nothing changes). Committed to disk when this returns."""
        return self.add_many([(session_id, device_id, message_id, body, platform, standardised)])[0]

    def add_many(self, rows: list[tuple[str, str, int, str, str, bool]]) -> list[bool]:
        """:meth:`add` for each of ``rows`` (session, device, message id, body, platform,
        standardised), in order, in one transaction: on disk when this returns."""
        now = time.time_ns()
        new = []
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                for session_id, device_id, message_id, body, platform, standardised in rows:
                    cur = self._db.execute(
                        "INSERT OR IGNORE INTO messages VALUES (?, ?, ?, ?, ?)",
                        (session_id, device_id, message_id, now, body),
                    )
                    new.append(cur.rowcount == 1)
                    if new[-1]:
                        self._db.execute(
                            "INSERT OR IGNORE INTO sessions VALUES (?, ?, ?, ?)",
                            (session_id, platform, int(standardised), now),
                        )
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
        return new

    def messages_after(self, rowid: int, limit: int = 10_000) -> list[tuple[int, str, str, bool, int, str]]:
        """Messages stored after row ``rowid``, oldest first, at most ``limit``: (rowid, session,
        platform, standardised, received_ns, body); a tracker process reads on from the last rowid."""
        with self._lock:
            return self._db.execute(
                "SELECT m.rowid, m.session_id, s.platform, s.standardised, m.received_ns, m.body "
                "FROM messages m JOIN sessions s ON s.session_id = m.session_id "
                "WHERE m.rowid > ? ORDER BY m.rowid LIMIT ?",
                (rowid, limit),
            ).fetchall()

    def put_states(self, states: dict[str, str]) -> None:
        """Each session's page state (JSON text), replacing the last, in one transaction."""
        if not states:
            return
        now = time.time_ns()
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                self._db.executemany(
                    "INSERT OR REPLACE INTO states VALUES (?, ?, ?)", [(sid, now, st) for sid, st in states.items()]
                )
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise

    def state(self, session_id: str) -> dict | None:
        """The page state a tracker process wrote for the session last (None: none yet)."""
        with self._lock:
            row = self._db.execute("SELECT state FROM states WHERE session_id = ?", (session_id,)).fetchone()
        return None if row is None else json.loads(row[0])

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


__all__ = ["GroupCommit", "Store"]
