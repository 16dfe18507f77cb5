"""The receiver's on-disk session store: SQLite, one row per accepted message (the embedded
default; :mod:`wearnav.live.store_pg` is the same on a PostgreSQL server, for a deployment that
spans machines: :func:`open_store` picks by what ``--store`` names).

Rows are keyed by (session_id, device_id, message_id), so a message sent twice is stored once
(``INSERT OR IGNORE``); each insert is committed (WAL journal, ``synchronous=FULL``: on disk
before the call returns) before the receiver answers 200, so nothing acknowledged is lost when
the process is killed. The body is kept as received (UTF-8 JSON text), and a session's
settings (platform, standardisation: what Sensor Logger does not send) beside it; the live
buffers are rebuilt from here on restart.

Group commit (issue 37; one committer thread since issue 61): messages that arrive while a
transaction is being committed wait and go into the next one together (:class:`GroupCommit`), so
many sessions' pushes cost one ``fsync`` (measured on this machine: 3.4 ms a commit, which alone
capped one receiver near 290 messages a second), and each is still on disk before its 200.

Tracker processes (``wearnav live track``) read the messages by row id as they arrive
(:meth:`Store.messages_after`) and write each session's page state into ``states``, which a
receiver that does not track itself serves (:meth:`Store.state`).

Decision: docs/decisions/0028-live-crowd.md.
"""

from __future__ import annotations

import asyncio
import bisect
import json
import sqlite3
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

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


class GroupCommit:
    """Every item submitted while a transaction commits goes into the next one (one commit per
    tick, however many messages arrived in it, once more than two a tick have been arriving; right
    away while fewer do): one committer thread of its own calls
    ``flush(items) -> results`` (in order, one transaction), then hands each submitter its own
    item's result, or the batch's error. :meth:`submit` blocks a thread until then;
    :meth:`submit_async` returns an asyncio future of the running loop (the receiver's ``/push``
    awaits it: no worker thread per message), all of one batch resolved by one wake-up of the loop."""

    def __init__(self, flush: Callable[[list], list], tick_s: float = 0.0):
        self._flush = flush
        self.tick_s = float(tick_s)  # transactions start at most this often (s): busier, fewer and larger
        self._queue: list[tuple[Any, Any]] = []  # (item, waiter: a callable or (loop, future))
        self._cv = threading.Condition()
        self._stopped = False
        self.batches = 0
        self.items = 0
        self._thread = threading.Thread(target=self._run, name="live-commit", daemon=True)
        self._thread.start()

    def submit(self, item):
        """``item``'s result once the transaction holding it is committed (or its error, raised)."""
        done = threading.Event()
        box: list = [None, None]

        def waiter(result, error):
            box[0], box[1] = result, error
            done.set()

        self._put(item, waiter)
        done.wait()
        if box[1] is not None:
            raise box[1]
        return box[0]

    def submit_async(self, item) -> asyncio.Future:
        """An asyncio future (of the running loop) of ``item``'s result."""
        loop = asyncio.get_running_loop()
        fut = loop.create_future()
        self._put(item, (loop, fut))
        return fut

    def _put(self, item, waiter) -> None:
        with self._cv:
            if self._stopped:
                raise RuntimeError("the store's committer has stopped")
            self._queue.append((item, waiter))
            self._cv.notify()

    def stop(self) -> None:
        """Commit what is waiting, then end the committer thread."""
        with self._cv:
            self._stopped = True
            self._cv.notify()
        self._thread.join(30)

    def _run(self) -> None:
        last = -float("inf")
        recent: list[float] = []  # when the items of the last second were taken (monotonic s)
        while True:
            with self._cv:
                while not self._queue and not self._stopped:
                    self._cv.wait()
                if not self._queue:
                    return
            now = time.monotonic()
            del recent[: bisect.bisect_left(recent, now - 1.0)]
            rest = last + self.tick_s - now
            # busy (more than two items a tick over the last second): the tick's other items join this
            # transaction; quiet: no wait (a lone sender's next message would wait a tick for nothing)
            if rest > 0 and len(recent) * self.tick_s > 2.0 and not self._stopped:
                time.sleep(rest)
            last = time.monotonic()
            with self._cv:
                batch, self._queue = self._queue, []
            recent += [last] * len(batch)
            results: list = [None] * len(batch)
            error: BaseException | None = None
            try:
                results = self._flush([item for item, _ in batch])
            except BaseException as exc:  # every submitter of the batch gets it
                error = exc
            self.batches += 1
            self.items += len(batch)
            loops: dict[int, tuple] = {}
            for (_, waiter), result in zip(batch, results):
                if callable(waiter):
                    waiter(result, error)
                else:
                    loops.setdefault(id(waiter[0]), (waiter[0], []))[1].append((waiter[1], result))
            for ev_loop, futs in loops.values():
                try:
                    ev_loop.call_soon_threadsafe(_resolve, futs, error)
                except RuntimeError:  # the loop has closed: nobody waits any more
                    pass


def _resolve(futs: list[tuple[asyncio.Future, object]], error: BaseException | None) -> None:
    for fut, result in futs:
        if fut.done():  # the request was cancelled (its client left)
            continue
        if error is not None:
            fut.set_exception(error)
        else:
            fut.set_result(result)


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


def open_store(where: str | Path, readonly: bool = False):
    """The store at ``where``: a ``postgresql://`` URL (:class:`wearnav.live.store_pg.PgStore`, a
    store that spans machines), else a SQLite file's path (:class:`Store`, the embedded default)."""
    from wearnav.live.store_pg import PgStore, is_url

    if is_url(where):
        return PgStore(str(where), readonly=readonly)
    return Store(where, readonly=readonly)


def store_missing(where: str | Path) -> bool:
    """Whether ``where`` is a SQLite path with no file there (a URL's server is asked when opened)."""
    from wearnav.live.store_pg import is_url

    return not is_url(where) and not Path(where).is_file()


__all__ = ["GroupCommit", "Store", "open_store", "store_missing"]
