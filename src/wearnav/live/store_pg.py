"""The session store on a PostgreSQL server (issue 61): receivers behind a balancer and trackers
on other machines (a Ray cluster's nodes) share one store, reached by a URL
(``wearnav live --store postgresql://user@host/db``; psycopg 3, the ``[postgres]`` extra).

The same interface and the same rule as the SQLite :class:`wearnav.live.store.Store`: a message is
committed (PostgreSQL's ``synchronous_commit`` on, its default: the commit's WAL is flushed to disk
before the commit returns) before its 200 is sent, a repeat ``(session, device, message id)`` is
stored once, and tracker processes read the messages by row id in the order they were committed.

That order needs care on a server: an identity column's values are handed out when rows are
inserted, not when they are committed, so with several receivers a row with a smaller id could
become visible after one with a larger id and a tracker reading on from the larger one would miss
it. Every transaction that adds messages therefore first takes one advisory lock
(``pg_advisory_xact_lock``, held until its commit), so ids are handed out in commit order: once
a tracker sees row ``n``, every row below it is committed and visible.

Decision: docs/decisions/0028-live-crowd.md; docs/live-scaling.md says how a deployment uses it.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from urllib.parse import urlsplit, urlunsplit

from wearnav.errors import ConfigError

SCHEMA = """
CREATE TABLE IF NOT EXISTS messages (
    rowid BIGINT GENERATED ALWAYS AS IDENTITY UNIQUE,
    session_id TEXT NOT NULL,
    device_id TEXT NOT NULL,
    message_id BIGINT NOT NULL,
    received_ns BIGINT NOT NULL,
    body TEXT NOT NULL,
    PRIMARY KEY (session_id, device_id, message_id)
);
CREATE TABLE IF NOT EXISTS sessions (
    session_id TEXT PRIMARY KEY,
    platform TEXT NOT NULL,
    standardised INTEGER NOT NULL,
    created_ns BIGINT NOT NULL
);
CREATE TABLE IF NOT EXISTS states (
    session_id TEXT PRIMARY KEY,
    updated_ns BIGINT NOT NULL,
    state TEXT NOT NULL
);
"""
# The advisory lock every message-adding transaction holds until its commit (module docstring).
ORDER_LOCK = 61_0001
SCHEMES = ("postgresql://", "postgres://")
PSYCOPG_MISSING = "a postgresql:// store needs psycopg 3: pip install 'wearnav[postgres]'"


def is_url(where: object) -> bool:
    """Whether ``where`` names a PostgreSQL store (a ``postgresql://`` URL) rather than a SQLite file."""
    return isinstance(where, str) and where.startswith(SCHEMES)


def redact(url: str) -> str:
    """``url`` without its password (for messages and logs)."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.hostname or ""
    user = f"{parts.username}:***@" if parts.username else ""
    return urlunsplit(parts._replace(netloc=f"{user}{host}{f':{parts.port}' if parts.port else ''}"))


class PgStore:
    """One PostgreSQL database as the session store: the methods of
    :class:`wearnav.live.store.Store`, safe to call from several threads (one connection, one lock)."""

    def __init__(self, url: str, readonly: bool = False):
        try:
            import psycopg
        except ImportError:
            raise ConfigError(PSYCOPG_MISSING) from None
        self.url = url
        self.path = redact(url)  # what messages name (no password)
        self._psycopg = psycopg
        self._db = self._connect()
        if not readonly:
            with self._db.transaction():
                self._db.execute("SELECT pg_advisory_xact_lock(%s)", (ORDER_LOCK,))  # one creator at a time
                self._db.execute(SCHEMA)
        self._lock = threading.Lock()

    def _connect(self):
        try:
            db = self._psycopg.connect(self.url, autocommit=True)
            # the durability rule holds whatever the server's default: a commit returns once on disk
            db.execute("SET synchronous_commit = on")
        except self._psycopg.Error as exc:
            raise ConfigError(f"cannot reach the store {redact(self.url)}: {str(exc).strip()[:300]}") from None
        return db

    def _again(self, exc: Exception) -> bool:
        """Whether a call that failed with ``exc`` may be tried once more: the connection broke (a
        server restarted, a network blip) and a new one could be made. Every write here is
        idempotent (a repeat is a no-op), so trying a transaction again is safe."""
        if not isinstance(exc, self._psycopg.OperationalError) or not self._db.closed:
            return False
        self._db = self._connect()
        return True

    def add(
        self, session_id: str, device_id: str, message_id: int, body: str, platform: str, standardised: bool
    ) -> bool:
        """Store one message; True when new, False for a repeat. Committed when this returns."""
        return self.add_many([(session_id, device_id, message_id, body, platform, standardised)])[0]

    def add_many(self, rows: list[tuple[str, str, int, str, str, bool]]) -> list[bool]:
        """:meth:`add` for each of ``rows`` in one transaction, row ids in commit order (module
        docstring): on disk when this returns."""
        with self._lock:
            try:
                return self._add_many(rows)
            except self._psycopg.OperationalError as exc:
                if not self._again(exc):
                    raise
                return self._add_many(rows)

    def _add_many(self, rows: list[tuple[str, str, int, str, str, bool]]) -> list[bool]:
        now = time.time_ns()
        new = []
        with self._db.transaction(), self._db.cursor() as cur:
            cur.execute("SELECT pg_advisory_xact_lock(%s)", (ORDER_LOCK,))
            for session_id, device_id, message_id, body, platform, standardised in rows:
                cur.execute(
                    "INSERT INTO messages (session_id, device_id, message_id, received_ns, body) "
                    "VALUES (%s, %s, %s, %s, %s) ON CONFLICT DO NOTHING",
                    (session_id, device_id, message_id, now, body),
                )
                new.append(cur.rowcount == 1)
                if new[-1]:
                    cur.execute(
                        "INSERT INTO sessions VALUES (%s, %s, %s, %s) ON CONFLICT DO NOTHING",
                        (session_id, platform, int(standardised), now),
                    )
        return new

    def _query(self, sql: str, args: tuple = ()) -> list:
        """Every row of one query (tried once more on a new connection where the old one broke)."""
        with self._lock:
            try:
                return self._db.execute(sql, args).fetchall()
            except self._psycopg.OperationalError as exc:
                if not self._again(exc):
                    raise
                return self._db.execute(sql, args).fetchall()

    def messages_after(self, rowid: int, limit: int = 10_000) -> list[tuple[int, str, str, bool, int, str]]:
        """Messages committed after row ``rowid``, oldest first, at most ``limit``: (rowid, session,
        platform, standardised, received_ns, body)."""
        return self._query(
            "SELECT m.rowid, m.session_id, s.platform, s.standardised, m.received_ns, m.body "
            "FROM messages m JOIN sessions s ON s.session_id = m.session_id "
            "WHERE m.rowid > %s ORDER BY m.rowid LIMIT %s",
            (rowid, limit),
        )

    def put_states(self, states: dict[str, str]) -> None:
        """Each session's page state (JSON text), replacing the last, in one transaction."""
        if not states:
            return
        with self._lock:
            try:
                self._put_states(states)
            except self._psycopg.OperationalError as exc:
                if not self._again(exc):
                    raise
                self._put_states(states)

    def _put_states(self, states: dict[str, str]) -> None:
        now = time.time_ns()
        with self._db.transaction(), self._db.cursor() as cur:
            cur.executemany(
                "INSERT INTO states VALUES (%s, %s, %s) ON CONFLICT (session_id) DO UPDATE "
                "SET updated_ns = EXCLUDED.updated_ns, state = EXCLUDED.state",
                [(sid, now, st) for sid, st in states.items()],
            )

    def state(self, session_id: str) -> dict | None:
        rows = self._query("SELECT state FROM states WHERE session_id = %s", (session_id,))
        return None if not rows else json.loads(rows[0][0])

    def sessions(self) -> dict[str, dict]:
        rows = self._query(
            "SELECT s.session_id, s.platform, s.standardised, s.created_ns, "
            "(SELECT COUNT(*) FROM messages m WHERE m.session_id = s.session_id) "
            "FROM sessions s ORDER BY s.created_ns, s.session_id"
        )
        return {
            r[0]: {"platform": r[1], "standardised": bool(r[2]), "created_ns": r[3], "messages": r[4]} for r in rows
        }

    def messages(self, session_id: str) -> Iterator[tuple[str, int, int, str]]:
        yield from self._query(
            "SELECT device_id, message_id, received_ns, body FROM messages WHERE session_id = %s ORDER BY rowid",
            (session_id,),
        )

    def message_ids(self, session_id: str) -> set[tuple[str, int]]:
        rows = self._query("SELECT device_id, message_id FROM messages WHERE session_id = %s", (session_id,))
        return {(d, m) for d, m in rows}

    def count(self) -> int:
        rows = self._query("SELECT COUNT(*) FROM messages")
        return int(rows[0][0]) if rows else 0

    def close(self) -> None:
        with self._lock:
            self._db.close()


__all__ = ["PgStore", "SCHEMES", "is_url", "redact"]
