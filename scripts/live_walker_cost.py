"""What one phone-only walker costs the live tracker (docs/live-scaling.md, "What one walker costs").

A simulated walk (``wearnav simulate --format sensorlogger``'s export, phone-only as ``wearnav live
bench`` makes it) is pushed message by message (0.2-s batches, as Sensor Logger sends them) into
``--walkers`` session buffers at once, and one :class:`wearnav.live.crowd.Crowd` tracks them, its
ticks run here in this thread after each round of messages (no HTTP, no clock: the tracking CPU
alone). Prints the tracking CPU per walker-second of data and where it goes (each stage's process
CPU time, summed over the walkers), or with ``--profile FILE`` a cProfile of the ticks instead.

    PYTHONPATH=src OMP_NUM_THREADS=1 python scripts/live_walker_cost.py --walk-s 90 --walkers 8
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import os
import pstats
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live import buffer as live_buffer
from wearnav.live import crowd as live_crowd
from wearnav.live import tracker as live_tracker
from wearnav.live.bench import walker_export
from wearnav.live.models import SharedModels
from wearnav.live.replay import build

STAGES = [  # (owner, method, what the docs call it)
    (live_buffer.SessionBuffer, "recording", "the update's Recording from the buffer"),
    (live_tracker.LiveTracker, "_windows", "aligning and windowing"),
    (live_crowd.Crowd, "_forward", "the odometry model (batched)"),
    (live_tracker.LiveTracker, "_grow", "growing the path"),
    (live_tracker.LiveTracker, "_take_fixes", "taking the fixes"),
    (live_tracker.LiveTracker, "_fuse", "the fixed-lag smoother"),
    (live_crowd.Crowd, "_activities", "the activity classifier"),  # its windows and one batched pass
    (live_tracker.LiveTracker, "_label", "the activity classifier"),  # each session's label from it
    (live_tracker.LiveTracker, "_snapshot", "the page's state"),
]


def timed(owner, name: str, label: str, spent: dict) -> None:
    """``owner.name`` adding its process CPU time to ``spent[label]`` (outermost calls only)."""
    raw = owner.__dict__[name]
    f = raw.__func__ if isinstance(raw, staticmethod) else raw
    depth = [0]

    @functools.wraps(f)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--walk-s", type=float, default=90.0, help="seconds of simulated walk (default 90)")
    ap.add_argument("--walkers", type=int, default=8, help="sessions tracked at once (default 8)")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--profile", type=Path, help="write a cProfile of the ticks here (no per-stage times)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    work = Path(tempfile.mkdtemp(prefix="wearnav-walker-cost-"))
    simulated_export(work / "export", seed=args.seed, duration_s=args.walk_s)
    rp = build(walker_export(work / "export", "phone"), batch_s=0.2, start_ns=time.time_ns())
    spent: dict[str, float] = {}
    if args.profile is None:
        for owner, name, label in STAGES:
            timed(owner, name, label, spent)
    models = SharedModels("cpu")
    crowd = live_crowd.Crowd(lambda: live_tracker.LiveTracker(models=models))
    crowd.stop()  # its thread ends: the ticks run here
    bufs = {f"w{i}": live_buffer.SessionBuffer(f"w{i}", rp.platform, rp.standardised) for i in range(args.walkers)}
    prof = cProfile.Profile() if args.profile is not None else None
    cpu = 0.0
    for msg in rp.messages:
        for sid, buf in bufs.items():
            buf.add(msg["payload"])
            crowd.poke(sid, buf)
        tic = time.process_time()
        if prof is not None:
            prof.enable()
        crowd.tick()
        if prof is not None:
            prof.disable()
        cpu += time.process_time() - tic
    for s in crowd.sessions.values():  # the sessions end: their last windows made final
        s.last_push -= 2 * live_crowd.SESSION_END_S
    tic = time.process_time()
    crowd.tick()
    cpu += time.process_time() - tic
    data_s = len(rp.messages) * 0.2
    walker_s = args.walkers * data_s
    busy = np.asarray(crowd.sessions["w0"].tracker.timings) * 1e3
    print(
        f"{args.walkers} phone-only walkers × {data_s:.0f} s of walk, load {os.getloadavg()[0]:.2f}: tracking CPU "
        f"{cpu:.2f} s = {1e3 * cpu / walker_s:.2f} ms per walker-second ({100 * cpu / walker_s:.2f} % of a core "
        f"per walker); one walker's {busy.size} updates took p50 {np.median(busy):.1f} ms, p95 "
        f"{np.percentile(busy, 95):.1f} ms (wall, its tick's batched model included)"
    )
    if prof is not None:
        prof.dump_stats(args.profile)
        pstats.Stats(prof).sort_stats("cumulative").print_stats(30)
        return
    for label, s in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {label:40s} {1e3 * s / walker_s:6.2f} ms per walker-second {100 * s / cpu:5.1f} %")
    rest = cpu - sum(spent.values())
    print(f"  {'the rest':40s} {1e3 * rest / walker_s:6.2f} ms per walker-second {100 * rest / cpu:5.1f} %")


if __name__ == "__main__":
    main()
