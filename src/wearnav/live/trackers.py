"""Tracker processes beside the receiver (issue 37, "past one machine"): ``wearnav live track``.

A receiver started with ``--no-track`` only stores (every message committed before its 200) and
serves; trackers run as separate processes that share its store. Each reads the messages by row id
as they are committed (:meth:`wearnav.live.store.Store.messages_after`, polled every ``POLL_S``),
keeps the sessions of its shard (``--shard i/n``: the k-th session to arrive in the store, by its
first message's row id, belongs to shard k mod n; every tracker reads the same rows in the same
order, so every session has exactly one tracker and none is tracked twice, and n trackers hold
sessions that differ in number by at most one; this rests on the store never deleting a message,
which it does not), updates them with a
:class:`wearnav.live.crowd.Crowd` (the model once per tick for all of them) and writes each
session's page state into the store every ``STATE_EVERY_S``, where the receiver's ``/state`` and
``/events`` find it. A tracker that is restarted reads the store from the start again and resumes
every session of its shard (as a restarted receiver does).

:func:`place_on_ray` starts ``n`` trackers as Ray tasks of one CPU each (``wearnav live track
--executor ray --address ...``), on whichever nodes the cluster has room on: every node needs
wearnav installed and the store's path (SQLite, WAL: a file system that all of them share with
working locks, as a single machine's or a cluster node's local disk mounted at the same path;
WAL over NFS is not safe, docs/live-scaling.md).

Decision: docs/decisions/0028-live-crowd.md.
"""

from __future__ import annotations

import gc
import json
import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from wearnav.bench.executor import RAY_MISSING
from wearnav.core.fileio import write_text_atomic
from wearnav.errors import ConfigError
from wearnav.fuse.radiomap import RadioMap
from wearnav.live.buffer import NS, SessionBuffer
from wearnav.live.crowd import Crowd
from wearnav.live.models import SharedModels
from wearnav.live.store import open_store
from wearnav.live.store_pg import is_url
from wearnav.live.tracker import LiveTracker

log = logging.getLogger("wearnav.live")
POLL_S = 0.1  # the store is read for new messages this often (s)
STATE_EVERY_S = 0.25  # each session's changed state is written at most this often (the page's /events rate)
STATS_EVERY_S = 1.0  # a tracker's summary (--stats) is rewritten this often
# A session whose tracker's state is unchanged has its state rewritten only this often while its
# messages arrive (the devices' rates and last-seen times, the messages counted). Issue 61: making
# and comparing every session's state four times a second was 9 % of a tracker process's CPU.
DEVICES_EVERY_S = 1.0


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/n"`` → (i, n), 0 ≤ i < n."""
    try:
        i, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise ConfigError(f"--shard {text!r}: i/n, e.g. 0/2") from None
    if not 0 <= i < n:
        raise ConfigError(f"--shard {text!r}: i/n with 0 ≤ i < n")
    return i, n


class TrackerProcess:
    """One tracker over ``store`` for shard ``shard`` = (i, n); :meth:`run` until ``stop`` is set."""

    def __init__(
        self,
        store: str | Path,
        tracker_factory: Callable[[], Any],
        shard: tuple[int, int] = (0, 1),
        stats: str | Path | None = None,
    ):
        self.store = open_store(store)
        self.shard = shard
        self.stats = None if stats is None else Path(stats)
        self.crowd = Crowd(tracker_factory)
        self.buffers: dict[str, SessionBuffer] = {}
        self.last_rowid = 0
        # every session in the store → its place in the order of arrival (module docstring: the shards).
        # Issue 61: a hash of the id split 100 walkers 45 / 55, and the process of 55 was the slow one.
        self.arrived: dict[str, int] = {}
        self.messages = 0
        self._written: dict[str, str] = {}
        self._made: dict[str, tuple] = {}  # session → (its Crowd.state_key, messages, monotonic time) when made

    def poll(self) -> int:
        """Read the messages committed since the last poll; poke their sessions. How many were this shard's."""
        i, n = self.shard
        taken = 0
        touched: dict[str, int] = {}  # session → receive time of its oldest new message, ns
        while rows := self.store.messages_after(self.last_rowid):
            for rowid, sid, platform, standardised, received_ns, body in rows:
                self.last_rowid = rowid
                if self.arrived.setdefault(sid, len(self.arrived)) % n != i:
                    continue
                buf = self.buffers.get(sid)
                if buf is None:
                    buf = self.buffers[sid] = SessionBuffer(sid, platform, bool(standardised))
                buf.add_body(body, received_unix_s=received_ns / NS)
                taken += 1
                touched.setdefault(sid, received_ns)  # the oldest new message of the session
        # its latency runs from when the receiver stored it (just before its 200; one clock on one machine)
        wall_ns, now = time.time_ns(), time.perf_counter()
        for sid, received_ns in touched.items():
            self.crowd.poke(sid, self.buffers[sid], since=now - max(0, wall_ns - received_ns) / NS)
        self.messages += taken
        return taken

    def write_states(self) -> int:
        """The page state of every session whose state changed, into the store; how many. A state
        is made again when its tracker's changed, or every ``DEVICES_EVERY_S`` while messages arrive."""
        changed = {}
        now = time.monotonic()
        for sid, buf in self.buffers.items():
            key = self.crowd.state_key(sid)
            if key is None:
                continue
            made = self._made.get(sid)
            if made is not None and made[0][0] is key[0] and made[0][1] == key[1]:
                if made[1] == buf.messages or now - made[2] < DEVICES_EVERY_S:
                    continue
            st = self.crowd.state(sid)
            if st is None:
                continue
            self._made[sid] = (key, buf.messages, now)
            text = json.dumps(
                {
                    **st,
                    "tracker": f"{self.shard[0]}/{self.shard[1]}",
                    "tracked_messages": buf.messages,
                    "devices": buf.devices(),  # the whole session's (a receiver of several sees a part)
                }
            )
            if self._written.get(sid) != text:
                changed[sid] = text
        self.store.put_states(changed)
        self._written.update(changed)
        return len(changed)

    def summary(self) -> dict:
        """What this tracker did: its shard, sessions, messages, and each session's update latency
        (s, from the receiver storing a message to the update that put it on the page)."""
        return {
            "shard": list(self.shard),
            "sessions": len(self.buffers),
            "messages": self.messages,
            "ticks": self.crowd.ticks,
            "update_latency_s": self.crowd.latency_s(),
        }

    def run(self, stop: threading.Event | None = None, max_s: float | None = None) -> dict:
        """Poll, track and write states until ``stop`` is set (or ``max_s`` has passed); the
        :meth:`summary` also to ``stats`` (JSON) every ``STATS_EVERY_S`` and at the end."""
        stop = stop or threading.Event()
        t_end = None if max_s is None else time.monotonic() + max_s
        next_write = next_stats = 0.0
        try:
            while not stop.is_set() and (t_end is None or time.monotonic() < t_end):
                self.poll()
                if time.monotonic() >= next_write:
                    self.write_states()
                    next_write = time.monotonic() + STATE_EVERY_S
                if self.stats is not None and time.monotonic() >= next_stats:
                    write_text_atomic(json.dumps(self.summary()), self.stats)
                    next_stats = time.monotonic() + STATS_EVERY_S
                stop.wait(POLL_S)
            self.write_states()
        finally:
            self.crowd.stop()
        if self.stats is not None:
            write_text_atomic(json.dumps(self.summary()), self.stats)
        return self.summary()


def run_tracker(
    store: str,
    shard: tuple[int, int],
    model: str | None = None,
    max_s: float | None = None,
    stats: str | None = None,
    plan: str | None = None,
    model_device: str | None = None,
    radiomap: str | None = None,
) -> dict:
    """One tracker process's work (the CLI's and a Ray task's): LiveTrackers sharing one set of
    models (:class:`wearnav.live.models.SharedModels`, on ``model_device``: None, the
    CPU); ``plan``: a GeoJSON floor plan each session's page draws; ``radiomap``: a radio map folder
    whose positions of each session's Wi-Fi scans join its fixes (loaded once for all)."""
    rmap = None if radiomap is None else RadioMap.load(radiomap)
    models = SharedModels(model_device)
    models.preload(model)  # before the first session, which would otherwise wait for it
    # The modules and models loaded so far out of the collector's sight, as the receiver's (issue 61):
    # ~450,000 objects, whose full collection paused a crowd's tick for 0.31 s (measured, 50 walkers).
    gc.freeze()
    proc = TrackerProcess(
        store, lambda: LiveTracker(model=model, models=models, plan=plan, radiomap=rmap), shard, stats
    )
    log.info("tracker %d/%d on %s", *shard, store)
    return proc.run(max_s=max_s)


def place_on_ray(
    store: str | Path,
    trackers: int,
    model: str | Path | None = None,
    address: str | None = None,
    max_s: float | None = None,
    model_device: str | None = None,
) -> list:
    """``trackers`` tracker processes as Ray tasks of one CPU each, shards 0/n .. n−1/n, on the
    cluster at ``address`` (as ``ray.init``'s; a Ray instance already started in this process is
    used as it is). Returns their object refs (``ray.get`` waits; ``ray.cancel`` stops one)."""
    try:
        import ray
    except ImportError:
        raise ConfigError(RAY_MISSING) from None
    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, logging_level=logging.WARNING)
    task = ray.remote(run_tracker).options(num_cpus=1, max_retries=0)
    path = str(store) if is_url(str(store)) else str(Path(store).resolve())
    model_arg = None if model is None else str(model)
    return [task.remote(path, (i, trackers), model_arg, max_s, model_device=model_device) for i in range(trackers)]


__all__ = ["TrackerProcess", "parse_shard", "place_on_ray", "run_tracker"]
