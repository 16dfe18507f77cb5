"""``wearnav live bench``: the receiver under load, measured on this machine.

Two phases, each against a real ``wearnav live`` process on 127.0.0.1 (:mod:`wearnav.live.process`)
fed by :mod:`wearnav.live.replay` over real HTTP, from a simulated walk written as an iPhone's
Sensor Logger export (phone: accelerometer, gravity, gyroscope, orientation at 100 Hz; watch
100 Hz; earbuds 25 Hz, as AirPods; fixes 1 Hz):

1. **Load**: ``duration_s`` wall seconds of the walk replayed at ``speed`` × real time (0.2-s
   batches), no tracking: acknowledgement latency (POST sent → 200 received, p50 / p95 / p99 /
   max), whether it kept up, and lost or duplicated samples: the stored session exported and
   compared, device by device, with importing the export directly.
2. **Walkers**: 1, 2, 4, 8 ... sessions (``walkers``) replayed at once at real time for ``cpu_s``
   seconds each, with the live tracker where this installation has one: the server process's CPU
   time (user + system, ``/proc``) over the wall time as a share of one core, ack latency, the
   tracker's update latency (the oldest 200 not yet on the page → the update that changed the
   path), and whether it kept up (stops at the first count that does not): the capacity of this
   machine.
3. **Bad input**: :func:`wearnav.live.badinputs.catalogue`, a body over the size limit, random
   byte mutations of a good body, requests without the token, a flood past the rate limit.
4. **Faults**: SIGKILL mid-replay and restart (twice): acknowledged messages missing, and the
   final export against importing the export directly.

``results.json`` and ``results.md`` go to ``out`` (``wearnav results`` stitches the page into
docs/results.md).
"""

from __future__ import annotations

import http.client
import importlib.util
import json
import logging
import os
import platform
import shutil
import sqlite3
import threading
import time
from dataclasses import replace
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import numpy as np

from wearnav import pretrained
from wearnav.core.fileio import write_text_atomic
from wearnav.core.provenance import provenance
from wearnav.errors import ConfigError
from wearnav.importers import sensorlogger
from wearnav.importers.sensorlogger_build import build_recording
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.importers.sensorlogger_map import DEVICE_FILES, Table
from wearnav.live import replay
from wearnav.live.badinputs import body, catalogue, enc
from wearnav.live.bench_page import BATCH_S, KEPT_UP_UPDATE_S, LATENCY_GOAL_S, page
from wearnav.live.export import export_session
from wearnav.live.process import LiveServer, cpu_s, start_tracker
from wearnav.live.trackers import STATS_EVERY_S

log = logging.getLogger(__name__)

# The walkers a walkers phase replays: phone-only (the default model is then wearnav.pretrained's
# phone_only_choice: PDR or the shipped phone model) or phone, watch and earbuds (the shipped
# three-device model).
WALKER_DEVICES = {"phone": ("phone",), "all": ("phone", "watch", "earbuds")}


def _pct(x, q) -> float | None:
    return None if not len(x) else round(float(np.percentile(np.asarray(x) * 1e3, q)), 2)


def lost_and_duplicated(ref, live) -> dict:
    """Per device: samples of ``ref`` missing from ``live`` and extra samples in ``live``
    (matched by time), and whether the common samples are equal."""
    out = {}
    for dev in sorted(set(ref.devices) | set(live.devices)):
        a = ref.devices[dev].t if dev in ref.devices else np.zeros(0)
        b = live.devices[dev].t if dev in live.devices else np.zeros(0)
        common = np.intersect1d(np.round(a, 9), np.round(b, 9)).size
        same = (
            dev in ref.devices
            and dev in live.devices
            and a.size == b.size
            and bool(np.allclose(ref.devices[dev].acc, live.devices[dev].acc, atol=1e-6))
        )
        out[dev] = {
            "samples": int(a.size),
            "lost": int(a.size - common),
            "duplicated": int(b.size - common),
            "equal": same,
        }
    return out


def reference(export: Path, data_s: float):
    """What importing ``export`` gives for its first ``data_s`` seconds (every sensor's rows cut
    where the replay stopped, then the importer's own build)."""
    platform_, standardised, info, tables = sensorlogger.export_tables(export)
    t_first = min(int(tb.t_ns[0]) for tb in tables.values())
    lim = t_first + int(round(data_s * 1e9))
    cut = {}
    for fname, tb in tables.items():
        k = tb.t_ns < lim
        cut[fname] = Table(tb.path, tb.t_ns[k], tb.df[k].reset_index(drop=True), tb.duplicates)
    return build_recording(cut, platform_, standardised, export, "reference", export.name, info)


def load_phase(work: Path, export: Path, duration_s: float, speed: float) -> dict:
    rp = replay.build(export, batch_s=BATCH_S, session_id="bench-load")
    n = min(len(rp.messages), int(round(duration_s * speed / BATCH_S)))
    with LiveServer(work / "load.db", "--no-track") as srv:
        time.sleep(1.0)  # start-up work done
        c0, w0 = srv.cpu_s(), time.perf_counter()
        res = replay.send(rp, f"{srv.url}/push", speed=speed, stop_after=n)
        c1, w1 = srv.cpu_s(), time.perf_counter()
    samples = sum(len(m["payload"]) for m in rp.messages[:n])
    live = export_session(work / "load.db", "bench-load", work / "load-export")
    ref = reference(export, rp.messages[n - 1]["_due_s"])
    live_rec = live.load("bench-load")
    lat = res.ack_latency_s
    return {
        "messages": n,
        "samples": samples,
        "data_s": round(n * BATCH_S, 1),
        "speed": speed,
        "wall_s": round(res.wall_s, 2),
        "schedule_s": round(n * BATCH_S / speed, 2),
        "behind_at_end_s": round(res.late_s, 3),
        "acknowledged": len(res.acknowledged),
        "retries": res.retries,
        "cpu_share_of_one_core": None if c0 is None or c1 is None else round((c1 - c0) / (w1 - w0), 4),
        "ack_ms": {
            "p50": _pct(lat, 50),
            "p95": _pct(lat, 95),
            "p99": _pct(lat, 99),
            "max": round(1e3 * max(lat), 2) if lat else None,
        },
        "devices": lost_and_duplicated(ref, live_rec),
    }


def send_lean(url: str, bodies: list[bytes], due_s: list[float], t_start: float) -> replay.Result:
    """One walker's messages (``bodies``, encoded beforehand) each at ``t_start + due_s`` (perf_counter
    s) over one keep-alive connection, as :func:`wearnav.live.replay.send` sends them but with
    little of the sender's own CPU (``http.client``, no encoding on the way): on this 2-core machine
    a hundred httpx senders used more of it than the server measured. A failed request is retried
    on a new connection every 0.1 s, for at most 60 s."""
    parts = urlsplit(url)
    target = f"{parts.path}?{parts.query}" if parts.query else parts.path
    headers = {"content-type": "application/json"}
    res = replay.Result()

    def connect() -> http.client.HTTPConnection:
        return http.client.HTTPConnection(parts.hostname or "127.0.0.1", parts.port, timeout=10.0)

    conn = connect()
    for k, (raw, due) in enumerate(zip(bodies, due_s)):
        wait = t_start + due - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        res.late_s = max(0.0, -wait)
        give_up = time.perf_counter() + 60.0
        while True:
            t0 = time.perf_counter()
            status: int | None
            try:
                conn.request("POST", target, raw, headers)
                answer = conn.getresponse()
                text = answer.read()
                status = answer.status
            except (OSError, http.client.HTTPException):
                conn.close()
                conn, status, text = connect(), None, b""
            res.sent += 1
            if status == 200:
                res.ack_latency_s.append(time.perf_counter() - t0)
                res.acknowledged.append(k)
                break
            if status is not None and status < 500 and status != 429:
                raise ConfigError(f"the receiver refused message {k}: {status} {text[:200]!r}")
            if time.perf_counter() > give_up:
                raise ConfigError(f"no answer from {url} for 60 s (message {k})")
            res.retries += 1
            time.sleep(0.1)
    conn.close()
    res.wall_s = time.perf_counter() - t_start
    return res


def walker_export(export: Path, devices: str) -> Path:
    """The export a walker of ``devices`` (a key of :data:`WALKER_DEVICES`) replays: ``export``
    itself, or beside it a copy without the wearables' files (phone-only)."""
    if devices == "all":
        return export
    if devices not in WALKER_DEVICES:
        raise ConfigError(f"walker devices {devices!r}: one of {', '.join(WALKER_DEVICES)}")
    folder = export.with_name(f"{export.name}-{devices}")
    if not (folder / "Metadata.csv").is_file():
        if folder.exists():
            shutil.rmtree(folder)
        shutil.copytree(export, folder, ignore=shutil.ignore_patterns(*DEVICE_FILES.values()))
    return folder


def walkers_phase(
    work: Path,
    export: Path,
    walkers: int,
    seconds: float,
    track: bool,
    devices: str = "all",
    trackers: int = 0,
    model_device: str = "cpu",
) -> dict:
    """``walkers`` sessions of ``devices`` (:data:`WALKER_DEVICES`) replayed at once at real time into
    one server (with the live tracker where there is one; ``trackers`` > 0: the server stores only and
    that many ``wearnav live track`` processes track, sharing its store): the CPU share of the server
    (and trackers), ack latency, tracker update latency, and whether it kept up."""
    tracking = track and importlib.util.find_spec("wearnav.live.tracker") is not None
    base = replay.build(walker_export(export, devices), batch_s=BATCH_S, session_id="walker-0")
    n = min(len(base.messages), int(round(seconds / BATCH_S)))
    plays = [
        replace(base, session_id=f"walker-{i}", messages=[{**m, "sessionId": f"walker-{i}"} for m in base.messages[:n]])
        for i in range(walkers)
    ]
    load_before = os.getloadavg()[0]  # the machine is shared: its load beside every figure
    bodies = [[json.dumps({k: v for k, v in m.items() if k[0] != "_"}).encode() for m in rp.messages] for rp in plays]
    due = [m["_due_s"] for m in base.messages[:n]]
    results: list = [None] * walkers
    # every walker pushes from 127.0.0.1 here, where real ones have an address each: the per-client
    # rate limit is raised to ten times what they send together (else it caps them at 100 messages a second)
    limit = ["--rate-limit", f"{max(100.0, 10 * walkers / BATCH_S):g}"]
    db = work / f"walkers-{devices}-{walkers}{f'-t{trackers}' if trackers else ''}.db"
    for old in work.glob(f"{db.name}*"):
        old.unlink()
    procs: list = []
    stats_files = [db.with_suffix(f".tracker{i}.json") for i in range(trackers if tracking else 0)]
    for f in stats_files:
        f.unlink(missing_ok=True)
    on = ["--model-device", model_device]
    with LiveServer(db, *limit, *(on if tracking and not trackers else ["--no-track"])) as srv:
        procs = [
            start_tracker(db, (i, len(stats_files)), *on, stats=f, log=f.with_suffix(".log"))
            for i, f in enumerate(stats_files)
        ]
        try:
            deadline = time.monotonic() + 60.0
            while not all(f.is_file() for f in stats_files) and time.monotonic() < deadline:
                time.sleep(0.2)  # the trackers have started (torch imported)
            time.sleep(1.0)  # start-up work done

            def used() -> float | None:
                parts = [srv.cpu_s(), *(cpu_s(p.pid) for p in procs)]
                return None if any(c is None for c in parts) else sum(c for c in parts if c is not None)

            r0, c0, w0, s0 = srv.cpu_s(), used(), time.perf_counter(), time.process_time()
            url = replay.push_url(f"{srv.url}/push", base)

            def walk(i: int) -> None:
                try:
                    results[i] = send_lean(url, bodies[i], due, w0 + i * BATCH_S / walkers)
                except ConfigError as e:  # the receiver refused it, or stopped answering: not kept up
                    gave_up.append(str(e))

            gave_up: list[str] = []
            # the walkers' pushes spread over one batch period, as walkers who did not start together
            threads = [threading.Thread(target=walk, args=(i,)) for i in range(walkers)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            r1, c1, w1, s1 = srv.cpu_s(), used(), time.perf_counter(), time.process_time()
            time.sleep(1.0 + (2 * STATS_EVERY_S if procs else 0.0))  # the last updates (and the trackers' summaries)
            try:  # a receiver that fell far behind may answer late, or not at all: then nothing is known of its updates
                stats = httpx.get(f"{srv.url}/stats", timeout=60.0).json()
            except httpx.HTTPError:
                stats = {}
        finally:
            for p in procs:
                p.terminate()
                p.wait(10)
    if stats_files:
        stats = {"update_latency_s": {}}
        for f in stats_files:
            stats["update_latency_s"].update(json.loads(f.read_text())["update_latency_s"])
    acks = [x for r in results if r is not None for x in r.ack_latency_s]
    upd = [x for v in stats.get("update_latency_s", {}).values() for x in v]
    behind = max((r.late_s for r in results if r is not None), default=float("inf"))
    complete = all(r is not None and len(r.acknowledged) == n for r in results)
    upd_p95 = _pct(upd, 95)
    kept_up = complete and behind < 1.0 and (not tracking or (upd_p95 is not None and upd_p95 < 1e3 * KEPT_UP_UPDATE_S))
    return {
        "walkers": walkers,
        "devices": devices,
        "model": odometry_name(WALKER_DEVICES[devices]) if tracking else None,
        "tracker_processes": len(stats_files),
        "load_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "seconds": round(w1 - w0, 1),
        "messages": n * walkers,
        "tracking": tracking,
        "cpu_share_of_one_core": None if c0 is None or c1 is None else round((c1 - c0) / (w1 - w0), 4),
        # with tracker processes: the receiver's own share (the rest is the trackers')
        "receiver_cpu_share_of_one_core": None
        if not procs or r0 is None or r1 is None
        else round((r1 - r0) / (w1 - w0), 4),
        # the walkers' senders (threads of this process) share the machine: what they took
        "senders_cpu_share_of_one_core": round((s1 - s0) / (w1 - w0), 4),
        "ack_ms": {"p50": _pct(acks, 50), "p99": _pct(acks, 99)},
        "behind_at_end_s": round(behind, 3),
        "update_ms": {"p50": _pct(upd, 50), "p95": upd_p95, "n": len(upd)},
        "kept_up": kept_up,
        # walkers that gave up, and why (the first reason): they count as not kept up
        **({"gave_up": {"walkers": len(gave_up), "first": gave_up[0]}} if gave_up else {}),
        "latency_goal_met": None if not tracking or upd_p95 is None else upd_p95 < 1e3 * LATENCY_GOAL_S,
    }


def odometry_name(devices: tuple[str, ...]) -> str:
    """The odometry a session with ``devices`` is tracked by without ``--model`` (shipped name or pdr):
    the bench's walkers push fixes from their start."""
    path, _ = pretrained.default_model("odometry", devices, has_fixes=True)
    return pretrained.shipped_name(path) or str(path)


def stored_rows(db: Path) -> int:
    with sqlite3.connect(db) as c:
        return c.execute("SELECT COUNT(*) FROM messages").fetchone()[0]


def bad_input_phase(work: Path, fuzz: int = 200, seed: int = 0) -> dict:
    """Every body of :func:`wearnav.live.badinputs.catalogue`, one over the size limit, ``fuzz``
    random mutations of a good body, a flood past the rate limit and requests without the token:
    how many were answered with the expected 4xx, and how many rows got stored (0 expected)."""
    rng = np.random.default_rng(seed)
    db, token = work / "bad.db", "bench-token"
    wrong: list[str] = []
    with (
        LiveServer(db, "--no-track", "--max-body", "65536", "--rate-limit", "20", "--token", token, token=token) as srv,
        httpx.Client(base_url=srv.url, headers={"authorization": f"Bearer {token}"}) as c,
    ):
        tried = 0
        for name, (raw, status, _word) in catalogue().items():
            tried += 1
            r = c.post("/push", content=raw)
            if r.status_code != status:
                wrong.append(f"{name}: {r.status_code}")
            time.sleep(0.06)  # under the rate limit
        big = enc(body(payload=[{"name": "battery", "time": time.time_ns(), "values": {"s": "x" * 70_000}}]))
        tried += 1
        if c.post("/push", content=big).status_code != 413:
            wrong.append("over the size limit")
        good = enc(body())
        fz = {"refused": 0, "accepted": 0, "stored": 0, "other": 0}
        for _ in range(fuzz):
            flipped = bytearray(good)
            for i in rng.integers(0, len(flipped), size=int(rng.integers(1, 6))):
                flipped[i] = int(rng.integers(0, 256))
            r = c.post("/push", content=bytes(flipped))
            if r.status_code in (400, 422):
                fz["refused"] += 1
            elif r.status_code == 200:  # still a valid push (a digit changed, say)
                fz["accepted"] += 1
                fz["stored"] += bool(r.json().get("stored"))
            else:
                fz["other"] += 1
            time.sleep(0.06)
        rows_after_bad = stored_rows(db)
        no_token = sum(httpx.post(f"{srv.url}/push", content=good).status_code == 401 for _ in range(5))
        time.sleep(1.0)
        flood = [c.post("/push", content=enc(body(messageId=1000 + k))).status_code for k in range(100)]
        rows_flood = stored_rows(db) - rows_after_bad
    return {
        "catalogue": tried,
        "catalogue_wrong": wrong,
        "fuzz": fuzz,
        "fuzz_answers": fz,
        "rows_after_bad": rows_after_bad,
        "no_token_401": no_token,
        "flood": len(flood),
        "flood_429": flood.count(429),
        "flood_200": flood.count(200),
        "flood_stored": rows_flood,
    }


def kill_phase(work: Path, export: Path, kills: int = 2, speed: float = 10.0, data_s: float = 60.0) -> dict:
    """A replay at ``speed`` × into a server SIGKILLed ``kills`` times and restarted on the same
    store: acknowledged messages missing after each restart (0 expected), and whether the final
    export equals importing the export directly."""
    db = work / "kill.db"
    rp = replay.build(export, batch_s=BATCH_S, session_id="bench-kill")
    n = min(len(rp.messages), int(round(data_s / BATCH_S)))
    acked: list[int] = []
    out: dict = {}
    srv = LiveServer(db, "--no-track").start()
    sender = threading.Thread(
        target=lambda: out.update(
            res=replay.send(rp, f"{srv.url}/push", speed=speed, stop_after=n, on_ack=acked.append)
        )
    )
    sender.start()
    missing = 0
    try:
        for k in range(kills):
            target = (k + 1) * n // (kills + 1)
            while len(acked) < target and sender.is_alive():
                time.sleep(0.01)
            srv.kill()
            before = set(acked)
            with sqlite3.connect(db) as c:
                ids = {m for (m,) in c.execute("SELECT message_id FROM messages")}
            missing += len(before - ids)
            srv = LiveServer(db, "--no-track", port=srv.port).start()
        sender.join()
    finally:
        srv.stop()
    res = out.get("res")
    live = export_session(db, "bench-kill", work / "kill-export").load("bench-kill")
    same = lost_and_duplicated(reference(export, rp.messages[n - 1]["_due_s"]), live)
    return {
        "kills": kills,
        "messages": n,
        "acknowledged": len(res.acknowledged) if res else 0,
        "retries": res.retries if res else 0,
        "acknowledged_missing": missing,
        "export_equal": all(d["equal"] and not d["lost"] and not d["duplicated"] for d in same.values()),
    }


def models_on(model_device: str = "cpu") -> str:
    """Where the trackers' odometry models run: ``model_device``, or for ``auto`` the choice
    :class:`wearnav.live.models.SharedModels` makes in every process of this machine (CUDA where
    there is one, else the CPU)."""
    if model_device == "cpu" or importlib.util.find_spec("torch") is None:
        return "cpu"
    import torch  # heavy: only to read the accelerator, once per bench

    from wearnav.live.models import SharedModels  # its choice, made as every tracker process makes it

    device = SharedModels(model_device).device
    return f"cuda ({torch.cuda.get_device_name(device)})" if device.type == "cuda" else "cpu"


def run_bench(
    out: str | Path,
    duration_s: float = 60.0,
    speed: float = 10.0,
    cpu_s: float = 30.0,
    track: bool = True,
    walkers: tuple[int, ...] = (1, 2, 4, 8),
    fuzz: int = 200,
    seed: int = 0,
    devices: tuple[str, ...] = ("all",),
    trackers: int = 0,
    model_device: str = "cpu",
) -> Path:
    """Every phase (module docstring) into ``out``; the walkers phase once per kind of walker in
    ``devices`` (keys of :data:`WALKER_DEVICES`), each up to the first count that does not keep up;
    ``trackers`` > 0: tracked by that many ``wearnav live track`` processes beside a storing receiver;
    ``model_device``: where their odometry models run (``wearnav live --model-device``)."""
    for d in devices:
        if d not in WALKER_DEVICES:
            raise ConfigError(f"--devices {d!r}: one of {', '.join(WALKER_DEVICES)}")
    out = Path(out)
    work = out / "work"
    for db in work.glob("*.db*"):
        db.unlink()
    export = work / "export"
    if not (export / "Metadata.csv").is_file():
        simulated_export(export, seed=seed, duration_s=max(duration_s * speed, cpu_s) + 2.0)
    for folder in ("load-export", "kill-export"):
        if (work / folder).exists():
            shutil.rmtree(work / folder)
    rows = []
    for kind in devices:
        for k in sorted(set(walkers) | {1}):
            rows.append(walkers_phase(work, export, k, cpu_s, track, kind, trackers, model_device))
            log.info("%s", {key: rows[-1][key] for key in ("walkers", "devices", "kept_up", "update_ms")})
            if not rows[-1]["kept_up"]:
                break  # more walkers will not keep up either
    result = {
        "load": load_phase(work, export, duration_s, speed),
        "walkers": rows,
        "bad_inputs": bad_input_phase(work, fuzz=fuzz),
        "faults": kill_phase(work, export, speed=speed),
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cores": os.cpu_count(),
            "models_on": models_on(model_device),
        },
        "provenance": provenance(),
    }
    write_text_atomic(json.dumps(result, indent=1, default=str), out / "results.json")
    return write_text_atomic(page(result), out / "results.md")


__all__ = ["lost_and_duplicated", "run_bench"]
