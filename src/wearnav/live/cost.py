"""What receiving and tracking cost, measured (issue 61): ``wearnav live cost receiver|tracker``.

:func:`receiver_cost` posts ``messages`` pre-encoded phone-only pushes (0.2 s of a simulated walk
each, the body Sensor Logger sends: accelerometer, gravity, gyroscope, orientation at 100 Hz and
a fix a second) over real HTTP to a real ``wearnav live --no-track`` process on 127.0.0.1, spread
over ``walkers`` sessions and sent by ``senders`` keep-alive connections at ``rate`` messages a
second (the pace of ``rate / 5`` walkers), and reads the receiver's CPU time (user + system,
``/proc``) before and after: the receiver's CPU per message, with its start-up left out. Every
message must be acknowledged and stored (counted in the store afterwards). With ``floor``, the same
pushes then go to :func:`floor_app` under the same HTTP server (uvicorn, httptools and uvloop where
installed, as ``wearnav live`` runs): an app that only reads each body and answers 200, whose CPU a
message is what no receiver on that server goes below on this machine at that minute (issue 61's
0.3 ms sat at it: docs/live-scaling.md).

:func:`tracker_cost` pushes ``walkers`` phone-only sessions of a simulated walk message by message
into session buffers (no HTTP) and runs one :class:`wearnav.live.crowd.Crowd`'s ticks in this
thread after each round of messages: the tracking CPU (this process's, ``time.process_time``) per
walker-second of data, as ``scripts/live_walker_cost.py`` measured it before (this replaces it).
"""

from __future__ import annotations

import http.client
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from wearnav.errors import ConfigError
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live import replay
from wearnav.live.process import LiveServer, cpu_s, env, free_port

BATCH_S = 0.2  # s of walk per push, as the app batches (wearnav.live.bench_page.BATCH_S)


def walker_bodies(work: Path, walkers: int, per_walker: int, seed: int = 0) -> tuple[list[list[bytes]], str]:
    """``walkers`` phone-only sessions' first ``per_walker`` pushes, encoded, and the push URL's
    query (the export's platform). The walk is simulated once; each walker is the same walk under
    its own session id."""
    from wearnav.live.bench import walker_export  # the bench's own phone-only copy of the export

    export = work / "export"
    if not (export / "Metadata.csv").is_file():
        simulated_export(export, seed=seed, duration_s=max(30.0, per_walker * BATCH_S + 4.0))
    base = replay.build(walker_export(export, "phone"), batch_s=BATCH_S, session_id="walker-0")
    if len(base.messages) < per_walker:
        raise ConfigError(f"the simulated walk has {len(base.messages)} pushes, fewer than {per_walker}")
    msgs = [{k: v for k, v in m.items() if k[0] != "_"} for m in base.messages[:per_walker]]
    bodies = [[json.dumps({**m, "sessionId": f"walker-{i}"}).encode() for m in msgs] for i in range(walkers)]
    query = replay.push_url("/push", base).split("?", 1)[1]
    return bodies, query


def _system_s(srv: LiveServer) -> float:
    """The system part (kernel: sockets, writes, fsync) of the server's CPU time so far, s."""
    if srv.proc is None:
        return 0.0
    try:
        fields = Path(f"/proc/{srv.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return int(fields[12]) / os.sysconf("SC_CLK_TCK")


def _wait_for_workers(srv: LiveServer, server_args: tuple[str, ...], timeout_s: float = 60.0) -> None:
    """With ``--workers N``: until N receiver processes answer (new connections, /stats' pid)."""
    args = list(server_args)
    n = int(args[args.index("--workers") + 1]) if "--workers" in args else 1
    seen: set = set()
    deadline = time.monotonic() + timeout_s
    while len(seen) < n and time.monotonic() < deadline:
        conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=10.0)
        try:
            conn.request("GET", "/stats")
            seen.add(json.loads(conn.getresponse().read()).get("pid"))
        except (OSError, http.client.HTTPException, ValueError):
            time.sleep(0.2)
        finally:
            conn.close()
    if len(seen) < n:
        raise ConfigError(f"receiver cost: {len(seen)} of {n} receiver processes answered in {timeout_s:g} s")


def _send(port: int, target: str, bodies: list[bytes], due: list[float], t0: float, errors: list) -> None:
    """POST ``bodies`` in order, each not before ``t0 + due`` (perf_counter s), over one keep-alive
    connection; any answer but 200 is an error (nothing is retried: the receiver is not loaded past
    its limits here)."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30.0)
    headers = {"content-type": "application/json"}
    try:
        for raw, d in zip(bodies, due):
            wait = t0 + d - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
            conn.request("POST", target, raw, headers)
            answer = conn.getresponse()
            text = answer.read()
            if answer.status != 200:
                errors.append(f"{answer.status} {text[:200]!r}")
                return
    except (OSError, http.client.HTTPException) as exc:
        errors.append(f"{type(exc).__name__}: {exc}")
    finally:
        conn.close()


def _post_all(port: int, target: str, lanes: list[tuple[list[bytes], list[float]]]) -> float:
    """Every lane's bodies POSTed on its own keep-alive connection at their due times; the wall time
    (s). Any sender that failed: ConfigError."""
    errors: list[str] = []
    w0 = time.perf_counter()
    threads = [threading.Thread(target=_send, args=(port, target, b, d, w0 + 0.05, errors)) for b, d in lanes]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise ConfigError(f"receiver cost: {len(errors)} sender(s) failed, the first: {errors[0]}")
    return time.perf_counter() - w0


_FLOOR_START = {"type": "http.response.start", "status": 200, "headers": [(b"content-length", b"2")]}
_FLOOR_BODY = {"type": "http.response.body", "body": b"{}"}


async def floor_app(scope, receive, send) -> None:
    """The HTTP server's floor (module docstring): reads a request's body, answers 200 ``{}``."""
    if scope["type"] != "http":  # (lifespan: uvicorn goes on without it)
        return
    more = True
    while more:
        message = await receive()
        if message["type"] == "http.disconnect":
            return
        more = message.get("more_body", False)
    await send(_FLOOR_START)
    await send(_FLOOR_BODY)


def _floor_ms(lanes: list[tuple[list[bytes], list[float]]], n: int, timeout_s: float = 30.0) -> float:
    """:func:`floor_app`'s CPU a message (ms) under ``lanes`` (``n`` messages in all), served by
    uvicorn in a process of its own as ``wearnav live`` serves (no access log, no proxy headers)."""
    port = free_port()
    cmd = [sys.executable, "-m", "uvicorn", "wearnav.live.cost:floor_app", "--host", "127.0.0.1"]
    cmd += ["--port", str(port), "--no-access-log", "--no-proxy-headers", "--log-level", "warning"]
    proc = subprocess.Popen(cmd, env=env())
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=1.0)
            try:
                conn.request("GET", "/")
                conn.getresponse().read()
                break
            except (OSError, http.client.HTTPException):
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise ConfigError(f"receiver cost: the floor's server did not start ({' '.join(cmd)})") from None
                time.sleep(0.2)
            finally:
                conn.close()
        used0 = cpu_s(proc.pid)
        _post_all(port, "/push", lanes)
        used1 = cpu_s(proc.pid)
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
    if used0 is None or used1 is None:
        raise ConfigError("receiver cost: the floor's CPU time is not readable here (Linux /proc)")
    return 1e3 * (used1 - used0) / n


def receiver_cost(
    messages: int = 5000,
    walkers: int = 100,
    senders: int = 100,
    rate: float = 500.0,
    store: str | None = None,
    server_args: tuple[str, ...] = (),
    work: str | Path | None = None,
    floor: bool = False,
) -> dict:
    """The receiver's CPU per message (module docstring). ``rate`` 0: as fast as the senders go;
    ``store``: the receiver's ``--store`` (default a SQLite file in ``work``); ``server_args``: more
    ``wearnav live`` options (``--workers 2``, say); ``floor``: also the HTTP server's floor, the
    same pushes sent to :func:`floor_app` afterwards."""
    if messages < walkers or walkers < 1 or senders < 1:
        raise ConfigError("receiver cost: at least one message per walker, one walker and one sender")
    work = Path(work) if work is not None else Path(tempfile.mkdtemp(prefix="wearnav-receiver-cost-"))
    work.mkdir(parents=True, exist_ok=True)
    per_walker = messages // walkers
    bodies, query = walker_bodies(work, walkers, per_walker)
    n = per_walker * walkers
    # message k of every walker is due at k * BATCH_S (scaled to ``rate``), walkers spread over the period
    period = 0.0 if rate <= 0 else walkers / rate
    order = [(k * period + i * period / walkers, bodies[i][k]) for k in range(per_walker) for i in range(walkers)]
    lanes: list[tuple[list[bytes], list[float]]] = [([], []) for _ in range(senders)]
    for j, (due, raw) in enumerate(order):
        lanes[j % senders][0].append(raw)
        lanes[j % senders][1].append(due)
    db = Path(store) if store is not None and "://" not in store else work / "cost.db"
    for old in work.glob(f"{db.name}*"):
        old.unlink()
    store_arg = store if store is not None and "://" in store else str(db)
    limit = ["--rate-limit", "1000000"]
    with LiveServer(db, "--no-track", *limit, *server_args, store_url=store_arg) as srv:
        time.sleep(1.0)  # start-up done
        _wait_for_workers(srv, server_args)
        c0, s0, k0 = srv.cpu_s(), time.process_time(), _system_s(srv)
        wall = _post_all(srv.port, f"/push?{query}", lanes)
        c1, s1, k1 = srv.cpu_s(), time.process_time(), _system_s(srv)
        stored = srv.stored()
    if c0 is None or c1 is None:
        raise ConfigError("receiver cost: the receiver's CPU time is not readable here (Linux /proc)")
    ms = round(1e3 * (c1 - c0) / n, 4)
    out: dict[str, Any] = {
        "messages": n,
        "walkers": walkers,
        "senders": senders,
        "rate_per_s": rate,
        "achieved_per_s": round(n / wall, 1),
        "bytes_per_message": int(np.mean([len(b) for b in bodies[0]])),
        "samples_per_message": round(float(np.mean([b.count(b'"name"') for b in bodies[0]])), 1),
        "store": "postgresql" if "://" in store_arg else "sqlite",
        "server_args": list(server_args),
        "wall_s": round(wall, 2),
        "stored": stored,
        "receiver_cpu_s": round(c1 - c0, 3),
        "receiver_ms_per_message": ms,
        "receiver_share_of_one_core": round((c1 - c0) / wall, 4),
        "receiver_system_ms_per_message": round(1e3 * (k1 - k0) / n, 4),  # of it, in the kernel (I/O, fsync)
        "senders_cpu_s": round(s1 - s0, 3),
        "load_1min": round(os.getloadavg()[0], 2),
    }
    if floor:
        f = _floor_ms(lanes, n)
        out["server_floor_ms_per_message"] = round(f, 4)
        out["receiver_above_floor_ms_per_message"] = round(ms - f, 4)
    return out


def _timed(owner, name: str, label: str, spent: dict) -> None:
    """``owner.name`` adding its process CPU time to ``spent[label]`` (outermost calls only)."""
    raw = owner.__dict__[name]
    f = raw.__func__ if isinstance(raw, staticmethod) else raw
    depth = [0]

    def wrapper(*args, **kw):
        depth[0] += 1
        tic = time.process_time()
        try:
            return f(*args, **kw)
        finally:
            depth[0] -= 1
            if not depth[0]:
                spent[label] = spent.get(label, 0.0) + time.process_time() - tic

    setattr(owner, name, staticmethod(wrapper) if isinstance(raw, staticmethod) else wrapper)


def _stages() -> list[tuple[Any, str, str]]:
    """(owner, method, what the docs call it): the stages :func:`tracker_cost` times."""
    from wearnav.live import buffer, crowd, tracker

    return [
        (buffer.SessionBuffer, "recording", "the update's Recording from the buffer"),
        (tracker, "lean_recording", "the update's Recording from the buffer"),  # its arrays (issue 61 §2)
        (tracker.LiveTracker, "align_steps", "aligning and windowing (batched)"),
        (crowd.Crowd, "_forward", "the odometry model (batched)"),
        (tracker.LiveTracker, "_grow", "growing the path"),
        (tracker.LiveTracker, "_take_fixes", "taking the fixes"),
        (tracker.LiveTracker, "_fuse", "the fixed-lag smoother"),
        (crowd.Crowd, "_activities", "the activity classifier"),
        (tracker.LiveTracker, "_label", "the activity classifier"),
        (tracker.LiveTracker, "_snapshot", "the page's state"),
    ]


def tracker_cost(walk_s: float = 90.0, walkers: int = 8, seed: int = 3, stages: bool = False) -> dict:
    """The tracking CPU per walker-second (module docstring); ``stages``: and where it goes (each
    stage's CPU, the methods wrapped for the run: a little slower in all)."""
    import torch

    from wearnav.live import buffer, crowd
    from wearnav.live.bench import walker_export
    from wearnav.live.models import SharedModels
    from wearnav.live.tracker import LiveTracker

    torch.set_num_threads(1)
    work = Path(tempfile.mkdtemp(prefix="wearnav-tracker-cost-"))
    simulated_export(work / "export", seed=seed, duration_s=walk_s)
    rp = replay.build(walker_export(work / "export", "phone"), batch_s=BATCH_S, start_ns=time.time_ns())
    bodies = [json.dumps({k: v for k, v in m.items() if k[0] != "_"}).encode() for m in rp.messages]
    spent: dict[str, float] = {}
    saved = []
    if stages:
        for owner, name, label in _stages():
            saved.append((owner, name, owner.__dict__[name]))
            _timed(owner, name, label, spent)
    try:
        models = SharedModels("cpu")
        models.preload()
        cr = crowd.Crowd(lambda: LiveTracker(models=models))
        cr.stop()  # its thread ends: the ticks run here
        bufs = {f"w{i}": buffer.SessionBuffer(f"w{i}", rp.platform, rp.standardised) for i in range(walkers)}
        cpu = 0.0
        for raw in bodies:
            for sid, buf in bufs.items():
                buf.add_body(raw)
                cr.poke(sid, buf)
            tic = time.process_time()
            cr.tick()
            cpu += time.process_time() - tic
        for sess in cr.sessions.values():  # the sessions end: their last windows made final
            sess.last_push -= 2 * crowd.SESSION_END_S
        tic = time.process_time()
        cr.tick()
        cpu += time.process_time() - tic
    finally:
        for owner, name, raw in saved:
            setattr(owner, name, raw)
    walker_s = walkers * len(bodies) * BATCH_S
    busy = np.asarray(cr.sessions["w0"].tracker.timings) * 1e3
    out = {
        "walkers": walkers,
        "walk_s": round(len(bodies) * BATCH_S, 1),
        "tracking_cpu_s": round(cpu, 3),
        "ms_per_walker_second": round(1e3 * cpu / walker_s, 3),
        "update_ms": {"p50": round(float(np.median(busy)), 2), "p95": round(float(np.percentile(busy, 95)), 2)},
        "updates_of_one_walker": int(busy.size),
        "load_1min": round(os.getloadavg()[0], 2),
    }
    if stages:
        by_stage = {k: round(1e3 * v / walker_s, 3) for k, v in spent.items()}
        by_stage["the rest"] = round(1e3 * (cpu - sum(spent.values())) / walker_s, 3)
        out["stages_ms_per_walker_second"] = by_stage
    return out


__all__ = ["receiver_cost", "tracker_cost", "walker_bodies"]
