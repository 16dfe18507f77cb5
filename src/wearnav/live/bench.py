"""``wearnav live bench``: the receiver under load, measured on this machine.

Two phases, each against a real ``wearnav live`` process on 127.0.0.1 (:mod:`wearnav.live.process`)
fed by :mod:`wearnav.live.replay` over real HTTP, from a simulated walk written as an iPhone's
Sensor Logger export (phone: accelerometer, gravity, gyroscope, orientation at 100 Hz; watch
100 Hz; earbuds 25 Hz, as AirPods; fixes 1 Hz):

1. **Load**: ``duration_s`` wall seconds of the walk replayed at ``speed`` × real time (0.2-s
   batches), no tracking: acknowledgement latency (POST sent → 200 received, p50 / p95 / p99 /
   max), whether it kept up, and lost or duplicated samples: the stored session exported and
   compared, device by device, with importing the export directly.
2. **CPU share**: ``cpu_s`` seconds replayed at real time, with the live tracker where this
   installation has one: the server process's CPU time (user + system, ``/proc``) over the
   replay's wall time, as a share of one core, and the tracker's update latency (the oldest
   unprocessed 200 → its path update done).

``results.json`` and ``results.md`` go to ``out`` (``wearnav results`` stitches the page into
docs/results.md).
"""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import time
from pathlib import Path

import httpx
import numpy as np

from wearnav.fileio import write_text_atomic
from wearnav.importers import sensorlogger
from wearnav.importers.sensorlogger_build import build_recording
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.importers.sensorlogger_map import Table
from wearnav.live import replay
from wearnav.live.export import export_session
from wearnav.live.process import LiveServer
from wearnav.provenance import provenance

BATCH_S = 0.2


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
        same = dev in ref.devices and dev in live.devices and a.size == b.size and bool(
            np.allclose(ref.devices[dev].acc, live.devices[dev].acc, atol=1e-6))
        out[dev] = {"samples": int(a.size), "lost": int(a.size - common), "duplicated": int(b.size - common),
                    "equal": same}
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
        time.sleep(1.0)   # start-up work done
        c0, w0 = srv.cpu_s(), time.perf_counter()
        res = replay.send(rp, f"{srv.url}/push", speed=speed, stop_after=n)
        c1, w1 = srv.cpu_s(), time.perf_counter()
    samples = sum(len(m["payload"]) for m in rp.messages[:n])
    live = export_session(work / "load.db", "bench-load", work / "load-export")
    ref = reference(export, rp.messages[n - 1]["_due_s"])
    live_rec = live.load("bench-load")
    lat = res.ack_latency_s
    return {"messages": n, "samples": samples, "data_s": round(n * BATCH_S, 1), "speed": speed,
            "wall_s": round(res.wall_s, 2), "schedule_s": round(n * BATCH_S / speed, 2),
            "behind_at_end_s": round(res.late_s, 3), "acknowledged": len(res.acknowledged), "retries": res.retries,
            "cpu_share_of_one_core": None if c0 is None or c1 is None else round((c1 - c0) / (w1 - w0), 4),
            "ack_ms": {"p50": _pct(lat, 50), "p95": _pct(lat, 95), "p99": _pct(lat, 99),
                       "max": round(1e3 * max(lat), 2) if lat else None},
            "devices": lost_and_duplicated(ref, live_rec)}


def cpu_phase(work: Path, export: Path, cpu_s: float, track: bool) -> dict:
    tracking = track and importlib.util.find_spec("wearnav.live.tracker") is not None
    rp = replay.build(export, batch_s=BATCH_S, session_id="bench-cpu")
    n = min(len(rp.messages), int(round(cpu_s / BATCH_S)))
    with LiveServer(work / "cpu.db", *([] if tracking else ["--no-track"])) as srv:
        time.sleep(1.0)   # start-up work done
        c0, w0 = srv.cpu_s(), time.perf_counter()
        res = replay.send(rp, f"{srv.url}/push", speed=1.0, stop_after=n)
        c1, w1 = srv.cpu_s(), time.perf_counter()
        time.sleep(1.0)   # the tracker's last update
        stats = httpx.get(f"{srv.url}/stats").json()
    lat = [x for v in stats.get("update_latency_s", {}).values() for x in v]
    share = None if c0 is None or c1 is None else round((c1 - c0) / (w1 - w0), 4)
    return {"seconds": round(w1 - w0, 1), "messages": n, "tracking": tracking, "cpu_share_of_one_core": share,
            "cores": os.cpu_count(), "ack_ms": {"p50": _pct(res.ack_latency_s, 50), "p99": _pct(res.ack_latency_s, 99)},
            "update_ms": {"p50": _pct(lat, 50), "p95": _pct(lat, 95), "n": len(lat)}}


def run_bench(out: str | Path, duration_s: float = 60.0, speed: float = 10.0, cpu_s: float = 30.0,
              track: bool = True, seed: int = 0) -> Path:
    out = Path(out)
    work = out / "work"
    for name in ("load.db", "cpu.db"):
        for suffix in ("", "-wal", "-shm"):
            (work / (name + suffix)).unlink(missing_ok=True)
    export = work / "export"
    if not (export / "Metadata.csv").is_file():
        simulated_export(export, seed=seed, duration_s=max(duration_s * speed, cpu_s) + 2.0)
    if (work / "load-export").exists():
        import shutil
        shutil.rmtree(work / "load-export")
    result = {"load": load_phase(work, export, duration_s, speed), "cpu": cpu_phase(work, export, cpu_s, track),
              "machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count()},
              "provenance": provenance()}
    write_text_atomic(json.dumps(result, indent=1, default=str), out / "results.json")
    return write_text_atomic(page(result), out / "results.md")


def page(r: dict) -> str:
    ld, cpu, p = r["load"], r["cpu"], r["provenance"]
    lost = sum(d["lost"] for d in ld["devices"].values())
    dup = sum(d["duplicated"] for d in ld["devices"].values())
    rows = "\n".join(f"| {dev} | {d['samples']} | {d['lost']} | {d['duplicated']} | {'yes' if d['equal'] else 'no'} |"
                     for dev, d in ld["devices"].items())
    share = cpu["cpu_share_of_one_core"]
    share_txt = "not measured (no /proc)" if share is None else f"{100 * share:.1f} % of one core"
    upd = (f"; tracker update after a 200: p50 {cpu['update_ms']['p50']} ms, p95 {cpu['update_ms']['p95']} ms "
           f"({cpu['update_ms']['n']} updates)") if cpu["tracking"] else " (tracking off: no live tracker in this installation)"
    return "\n".join([
        "# Live receiver (wearnav live)", "",
        f"Generated by `wearnav live bench` ({p['created']}, wearnav {p['wearnav']} {p['commit']}) on this machine: "
        f"{r['machine']['cpu']}, {r['machine']['cores']} CPUs; a real `wearnav live` process on 127.0.0.1 fed by "
        "`wearnav replay` over HTTP from a simulated walk written as an iPhone's Sensor Logger export (phone's four "
        "motion sensors and the watch at 100 Hz, earbuds at 25 Hz, fixes at 1 Hz: 526 samples per second of walk; "
        f"{BATCH_S:g}-s batches). Ack latency: POST sent → 200 received, the message committed to SQLite "
        "(WAL, synchronous=FULL) first. The machine is shared: timings vary with load.", "",
        f"## Load: {ld['data_s']:g} s of walk at {ld['speed']:g}× real time", "",
        f"{ld['messages']} messages ({ld['samples']} samples) in {ld['wall_s']} s (schedule {ld['schedule_s']} s; "
        f"{ld['behind_at_end_s']} s behind at the end), {ld['acknowledged']} acknowledged, {ld['retries']} retries. "
        f"Ack latency: p50 {ld['ack_ms']['p50']} ms, p95 {ld['ack_ms']['p95']} ms, p99 {ld['ack_ms']['p99']} ms, "
        f"max {ld['ack_ms']['max']} ms. The server process used "
        + ("?" if ld["cpu_share_of_one_core"] is None else f"{100 * ld['cpu_share_of_one_core']:.0f} %")
        + f" of one core (storing only, no tracking: {ld['speed']:g} walkers' worth of pushes). Lost samples: {lost}, duplicated: {dup} (the stored session exported with "
        "`wearnav live export`, compared with `wearnav import` of the same export):", "",
        "| device | samples | lost | duplicated | equal to the import |", "|---|---|---|---|---|", rows, "",
        f"## CPU share at real time ({cpu['seconds']} s, one walker)", "",
        f"The server process used {share_txt} while one walker's pushes arrived in real time"
        f"{' with live tracking' if cpu['tracking'] else ''}{upd}. Ack latency at real time: p50 "
        f"{cpu['ack_ms']['p50']} ms, p99 {cpu['ack_ms']['p99']} ms.", ""])


__all__ = ["lost_and_duplicated", "run_bench"]
