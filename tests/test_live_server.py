"""``wearnav live`` as a real uvicorn process on 127.0.0.1 (a free port), real HTTP: bad input and
floods refused with nothing stored, the token, a bounded load with zero lost or duplicated
samples, and SIGKILL mid-replay (every acknowledged message kept, the same final recording)."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time

import httpx
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import live_stores
from test_live_push import BAD, assert_same
from wearnav.dataset import Dataset
from wearnav.importers import import_dataset, sensorlogger
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live import replay
from wearnav.live.badinputs import body, enc
from wearnav.live.export import export_session
from wearnav.live.process import SRC, LiveServer
from wearnav.live.store import open_store

TOKEN = "t0k3n-for-the-test-only-9f3c"

# the store fixtures (SQLite, PostgreSQL) and helpers of tests/live_stores.py
postgres_cluster, store_where = live_stores.postgres_cluster, live_stores.store_where
count, message_ids = live_stores.count, live_stores.message_ids


@pytest.fixture(scope="module")
def export60(tmp_path_factory):
    """A simulated 60-s walk written as an iPhone's Sensor Logger export (phone's four sensors and
    the watch at 100 Hz, earbuds at 25 Hz, fixes at 1 Hz: 526 samples a second)."""
    folder = tmp_path_factory.mktemp("sl") / "walk"
    simulated_export(folder, seed=5, duration_s=60.0)
    return folder


@pytest.fixture(scope="module")
def imported(export60):
    return next(sensorlogger.read(export60))


def stored_rows(db) -> int:
    with sqlite3.connect(db) as c:
        return c.execute("SELECT COUNT(*) FROM messages").fetchone()[0]


def test_bad_inputs_refused_nothing_stored(tmp_path):
    db = tmp_path / "live.db"
    with LiveServer(db, "--no-track", "--max-body", "65536", "--rate-limit", "1000") as srv:
        with httpx.Client(base_url=srv.url) as c:
            for case, (raw, status, _word) in BAD.items():
                r = c.post("/push", content=raw)
                assert r.status_code == status, (case, r.text)
                assert set(r.json()) == {"error"}, case
            big = enc(body(payload=[{"name": "battery", "time": time.time_ns(), "values": {"s": "x" * 70000}}]))
            r = c.post("/push", content=big)
            assert r.status_code == 413 and "limit" in r.json()["error"]
            r = c.post("/push?platform=symbian", content=enc(body()))
            assert r.status_code == 422
            assert c.get("/sessions").json() == []
            assert stored_rows(db) == 0
            stats = c.get("/stats").json()
            assert stats["accepted"] == 0 and sum(stats["refused"].values()) == len(BAD) + 2
            # a good one after all that, and its repeat: stored once
            assert c.post("/push", content=enc(body())).json() == {"stored": True}
            assert c.post("/push", content=enc(body())).json() == {"stored": False}
            assert stored_rows(db) == 1
            n_before = stored_rows(db)

            @settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
            @given(raw=st.binary(max_size=300))
            def fuzz(raw):
                r = c.post("/push", content=raw)
                assert r.status_code in (400, 422), r.text
                assert stored_rows(db) == n_before

            fuzz()


def test_flood_gets_429_and_only_accepted_messages_are_stored(tmp_path):
    db = tmp_path / "live.db"
    with LiveServer(db, "--no-track", "--rate-limit", "5") as srv, httpx.Client(base_url=srv.url) as c:
        codes = [c.post("/push", content=enc(body(messageId=k))).status_code for k in range(40)]
        assert 429 in codes and codes[0] == 200
        assert set(codes) <= {200, 429}
        assert stored_rows(db) == codes.count(200) < 40
        r = c.post("/push", content=enc(body(messageId=99)))
        if r.status_code == 429:
            assert "messages a second" in r.json()["error"]


def test_token_required_and_never_logged(tmp_path):
    """--token on 127.0.0.1 (what a non-local bind makes compulsory): 401 and nothing stored
    without it, accepted as a bearer header or ?token=, absent from everything the server wrote."""
    db = tmp_path / "live.db"
    with LiveServer(db, "--no-track", "--token", TOKEN, token=TOKEN) as srv, httpx.Client(base_url=srv.url) as c:
        raw = enc(body())
        assert c.post("/push", content=raw).status_code == 401
        assert c.post("/push", content=raw, headers={"authorization": "Bearer wrong"}).status_code == 401
        assert c.post("/push?token=" + TOKEN[:-1], content=raw).status_code == 401
        assert c.get("/state").status_code == 401 and c.get("/sessions").status_code == 401
        assert c.get("/").status_code == 401
        assert stored_rows(db) == 0
        assert c.post("/push", content=raw, headers={"authorization": f"Bearer {TOKEN}"}).status_code == 200
        assert c.post("/push?token=" + TOKEN, content=enc(body(messageId=4))).status_code == 200
        assert c.get("/state?token=" + TOKEN).json()["messages"] == 2
        assert c.get("/events").status_code == 401
        with c.stream("GET", "/events?session=s-1&token=" + TOKEN, timeout=10) as r:  # server-sent events
            assert r.headers["content-type"].startswith("text/event-stream")
            first = next(line for line in r.iter_lines() if line.startswith("data: "))
        event = json.loads(first[len("data: ") :])
        assert event["session"] == "s-1" and event["messages"] == 2 and "path" in event
        assert set(event["devices"]) == {"phone"} and event["devices"]["phone"]["stopped"] is False
        page = c.get("/?token=" + TOKEN)
        assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
        for name in ("live.js", "draw.js", "style.css"):  # its own script; the drawing it shares (report/static)
            assert c.get(f"/static/{name}").status_code == 200, name
        sessions = c.get("/sessions?token=" + TOKEN).json()
        assert [x["session"] for x in sessions] == ["s-1"] and sessions[0]["messages"] == 2
        assert stored_rows(db) == 2
    assert TOKEN not in srv.output()
    # --require-token without --token: one is made and printed once (the push URL), then required
    with LiveServer(tmp_path / "b.db", "--no-track", "--require-token") as srv2:
        made = srv2.output().split("?token=")[1].split()[0]
        assert httpx.post(f"{srv2.url}/push", content=enc(body())).status_code == 401
        assert httpx.post(f"{srv2.url}/push?token={made}", content=enc(body())).status_code == 200
        assert srv2.output().count(made) == 2  # push URL and page URL lines, nothing after


@pytest.mark.parametrize("signum, name", [(signal.SIGTERM, "SIGTERM"), (signal.SIGINT, "Ctrl-C")])
def test_a_stopped_server_says_so_neutrally_and_exits_0(tmp_path, signum, name):
    """SIGTERM or Ctrl-C is how a server is stopped: one neutral line naming the sessions kept,
    exit 0, no ``error:`` (README: "wearnav live")."""
    db = tmp_path / "live.db"
    srv = LiveServer(db, "--no-track").start()
    try:
        assert httpx.post(f"{srv.url}/push", content=enc(body())).status_code == 200
    finally:
        code = srv.stop(signum)
    lines = srv.output().strip().splitlines()
    assert code == 0, srv.output()
    assert lines[-1] == f"live: stopped ({name}); 1 session stored in {db} (`wearnav live` resumes them)"
    assert not any(line.startswith("error") for line in lines), srv.output()
    assert stored_rows(db) == 1


@pytest.mark.slow
def test_load_10x_no_sample_lost_or_duplicated(tmp_path, export60, imported):
    """60 s of a walk replayed at 10× (6 s, 0.2-s batches: 50 messages a second), then the stored
    session exported: the same samples and fixes as importing the export directly."""
    db = tmp_path / "live.db"
    rp = replay.build(export60, batch_s=0.2, session_id="load")
    with LiveServer(db, "--no-track") as srv:
        res = replay.send(rp, f"{srv.url}/push", speed=10.0)
        state = httpx.get(f"{srv.url}/state?session=load").json()
    assert res.acknowledged == list(range(len(rp.messages))) and res.retries == 0
    assert state["messages"] == len(rp.messages)
    assert state["devices"]["phone"]["samples"] == len(imported.devices["phone"])
    lat = np.array(res.ack_latency_s)
    print(
        f"\nload: {len(rp.messages)} messages, {rp.samples} samples in {res.wall_s:.1f} s; ack latency ms "
        f"p50 {1e3 * np.percentile(lat, 50):.1f} p95 {1e3 * np.percentile(lat, 95):.1f} "
        f"p99 {1e3 * np.percentile(lat, 99):.1f}; behind schedule at the end {res.late_s:.2f} s"
    )
    assert res.wall_s < 6.0 * 1.5  # kept up with 10× (schedule 6 s)
    # `wearnav live export` writes what `wearnav import sensorlogger` writes, with the same samples
    env = {**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"}
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "wearnav",
            "live",
            "export",
            "load",
            "--store",
            str(db),
            "--out",
            str(tmp_path / "live-ds"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    live, direct = (
        Dataset.open(tmp_path / "live-ds"),
        import_dataset("sensorlogger", export60, tmp_path / "direct", progress=False),
    )
    assert live.names == ["load"] and len(direct) == 1
    cols = ["duration", "devices", "source", "fixes"]
    assert live.manifest[cols].to_dict("records") == direct.manifest[cols].to_dict("records")
    assert_same(direct.load(direct.names[0]), live.load("load"))


@pytest.mark.slow
def test_sigkill_mid_replay_loses_nothing(tmp_path, export60, imported, store_where):
    """SIGKILL the server while a replay runs, restart it on the same store (SQLite, PostgreSQL):
    every message acknowledged before the kill is in the store, the replay's retries fill in the
    rest, the restarted server resumed the session, and the export equals an uninterrupted one's."""
    db = tmp_path / "live.db"
    rp = replay.build(export60, batch_s=0.2, session_id="kill")  # sent without ?platform=: decided from the data
    acked: list[int] = []
    srv = LiveServer(db, "--no-track", store_url=store_where).start()
    out: dict = {}
    sender = threading.Thread(
        target=lambda: out.update(
            res=replay.send(rp, f"{srv.url}/push", speed=10.0, retry_for_s=60.0, on_ack=acked.append, platform=False)
        )
    )
    sender.start()
    try:
        while len(acked) < 60:
            time.sleep(0.01)
        srv.kill()
        acked_at_kill = list(acked)
        assert set(acked_at_kill) <= message_ids(store_where, "kill")
        time.sleep(0.5)
        srv = LiveServer(db, "--no-track", port=srv.port, store_url=store_where).start()
        sender.join(120)
        state = httpx.get(f"{srv.url}/state?session=kill").json()
    finally:
        srv.stop()
    res = out["res"]
    assert res.retries > 0  # it did go down
    assert res.acknowledged == list(range(len(rp.messages)))
    assert state["messages"] == len(rp.messages)  # the restarted buffer holds the whole session
    assert count(store_where) == len(rp.messages)
    store = open_store(store_where)
    try:
        bodies = sorted((json.loads(b) for _d, _m, _r, b in store.messages("kill")), key=lambda b: b["messageId"])
    finally:
        store.close()
    assert [b["messageId"] for b in bodies] == list(range(len(rp.messages)))
    ds = export_session(store_where, "kill", tmp_path / "out")
    assert_same(imported, Dataset.open(ds.root).load("kill"))


def test_a_session_quiet_for_a_while_is_made_final_once(monkeypatch):
    """The crowd makes a tracker's last windows final (``update(final=True)``) once no push has
    come for ``SESSION_END_S``, once only; a push after it tracks on as before."""
    from wearnav.live import crowd as live_crowd

    monkeypatch.setattr(live_crowd, "SESSION_END_S", 0.3)
    calls = []

    class Tracker:
        def update(self, buf, final=False):
            calls.append(final)
            return True

        def state(self):
            return {}

    class Buf:
        session_id = "s"

    crowd = live_crowd.Crowd(Tracker)
    try:
        crowd.poke("s", Buf())
        deadline = time.monotonic() + 5.0
        while calls.count(True) < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert calls[:2] == [False, True]
        time.sleep(1.0)
        assert calls.count(True) == 1  # quiet on: not again
        crowd.poke("s", Buf())
        deadline = time.monotonic() + 5.0
        while calls.count(True) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert calls == [False, True, False, True]
    finally:
        crowd.stop()


def test_several_receivers_share_one_port_and_the_store(tmp_path):
    """`wearnav live --no-track --workers 2`: two processes on one port (SO_REUSEPORT), one store;
    pushes over many connections are all stored once, whichever process took them, and either
    process serves every session (the store's sessions)."""
    db = tmp_path / "live.db"
    srv = LiveServer(db, "--no-track", "--workers", "2").start()
    try:
        time.sleep(1.0)  # the second process binds too
        pids = set()
        for k in range(40):  # a new connection each: the kernel spreads them over the two processes
            with httpx.Client(base_url=srv.url) as c:
                r = c.post("/push", content=enc(body(messageId=k, sessionId=f"s-{k % 4}")))
                assert r.status_code == 200 and r.json() == {"stored": True}
                pids.add(c.get("/stats").json().get("pid"))
        assert count(str(db)) == 40
        with httpx.Client(base_url=srv.url) as c:
            for _ in range(6):  # every session known to whichever process answers
                assert sorted(s["session"] for s in c.get("/sessions").json()) == [f"s-{i}" for i in range(4)]
                assert c.get("/state", params={"session": "s-3"}).status_code == 200
    finally:
        code = srv.stop()
    assert code == 0, srv.output()
    assert len(pids) == 2  # both processes took pushes


def test_a_receiver_that_only_stores_loads_no_torch():
    """The receiver's modules (the command, the app, the session buffer, the push reading and the
    stores) import neither torch nor scikit-learn: a `--no-track` receiver (or one of `--workers`)
    starts in under a second, and a second worker binds its port before the first pushes come.
    (The live Wi-Fi readings once brought the radio map, and with it torch, into the buffer's imports:
    5.8 s instead of 0.8 s.) Nor does a radio map (`--radiomap`, checked where the sessions are stored):
    only building one runs the survey walks' odometry."""
    code = "import sys, wearnav.cli.live, wearnav.live.app; print('torch' in sys.modules, 'sklearn' in sys.modules)"
    code += "\nimport wearnav.fuse.radiomap; print('torch' in sys.modules)"  # --radiomap, loaded where it stores
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": str(SRC)},
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False", "False"]
