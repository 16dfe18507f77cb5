"""The receiver: a Starlette app taking Sensor Logger's HTTP Push, storing it, tracking it live.

Routes (``wearnav live`` serves them with uvicorn)::

    POST /push       one Sensor Logger message (wearnav.live.push); 200 {"stored": true|false}
                     once committed to the store (false: a repeat, a no-op)
    GET  /events     server-sent events: the session's state, at most 4 times a second
    GET  /state      the same JSON once            (?session=ID; default the latest session)
    GET  /sessions   the sessions in the store, oldest first
    GET  /stats      counters: accepted, repeats, refused by status, tracker update latency
    GET  /           the live page (wearnav/live/static/index.html; its files under /static, with the
                     path drawing it shares with trajectory.html: wearnav/report/static/draw.js, style.css)

With a token set (required when the server listens beyond 127.0.0.1; ``wearnav live`` makes one
when none is given) every route but ``/static`` (the page's own scripts and styles) wants it, as
``Authorization: Bearer T`` or ``?token=T``, compared in constant time; without it: 401 and
nothing stored. Refusals are one JSON ``{"error": ...}``
with a 4xx: 401, 413 (body over ``max_body``), 429 (over ``rate_limit`` messages a second from one
client, bursts of twice that), 400 / 422 (:mod:`wearnav.live.push`). The token is never logged:
uvicorn's access log is off and this module logs paths without their query.

Tracking: one :class:`wearnav.live.crowd.Crowd` updates every session's tracker in ticks, the
model run once per tick for all of them; a session is poked once its push's 200 has been sent.
A session without a push for ``wearnav.live.crowd.SESSION_END_S`` has ended: its path's
provisional end is made final once, as ``track`` would give it. The trackers come from
``tracker_factory`` (None: no tracking here, ``wearnav live --no-track``; the page's state then
comes from the store, where tracker processes write it: ``wearnav live track``).

A session's platform and standardisation (which the app does not push) come from the push URL's
query (``?platform=android&standardisation=true``), else from ``wearnav live --platform``, else
from the session's data (:data:`wearnav.live.buffer.AUTO`).
"""

from __future__ import annotations

import asyncio
import functools
import hmac
import json
import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response, StreamingResponse
from starlette.routing import BaseRoute, Mount, Route
from starlette.staticfiles import StaticFiles

from wearnav.importers.sensorlogger_map import PLATFORMS
from wearnav.live.buffer import AUTO, SessionBuffer
from wearnav.live.push import BadPush, check_id, parse
from wearnav.live.store import GroupCommit, Store, open_store
from wearnav.live.store_pg import PgStore

if TYPE_CHECKING:
    from wearnav.live.crowd import Crowd

log = logging.getLogger("wearnav.live")
STATIC = Path(__file__).parent / "static"
# draw.js and style.css: the path drawing the live page shares with track's trajectory.html
# (wearnav.report.trajectory_page), served under /static beside the live page's own files
DRAWING = ("wearnav.report", "static")
MAX_BODY = 4 * 1024 * 1024  # bytes; a 1-s batch of 3 devices at 100 Hz is ~150 kB
RATE_LIMIT = 100.0  # messages per second per client (burst: twice that)
MAX_FUTURE_S = 120.0  # sample times this far ahead of the server's clock are refused
MAX_AGE_S = 7 * 86400.0  # ... and this far behind it
STOPPED_S = 5.0  # a device silent this long is shown as stopped
EVENT_PERIOD_S = 0.25  # /events sends at most 4 states a second
KEEPALIVE_S = 15.0
# The store commits at most this often (s): every message that arrived in a tick goes into one
# transaction, on disk before any of their 200s. A commit (WAL, synchronous=FULL) costs this
# machine ~0.2 ms of CPU and ~3.4 ms of wall time however small: at 100 walkers' 500 messages a
# second a tick of 20 ms makes ~10 messages a transaction (issue 61), and adds at most 20 ms to a
# 200 (nothing to the path's latency, which counts from the 200).
COMMIT_TICK_S = 0.02


class RateLimiter:
    """A token bucket per client address: ``rate`` a second, bursts of ``2 × rate``."""

    def __init__(self, rate: float):
        self.rate, self.burst = rate, 2.0 * rate
        self._buckets: dict[str, tuple[float, float]] = {}
        self._lock = threading.Lock()

    def allow(self, client: str) -> bool:
        now = time.monotonic()
        with self._lock:
            tokens, last = self._buckets.get(client, (self.burst, now))
            tokens = min(self.burst, tokens + (now - last) * self.rate)
            ok = tokens >= 1.0
            self._buckets[client] = (tokens - 1.0 if ok else tokens, now)
            if len(self._buckets) > 10_000:  # forget idle clients
                self._buckets = {c: v for c, v in self._buckets.items() if now - v[1] < 60}
        return ok


def untracked_state(buf: SessionBuffer, why: str = "off") -> dict:
    """The state without a tracker: ``why`` "off" (``--no-track``) or "starting"."""
    note = (
        "tracking is off here (wearnav live --no-track); a tracker process (wearnav live track) puts the path "
        "in the store"
        if why == "off"
        else "live tracking is starting"
    )
    return {
        "origin": None,
        "path": [],
        "anchor": "none",
        "fixes": [],
        "activity": None,
        "warnings": [note],
        "t_s": buf.covered_until(),
    }


class Receiver:
    """The app's state: store, buffers, workers, limits (one per app)."""

    def __init__(
        self,
        store: Store | PgStore,
        token: str | None,
        max_body: int,
        rate_limit: float,
        tracker_factory: Callable[[], object] | None,
        platform: str | None,
        standardised: bool,
        max_future_s: float,
        max_age_s: float,
        shared: bool = False,
    ):
        self.store, self.token, self.max_body = store, token, max_body
        # one of several receivers on one port and store (wearnav live --workers): each sees only the
        # messages that reach it, so a session's state comes from its tracker's, in the store
        self.shared = shared
        self.limiter = RateLimiter(rate_limit)
        self.tracker_factory = tracker_factory
        self.platform, self.standardised = platform, standardised
        self.max_future_s, self.max_age_s = max_future_s, max_age_s
        self.buffers: dict[str, SessionBuffer] = {}
        self.crowd: Crowd | None = None
        if tracker_factory is not None:
            from wearnav.live.crowd import Crowd  # torch and the models: only where the server tracks

            self.crowd = Crowd(tracker_factory)
        self.counts: dict[str, Any] = {"accepted": 0, "repeats": 0, "refused": {}}
        self._lock = threading.Lock()  # store + buffer in one order
        self.commits = GroupCommit(self._flush, COMMIT_TICK_S)
        for sid in store.sessions():  # resumed: what a restart finds in the store
            self.buffers[sid] = SessionBuffer.from_store(store, sid)
            self.poke(sid)

    def _buffer(self, sid: str, platform: str, standardised: bool) -> SessionBuffer:
        if sid not in self.buffers:
            self.buffers[sid] = SessionBuffer(sid, platform, standardised)
        return self.buffers[sid]

    def poke(self, sid: str) -> None:
        if self.crowd is not None:
            self.crowd.poke(sid, self.buffers[sid])

    def settings(self, request: Request) -> tuple[str, bool]:
        """The session's platform and standardisation: the push URL's ``?platform=`` /
        ``&standardisation=``, else the server's, else ``AUTO`` (decided from the data)."""
        return settings(request.query_params, self.platform, self.standardised)

    def accept(self, body: bytes, platform: str, standardised: bool, track: bool = True) -> str | None:
        """Parse, store (committed), buffer: the session id when new, None for a repeat. Runs in
        a worker thread; messages arriving together are committed together (the store's group
        commit), each on disk before this returns. ``track`` False leaves waking the tracker to the
        caller (:meth:`poke`), which the HTTP route does once its 200 is sent."""
        push = parse(body, time.time_ns(), self.max_future_s, self.max_age_s)
        new = self.commits.submit((push, body, platform, standardised))
        if new and track:
            self.poke(push.session_id)
        return push.session_id if new else None

    async def accept_async(self, body: bytes, platform: str, standardised: bool) -> str | None:
        """:meth:`accept` on the event loop (``/push``): parsed here (a fraction of a millisecond),
        committed by the store's committer thread with whatever else arrived meanwhile, awaited;
        the tracker is not woken (the route does that once its 200 is sent)."""
        push = parse(body, time.time_ns(), self.max_future_s, self.max_age_s)
        new = await self.commits.submit_async((push, body, platform, standardised))
        return push.session_id if new else None

    def _flush(self, items: list) -> list[bool]:
        """One transaction for ``items`` (push, body, platform, standardised), then their samples
        into the buffers in the same order (a session's settings are its first message's)."""
        rows = [(p.session_id, p.device_id, p.message_id, b.decode("utf-8"), pl, st) for p, b, pl, st in items]
        with self._lock:
            new = self.store.add_many(rows)
            for (p, _, pl, st), fresh in zip(items, new):
                if fresh:
                    self._buffer(p.session_id, pl, st).add_push(p)
                self.counts["accepted" if fresh else "repeats"] += 1
        return new

    def known(self, sid: str) -> bool:
        """Whether session ``sid`` is here (a shared receiver also knows the store's sessions that
        reached another receiver: an empty buffer stands for them)."""
        if sid in self.buffers:
            return True
        if not self.shared:
            return False
        info = self.store.sessions().get(sid)
        if info is None:
            return False
        with self._lock:
            self._buffer(sid, info["platform"], info["standardised"])
        return True

    def state(self, sid: str) -> dict:
        buf = self.buffers[sid]
        if self.shared:  # the tracker's view of the whole session (this receiver's is a part)
            st = self.store.state(sid) or untracked_state(buf)
            now = time.time()
            devices = {
                d: {**v, "stopped": now - v["last_seen_unix_s"] > STOPPED_S}
                for d, v in (st.get("devices") or buf.devices()).items()
            }
            return {**st, "session": sid, "devices": devices, "messages": st.get("tracked_messages", buf.messages)}
        if self.crowd is not None:
            st = self.crowd.state(sid) or {}
            if "path" not in st:  # no tracker yet, or it could not be made: its error stays a warning
                base = untracked_state(buf, "starting")
                st = {**base, "warnings": base["warnings"] + st.get("warnings", [])}
        else:
            st = self.store.state(sid) or untracked_state(buf)
        now = time.time()
        devices = {d: {**v, "stopped": now - v["last_seen_unix_s"] > STOPPED_S} for d, v in buf.devices().items()}
        return {**st, "session": sid, "devices": devices, "messages": buf.messages}

    def latest(self) -> str | None:
        if self.shared:
            return next(reversed(self.store.sessions()), None)
        return next(reversed(self.buffers), None)


def settings(query, platform: str | None, standardised: bool) -> tuple[str, bool]:
    """(platform, standardisation) from a push or MQTT URL's ``query`` (a mapping), else the
    server's ``platform`` / ``standardised``; a platform given by neither is ``AUTO``."""
    given = query.get("platform")
    flag = query.get("standardisation")
    if flag is not None and flag.lower() not in ("true", "false", "1", "0", "on", "off"):
        raise BadPush(422, "standardisation must be true or false")
    std = standardised if flag is None else flag.lower() in ("true", "1", "on")
    if given is None:
        if platform is None and flag is None:
            return AUTO, False
        return platform or "ios", std
    given = given.strip().lower()
    if given not in PLATFORMS:
        raise BadPush(422, f"platform must be one of {', '.join(PLATFORMS)}")
    return given, std


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


_STORED, _REPEAT = b'{"stored":true}', b'{"stored":false}'  # /push's two answers, and their headers
_START = {
    body: {
        "type": "http.response.start",
        "status": 200,
        "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())],
    }
    for body in (_STORED, _REPEAT)
}


def _authorized_raw(token: str, headers: dict[bytes, bytes], query: bytes) -> bool:
    """The token check of ``authorized`` on raw ASGI headers and query string (constant time)."""
    given = dict(parse_qsl(query.decode("latin-1"), keep_blank_values=True)).get("token", "")
    header = headers.get(b"authorization", b"").decode("latin-1")
    if header[:7].lower() == "bearer ":
        given = header[7:].strip()
    return hmac.compare_digest(given.encode(), token.encode())


async def _call_asgi(handler, request: Request) -> Response:
    """A plain-ASGI handler's answer as a Starlette Response (for routes that reach it through Starlette)."""
    started: dict = {}
    parts: list[bytes] = []

    async def send(message) -> None:
        if message["type"] == "http.response.start":
            started.update(message)
        else:
            parts.append(message.get("body", b""))

    await handler(request.scope, request.receive, send)
    if not started:  # the client left before an answer
        return Response(status_code=499)
    headers = {k.decode(): v.decode() for k, v in started.get("headers", []) if k != b"content-length"}
    return Response(b"".join(parts), status_code=started["status"], headers=headers)


class _App(Starlette):
    """The receiver's Starlette app with ``POST /push`` answered before any routing (issue 61: the
    receiver's cost per message)."""

    push_asgi: Callable | None = None

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http" and scope["path"] == "/push" and scope["method"] == "POST" and self.push_asgi:
            await self.push_asgi(scope, receive, send)
            return
        await super().__call__(scope, receive, send)


def create_app(
    store: str | Path | Store | PgStore,
    token: str | None = None,
    max_body: int = MAX_BODY,
    rate_limit: float = RATE_LIMIT,
    tracker_factory: Callable[[], object] | None = None,
    platform: str | None = None,
    standardised: bool = False,
    max_future_s: float = MAX_FUTURE_S,
    max_age_s: float = MAX_AGE_S,
    shared: bool = False,
) -> Starlette:
    """The receiver app over ``store`` (a SQLite file, a ``postgresql://`` URL, or an open store;
    sessions in it are resumed)."""
    store = store if isinstance(store, (Store, PgStore)) else open_store(store)
    rx = Receiver(
        store, token, max_body, rate_limit, tracker_factory, platform, standardised, max_future_s, max_age_s, shared
    )

    def refuse(request: Request, status: int, message: str) -> JSONResponse:
        rx.counts["refused"][str(status)] = rx.counts["refused"].get(str(status), 0) + 1
        log.info("%s %s %d %s", request.method, request.url.path, status, message)
        return _error(status, message)

    def authorized(request: Request) -> bool:
        if rx.token is None:
            return True
        given = request.query_params.get("token", "")
        header = request.headers.get("authorization", "")
        if header[:7].lower() == "bearer ":
            given = header[7:].strip()
        return hmac.compare_digest(given.encode(), rx.token.encode())

    async def push(request: Request) -> Response:
        """``POST /push`` reaches :func:`push_asgi` first (:class:`_App`); this answers what Starlette
        routes here all the same (a mounted copy of the app, say) through the same steps."""
        return await _call_asgi(push_asgi, request)

    async def push_asgi(scope, receive, send) -> None:
        """``POST /push`` as plain ASGI (no Request, no routing, no thread per message: issue 61):
        the token, the client's rate, the body's size, the body read and checked here, its commit
        awaited (:meth:`Receiver.accept_async`), the 200, then the tracker woken."""
        headers = dict(scope["headers"])
        query = scope.get("query_string", b"")
        if rx.token is not None and not _authorized_raw(rx.token, headers, query):
            return await _send_refusal(send, 401, "a valid token is required (Authorization: Bearer T, or ?token=T)")
        client = scope["client"][0] if scope.get("client") else "?"
        if not rx.limiter.allow(client):
            return await _send_refusal(send, 429, f"over {rx.limiter.rate:g} messages a second from {client}")
        try:
            declared = int(headers.get(b"content-length", b"0"))
        except ValueError:
            return await _send_refusal(send, 400, "Content-Length is not a number")
        if declared > rx.max_body:
            return await _send_refusal(send, 413, f"body of {declared} bytes is over the limit of {rx.max_body}")
        chunks, size, more = [], 0, True
        while more:
            message = await receive()
            if message["type"] == "http.disconnect":
                return None
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > rx.max_body:
                return await _send_refusal(send, 413, f"body is over the limit of {rx.max_body} bytes")
            chunks.append(chunk)
            more = message.get("more_body", False)
        try:
            platform, standardised = settings_of(query)
            sid = await rx.accept_async(chunks[0] if len(chunks) == 1 else b"".join(chunks), platform, standardised)
        except BadPush as exc:
            return await _send_refusal(send, exc.status, exc.message)
        answer = _STORED if sid is not None else _REPEAT
        await send(_START[answer])
        await send({"type": "http.response.body", "body": answer})
        if sid is not None:  # the tracker runs after the 200 has gone out
            rx.poke(sid)
        return None

    async def _send_refusal(send, status: int, message: str) -> None:
        rx.counts["refused"][str(status)] = rx.counts["refused"].get(str(status), 0) + 1
        log.info("POST /push %d %s", status, message)
        body = json.dumps({"error": message}).encode()
        await send(
            {
                "type": "http.response.start",
                "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())],
            }
        )
        await send({"type": "http.response.body", "body": body})

    @functools.lru_cache(maxsize=256)
    def settings_of(query: bytes) -> tuple[str, bool]:
        return settings(dict(parse_qsl(query.decode("latin-1"), keep_blank_values=True)), rx.platform, rx.standardised)

    def session_of(request: Request) -> str | Response:
        """The session a /state or /events request asks for (default the latest), or its refusal."""
        if not authorized(request):
            return refuse(request, 401, "a valid token is required")
        sid = request.query_params.get("session") or rx.latest()
        if sid is None:
            return _error(404, "no session yet: start a recording with HTTP Push on")
        try:
            check_id(sid, "session")
        except BadPush as exc:
            return _error(exc.status, exc.message)
        if not rx.known(sid):
            return _error(404, f"no session {sid!r}")
        return sid

    async def state(request: Request) -> Response:
        sid = session_of(request)
        if isinstance(sid, Response):
            return sid
        return JSONResponse(await run_in_threadpool(rx.state, sid))

    async def events(request: Request) -> Response:
        sid = session_of(request)
        if isinstance(sid, Response):
            return sid

        async def stream():
            last, quiet = None, 0.0
            while True:
                text = json.dumps(await run_in_threadpool(rx.state, sid))
                if text != last:
                    last, quiet = text, 0.0
                    yield f"data: {text}\n\n"
                elif quiet >= KEEPALIVE_S:
                    quiet = 0.0
                    yield ": keep-alive\n\n"
                await asyncio.sleep(EVENT_PERIOD_S)
                quiet += EVENT_PERIOD_S

        return StreamingResponse(
            stream(), media_type="text/event-stream", headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}
        )

    async def sessions(request: Request) -> Response:
        if not authorized(request):
            return refuse(request, 401, "a valid token is required")
        stored = rx.store.sessions()

        def convention(sid: str, info: dict) -> dict:  # AUTO until the session's data decided it
            buf = rx.buffers.get(sid)
            if buf is None or buf.infer:
                return {"platform": info["platform"], "standardised": info["standardised"]}
            return {"platform": buf.platform, "standardised": buf.standardised}

        return JSONResponse(
            [
                {
                    "session": sid,
                    **convention(sid, info),
                    "created_unix_s": info["created_ns"] / 1e9,
                    "messages": info["messages"],
                    "devices": sorted(rx.buffers[sid].devices()) if sid in rx.buffers else [],
                }
                for sid, info in stored.items()
            ]
        )

    async def stats(request: Request) -> Response:
        if not authorized(request):
            return refuse(request, 401, "a valid token is required")
        lat = rx.crowd.latency_s() if rx.crowd is not None else {}
        return JSONResponse(
            {
                **rx.counts,
                "sessions": len(rx.buffers),
                "tracking": rx.tracker_factory is not None,
                "pid": os.getpid(),  # which receiver answered (wearnav live --workers N: one of N)
                "commits": {"transactions": rx.commits.batches, "messages": rx.commits.items},
                "update_latency_s": lat,
            }
        )

    async def index(request: Request) -> Response:
        if not authorized(request):
            return refuse(request, 401, "a valid token is required (open the page as /?token=T)")
        page = STATIC / "index.html"
        if not page.is_file():
            return PlainTextResponse(
                "the live page is not installed (wearnav/live/static/index.html); /state and /events work",
                status_code=404,
            )
        return FileResponse(page, headers={"Cache-Control": "no-cache"})

    routes: list[BaseRoute] = [
        Route("/push", push, methods=["POST"]),
        Route("/events", events),
        Route("/state", state),
        Route("/sessions", sessions),
        Route("/stats", stats),
        Route("/", index),
    ]
    if STATIC.is_dir():
        routes.append(Mount("/static", StaticFiles(directory=STATIC, packages=[DRAWING]), name="static"))
    app = _App(routes=routes)
    app.push_asgi = push_asgi
    app.state.receiver = rx
    return app


__all__ = ["MAX_BODY", "RATE_LIMIT", "Receiver", "create_app"]
