"""Trackers as processes of their own beside one receiver (issue 37 §2): a real ``wearnav live
--no-track`` process on 127.0.0.1, real HTTP pushes, and two ``wearnav live track --shard i/2``
processes (or two Ray tasks) sharing its store. Nothing acknowledged is lost: every session ends
up tracked by exactly one tracker, whose buffer holds every message the receiver acknowledged,
and the receiver serves the tracker's path."""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from dataclasses import replace
from pathlib import Path

import httpx
import pytest

import live_stores
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live import replay
from wearnav.live.bench import walker_export
from wearnav.live.process import SRC, LiveServer, children, start_tracker
from wearnav.live.store import Store, open_store
from wearnav.live.trackers import TrackerProcess, parse_shard

WALK_S = 30.0
SPEED = 5.0
SESSIONS = ("walker-a", "walker-b", "walker-c")  # in both of two shards (checked below)
# the store fixtures (SQLite, PostgreSQL) of tests/live_stores.py
postgres_cluster, store_where, count = live_stores.postgres_cluster, live_stores.store_where, live_stores.count


@pytest.fixture(scope="module")
def phone_export(tmp_path_factory):
    folder = tmp_path_factory.mktemp("trackers") / "walk"
    simulated_export(folder, seed=7, duration_s=WALK_S)
    return walker_export(folder, "phone")


def push_sessions(url: str, export: Path) -> dict[str, list[int]]:
    """Every session of SESSIONS replayed at once at SPEED × real time; the acknowledged ids."""
    base = replay.build(export, batch_s=0.2, session_id=SESSIONS[0])
    plays = [replace(base, session_id=s, messages=[{**m, "sessionId": s} for m in base.messages]) for s in SESSIONS]
    acked: dict[str, list[int]] = {}

    def send(rp):
        acked[rp.session_id] = replay.send(rp, url, speed=SPEED).acknowledged

    threads = [threading.Thread(target=send, args=(rp,)) for rp in plays]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return acked


def stored_states(db: Path | str) -> dict[str, dict]:
    """Every session's state in the store (a SQLite file or a postgresql:// URL)."""
    store = open_store(db)
    try:
        return {sid: st for sid in store.sessions() if (st := store.state(sid)) is not None}
    finally:
        store.close()


def wait_for_states(db: Path | str, acked: dict[str, list[int]], timeout_s: float) -> dict[str, dict]:
    """The store's states once every session's tracker holds all its acknowledged messages and a path."""
    deadline = time.monotonic() + timeout_s
    while True:
        states = stored_states(db)
        if all(
            sid in states and states[sid]["tracked_messages"] == len(ids) and states[sid]["path"]
            for sid, ids in acked.items()
        ):
            return states
        if time.monotonic() > deadline:
            return states
        time.sleep(0.25)


def arrival_shards(where: Path | str, n: int) -> dict[str, int]:
    """Each session's shard of ``n`` by its order of arrival in the store (its first message's row)."""
    store = open_store(where)
    try:
        order: dict[str, int] = {}
        rowid = 0
        while rows := store.messages_after(rowid):
            for row in rows:
                order.setdefault(row[1], len(order))
            rowid = rows[-1][0]
        return {sid: k % n for sid, k in order.items()}
    finally:
        store.close()


def test_shards_split_the_sessions_by_arrival_and_parse(tmp_path):
    """The k-th session to arrive in the store is shard k mod n's, whatever its id: n trackers hold
    sessions that differ in number by at most one (issue 61: a hash of the ids split 100 walkers
    45 / 55), and a session stays with its tracker as its messages go on arriving."""
    db = tmp_path / "s.db"
    store = open_store(db)
    ids = [f"walker-{k}" for k in range(101)]
    for rnd in range(3):  # the sessions' messages interleaved, in three rounds
        body = '{{"messageId": {m}, "sessionId": "{s}", "deviceId": "d", "payload": []}}'
        store.add_many([(sid, "d", rnd, body.format(m=rnd, s=sid), "ios", False) for sid in ids])
    store.close()
    held = []
    for i in range(2):
        proc = TrackerProcess(db, lambda: None, (i, 2))
        proc.crowd.stop()
        proc.poll()
        held.append(set(proc.buffers))
        proc.store.close()
    assert held[0] == set(ids[0::2]) and held[1] == set(ids[1::2])  # 51 and 50
    assert arrival_shards(db, 2) == {sid: k % 2 for k, sid in enumerate(ids)}
    assert parse_shard("1/2") == (1, 2)
    for bad in ("2/2", "x", "1/0", "-1/2"):
        with pytest.raises(Exception, match="--shard"):
            parse_shard(bad)


def test_group_commit_many_threads_each_durable_and_counted_once(tmp_path):
    """Twenty threads adding at once: every message stored once (a repeat is a no-op), committed in
    fewer transactions than messages, each call returning only once its row is in the file."""
    from wearnav.live.app import Receiver
    from wearnav.live.badinputs import body, enc

    rx = Receiver(Store(tmp_path / "live.db"), None, 1 << 20, 1e6, None, "ios", False, 120, 7 * 86400)
    seen_in_file = []

    def push(k):
        rx.accept(enc(body(messageId=k % 40)), "ios", False)
        with sqlite3.connect(tmp_path / "live.db") as c:  # another connection sees it: committed
            seen_in_file.append(
                c.execute("SELECT COUNT(*) FROM messages WHERE message_id = ?", (k % 40,)).fetchone()[0]
            )

    threads = [threading.Thread(target=push, args=(k,)) for k in range(80)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert seen_in_file == [1] * 80
    assert rx.counts["accepted"] == 40 and rx.counts["repeats"] == 40
    assert rx.commits.items == 80 and rx.commits.batches < 80
    assert rx.buffers["s-1"].messages == 40


@pytest.mark.slow  # ~60 s on 2 cores: three processes start (five with the restarts) and load torch
def test_receiver_and_two_trackers_killed_and_restarted_lose_nothing(tmp_path, phone_export, store_where):
    """A receiver and two tracker processes on one store (SQLite, PostgreSQL), each SIGKILLed once
    while three walkers push and started again: every acknowledged message stored once, every
    session tracked by the tracker of its shard with all of its messages, and the path served."""
    db = tmp_path / "live.db"
    log = tmp_path / "trackers.log"
    srv = LiveServer(db, "--no-track", store_url=store_where).start()

    def tracker(i: int):
        return start_tracker(store_where, (i, 2), stats=tmp_path / f"t{i}.json", log=log)

    procs = [tracker(0), tracker(1)]
    out: dict = {}
    pusher = threading.Thread(target=lambda: out.update(acked=push_sessions(f"{srv.url}/push", phone_export)))
    n = len(replay.build(phone_export).messages)
    try:
        pusher.start()
        for i, wait_s in ((0, 1.5), (None, 1.0), (1, 1.0)):  # tracker 0, the receiver, tracker 1
            time.sleep(wait_s)
            if i is None:
                srv.kill()
                srv = LiveServer(db, "--no-track", port=srv.port, store_url=store_where).start()
            else:
                procs[i].kill()
                procs[i].wait(10)
                procs[i] = tracker(i)
        pusher.join(180)
        acked = out["acked"]
        assert all(ids == list(range(n)) for ids in acked.values())
        states = wait_for_states(store_where, acked, timeout_s=150.0)
        served = httpx.get(f"{srv.url}/state", params={"session": SESSIONS[1]}).json()
    finally:
        srv.stop()
        for p in procs:
            p.terminate()
            p.wait(10)
    assert count(store_where) == n * len(SESSIONS)
    assert set(states) == set(SESSIONS), log.read_text()[-3000:]
    shards = arrival_shards(store_where, 2)
    for sid in SESSIONS:
        assert states[sid]["tracker"] == f"{shards[sid]}/2"
        assert states[sid]["tracked_messages"] == n and len(states[sid]["path"]) > 5
    assert {states[s]["tracker"] for s in SESSIONS} == {"0/2", "1/2"}  # both processes tracked
    assert served["path"] and served["messages"] == n and set(served["devices"]) == {"phone"}
    assert served["tracker"] == states[SESSIONS[1]]["tracker"]  # the receiver serves the tracker's path


def test_live_trackers_options_one_line_errors(tmp_path, monkeypatch, capsys):
    from conftest import run_cli

    db = tmp_path / "live.db"
    code, _, err = run_cli(monkeypatch, capsys, "live", "--store", db, "--trackers", "2", "--no-track")
    assert code == 2 and "one or the other" in err and err.count("\n") == 1
    code, _, err = run_cli(monkeypatch, capsys, "live", "--store", db, "--executor", "ray", "--trackers", "0")
    assert code == 2 and "at least 1 with --executor ray" in err and err.count("\n") == 1
    assert not db.exists()  # refused before anything was made


def test_live_starts_and_stops_its_own_tracker_processes(tmp_path, phone_export):
    """``wearnav live --trackers 2`` stores and serves, and every session is tracked by one of the
    two ``wearnav live track`` processes it started (the page's state from the store); they stop
    with it (SIGTERM, as a service manager stops it)."""
    db = tmp_path / "live.db"
    srv = LiveServer(db, "--trackers", "2").start()
    try:
        assert srv.proc is not None
        kids = children(srv.proc.pid)
        acked = push_sessions(f"{srv.url}/push", phone_export)
        states = wait_for_states(db, acked, timeout_s=150.0)
        served = httpx.get(f"{srv.url}/state", params={"session": SESSIONS[0]}).json()
    finally:
        code = srv.stop()
    assert len(kids) == 2 and code == 0, srv.log.read_text()[-2000:]
    assert set(states) == set(SESSIONS), srv.log.read_text()[-3000:]
    shards = arrival_shards(db, 2)
    assert all(states[sid]["tracker"] == f"{shards[sid]}/2" for sid in SESSIONS)
    assert served["path"] and served["tracker"] == states[SESSIONS[0]]["tracker"]
    deadline = time.monotonic() + 15
    while any(Path(f"/proc/{pid}").exists() for pid in kids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(
        Path(f"/proc/{pid}/cmdline").exists() and b"track" in Path(f"/proc/{pid}/cmdline").read_bytes() for pid in kids
    )


@pytest.fixture(scope="module")
def local_ray():
    """A Ray instance on this machine with 2 CPUs (as a CI runner has)."""
    ray = pytest.importorskip("ray")
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        logging_level="WARNING",
        runtime_env={
            "env_vars": {
                "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
                "OMP_NUM_THREADS": "1",
            }
        },
    )
    yield ray
    ray.shutdown()


def task_outcome(ray, ref) -> str:
    """What a finished Ray task returned, or the error it raised, in one line."""
    try:
        return repr(ray.get(ref, timeout=5))
    except Exception as err:  # any task error is the diagnosis to print
        return f"{type(err).__name__}: {err}"[:2000]


@pytest.mark.cluster
@pytest.mark.slow
def test_trackers_placed_on_ray_lose_nothing(local_ray, tmp_path, phone_export):
    """``wearnav live track --executor ray``'s placement: two Ray tasks (shards 0/2, 1/2) beside a
    real receiver; every session tracked once with every acknowledged message."""
    from wearnav.live.trackers import place_on_ray

    db = tmp_path / "live.db"
    with LiveServer(db, "--no-track") as srv:
        # Generous bounds (the wait ends as soon as every session is tracked): under the suite's
        # other worker on 2 cores, the two Ray trackers took 234 s beside two training runs (45 s alone).
        refs = place_on_ray(db, 2, max_s=420.0)
        try:
            acked = push_sessions(f"{srv.url}/push", phone_export)
            states = wait_for_states(db, acked, timeout_s=360.0)
            ended, _ = local_ray.wait(refs, num_returns=len(refs), timeout=0)
            ended_why = [task_outcome(local_ray, ref) for ref in ended]  # a tracker that stopped early says why
        finally:
            for ref in refs:
                local_ray.cancel(ref, force=True)
    n = len(replay.build(phone_export).messages)
    assert set(states) == set(SESSIONS), f"tracked {sorted(states)}; trackers ended early: {ended_why}"
    shards = arrival_shards(db, 2)
    for sid in SESSIONS:
        assert states[sid]["tracker"] == f"{shards[sid]}/2"
        assert states[sid]["tracked_messages"] == n and states[sid]["path"]


def test_a_state_is_made_again_only_when_its_tracker_changed_or_a_second_passed(tmp_path, monkeypatch):
    """``TrackerProcess.write_states`` makes a session's state (its devices, JSON) again when its
    tracker's state changed, or every ``DEVICES_EVERY_S`` while messages arrive (issue 61: four
    times a second for every session was 9 % of a tracker process)."""
    from wearnav.live import trackers
    from wearnav.live.buffer import SessionBuffer

    class StandIn:  # a tracker without begin/finish: its state is what the test sets
        def __init__(self):
            self.st = {"path": []}

        def update(self, buf, final=False):
            return True

        def state(self):
            return self.st

    proc = trackers.TrackerProcess(tmp_path / "s.db", StandIn)
    proc.crowd.stop()
    buf = proc.buffers["a"] = SessionBuffer("a", "ios", False)
    proc.crowd.poke("a", buf)
    proc.crowd.tick()
    made: list[str] = []
    devices = SessionBuffer.devices
    monkeypatch.setattr(SessionBuffer, "devices", lambda self: made.append(self.session_id) or devices(self))
    clock = [100.0]
    monkeypatch.setattr(trackers.time, "monotonic", lambda: clock[0])
    assert proc.write_states() == 1 and len(made) == 1
    assert proc.write_states() == 0 and len(made) == 1  # nothing changed: not made again
    buf.messages += 1  # a message arrived, the tracker's state unchanged: made again a second later
    clock[0] += 0.5
    assert proc.write_states() == 0 and len(made) == 1
    clock[0] += trackers.DEVICES_EVERY_S
    assert proc.write_states() == 1 and len(made) == 2
    proc.crowd.sessions["a"].tracker.st = {"path": [[1.0, 2.0]]}  # the tracker changed: made at once
    assert proc.write_states() == 1 and len(made) == 3
    assert proc.store.state("a")["path"] == [[1.0, 2.0]]
