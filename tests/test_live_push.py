"""The receiver's parts without a server: push validation (with a hypothesis fuzz of bodies, beside
the importer's property tests), the store's idempotence, and the session buffer against the CSV
importer (same samples in any message order)."""

from __future__ import annotations

import json
import math
import random
import sqlite3
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wearnav.errors import FormatError
from wearnav.importers import sensorlogger
from wearnav.importers.sensorlogger_export import simulated_export, write_export
from wearnav.importers.sensorlogger_map import WEARABLE_COLS as WEARABLE
from wearnav.live import push as push_module
from wearnav.live import replay
from wearnav.live.app import Receiver
from wearnav.live.badinputs import body, catalogue, enc
from wearnav.live.buffer import AUTO, SessionBuffer
from wearnav.live.push import BadPush, parse
from wearnav.live.store import Store
from wearnav.simulate import WalkConfig, simulate_recording

DAY = 86400.0


def check(raw: bytes):
    return parse(raw, time.time_ns(), max_future_s=120, max_age_s=7 * DAY)


BAD = catalogue()  # every refused body, its status and a word of its one-line reason


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_body_is_refused_with_its_status(case):
    raw, status, word = BAD[case]
    with pytest.raises(BadPush) as exc:
        check(raw)
    assert exc.value.status == status
    assert word in exc.value.message


def test_good_body_and_unknown_sensors_pass():
    doc = body()
    doc["payload"] += [
        {"name": "magnetometer", "time": time.time_ns(), "values": {"x": 1, "y": 2, "z": 3}},
        {
            "name": "battery",
            "time": time.time_ns(),
            "values": {"batteryLevel": 0.5, "state": "full", "lowPower": False, "x": None},
        },
        {"name": "future sensor", "time": time.time_ns(), "values": {"list": [1, {"a": "b"}]}},
        {"name": "camera", "time": time.time_ns(), "values": "aGVsbG8="},
    ]
    push = check(enc(doc))
    assert (push.session_id, push.device_id, push.message_id, len(push.payload)) == ("s-1", "phone.A:1", 3, 6)
    buf = SessionBuffer("s-1")
    assert buf.add(push.payload) == 2  # accelerometer + location read, the others ignored
    assert buf.ignored == {"magnetometer": 1, "battery": 1, "future sensor": 1, "camera": 1}
    with pytest.raises(BadPush):  # still finite
        check(enc(doc).replace(b'[1, {"a"', b'[1e999, {"a"'))


json_leaf = (
    st.none() | st.booleans() | st.integers(-(10**400), 10**400) | st.floats(allow_nan=True) | st.text(max_size=8)
)
json_value = st.recursive(
    json_leaf,
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids, max_size=4),
    max_leaves=12,
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    key=st.sampled_from(["messageId", "sessionId", "deviceId", "payload", "name", "time", "values", "x"]),
    value=json_value,
)
def test_fuzz_one_field_replaced(key, value):
    """Any value in any field: accepted as a valid push, or refused with a 4xx BadPush; never
    another exception, and nothing non-finite gets through."""
    doc = body()
    if key in ("name", "time", "values"):
        doc["payload"][0][key] = value
    elif key == "x":
        doc["payload"][0]["values"]["x"] = value
    else:
        doc[key] = value
    raw = json.dumps(doc, allow_nan=True).encode()
    try:
        push = check(raw)
    except BadPush as exc:
        assert 400 <= exc.status < 500  # noqa: PT017  either outcome is valid; the refusal is what the except checks
        return
    for item in push.payload:
        for v in item["values"].values():
            assert not (isinstance(v, float) and not math.isfinite(v))


@settings(max_examples=200, deadline=None)
@given(raw=st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_fuzz_bytes(raw):
    try:
        check(raw)
    except BadPush as exc:
        assert exc.status in (400, 422)  # noqa: PT017  either outcome is valid; the refusal is what the except checks


def test_store_repeat_is_a_no_op(tmp_path):
    store = Store(tmp_path / "live.db")
    assert store.add("s", "d", 0, '{"payload": []}', "ios", False) is True
    assert store.add("s", "d", 0, '{"payload": [1]}', "android", True) is False  # same key: ignored
    assert store.add("s", "d", 1, '{"payload": []}', "android", True) is True
    assert store.add("s", "e", 0, '{"payload": []}', "ios", False) is True  # another device
    assert store.count() == 3
    assert [(d, m, b) for d, m, _t, b in store.messages("s")][0] == ("d", 0, '{"payload": []}')
    assert store.sessions()["s"]["platform"] == "ios"  # the first message's settings
    store.close()
    db = sqlite3.connect(tmp_path / "live.db")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


@pytest.fixture(scope="module")
def export60(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sl") / "walk"
    simulated_export(folder, seed=3, duration_s=40.0)
    return folder


def assert_same(a, b):
    """Same devices, samples and fixes, to float precision (exactly, where nothing was recomputed)."""
    assert sorted(a.devices) == sorted(b.devices)
    for dev in a.devices:
        x, y = a.devices[dev], b.devices[dev]
        assert len(x.t) == len(y.t), dev
        np.testing.assert_allclose(x.t, y.t, rtol=0, atol=1e-9)
        np.testing.assert_allclose(x.acc, y.acc, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(x.gyro, y.gyro, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(x.quat, y.quat, rtol=1e-6, atol=1e-6)
    assert len(a.fixes) == len(b.fixes)
    np.testing.assert_allclose(a.fixes.t, b.fixes.t, atol=1e-9)
    np.testing.assert_allclose(a.fixes.pos, b.fixes.pos, atol=1e-6)
    np.testing.assert_allclose(a.fixes.accuracy, b.fixes.accuracy, atol=1e-9)


def test_buffer_in_any_order_equals_the_importer(export60):
    """Messages in order, shuffled, and with repeats give the importer's Recording; slices keep
    the session's time and local-frame origin."""
    ref = next(sensorlogger.read(export60))
    rp = replay.build(export60, batch_s=0.5)
    msgs = [json.loads(json.dumps({k: v for k, v in m.items() if not k.startswith("_")})) for m in rp.messages]
    in_order, shuffled = (
        SessionBuffer("a", rp.platform, rp.standardised),
        SessionBuffer("b", rp.platform, rp.standardised),
    )
    for m in msgs:
        in_order.add(m["payload"])
    order = list(range(len(msgs)))
    random.Random(0).shuffle(order)
    for i in order:
        shuffled.add(msgs[i]["payload"])
    a, b = in_order.recording(), shuffled.recording()
    assert_same(ref, a)
    assert_same(ref, b)
    assert a.meta["t0_unix_ns"] == b.meta["t0_unix_ns"] == ref.meta["t0_unix_ns"] + rp.shift_ns
    assert shuffled.covered_until() == pytest.approx(min(s.t[-1] for s in ref.devices.values()), abs=1e-6)
    part = shuffled.recording(t_from=20.0)
    for dev, s in part.devices.items():
        k = ref.devices[dev].t >= 20.0
        np.testing.assert_allclose(s.t, ref.devices[dev].t[k], atol=1e-9)
        np.testing.assert_allclose(s.acc, ref.devices[dev].acc[k], atol=1e-6)
        np.testing.assert_allclose(s.quat, ref.devices[dev].quat[k], atol=1e-6)
    k = ref.fixes.t >= 20.0
    np.testing.assert_allclose(part.fixes.pos, ref.fixes.pos[k], atol=1e-6)
    assert set(shuffled.devices()) == {"phone", "watch", "earbuds"}
    assert shuffled.devices()["phone"]["rate_hz"] == pytest.approx(100, rel=0.05)


class SlowTracker:
    """A test double of live-page's LiveTracker (same two methods): records what it saw."""

    def __init__(self):
        self.seen: list[int] = []
        self.busy = threading.Lock()
        self.overlap = False

    def update(self, buf, final: bool = False) -> bool:
        if not self.busy.acquire(blocking=False):
            self.overlap = True
            return False
        try:
            self.seen.append(buf.version)
            time.sleep(0.3)
        finally:
            self.busy.release()
        return True

    def state(self) -> dict:
        return {
            "origin": None,
            "path": [[0.0, 0.0, 0.0, None]],
            "anchor": "none",
            "fixes": [],
            "activity": None,
            "warnings": [],
            "t_s": 0.0,
        }


def test_tracker_runs_after_acks_coalesced(tmp_path):
    """Ten pushes while the tracker is busy make it run once more, not ten times; never two
    updates of one session at once (one crowd thread updates every session); the state merges
    the tracker's with the server's fields."""
    trackers = []

    def factory():
        trackers.append(SlowTracker())
        return trackers[-1]

    rx = Receiver(Store(tmp_path / "live.db"), None, 1 << 20, 1000.0, factory, "ios", False, 120, 7 * DAY)
    for k in range(10):
        assert rx.accept(enc(body(messageId=k)), "ios", False) == "s-1"
        time.sleep(0.01)
    rx.accept(enc(body(sessionId="other")), "ios", False)
    deadline = time.monotonic() + 5

    sessions = rx.crowd.sessions

    def done():  # the last update saw all ten messages and has finished
        t = sessions["s-1"].tracker
        return t is not None and t.seen and t.seen[-1] == 10 and len(sessions["s-1"].latency_s) == len(t.seen)

    while not done() and time.monotonic() < deadline:
        time.sleep(0.05)
    t = sessions["s-1"].tracker
    assert len(trackers) == 2 and sessions["other"].tracker is not None and not t.overlap
    assert t.seen[-1] == 10 and len(t.seen) <= 3  # coalesced: the last update saw every message
    st = rx.state("s-1")
    assert st["session"] == "s-1" and st["messages"] == 10 and st["path"] == [[0.0, 0.0, 0.0, None]]
    assert set(st["devices"]["phone"]) == {"rate_hz", "last_seen_unix_s", "samples", "stopped"}
    assert not st["devices"]["phone"]["stopped"]
    assert len(sessions["s-1"].latency_s) == len(t.seen)


def test_a_tracker_that_cannot_start_is_a_warning_not_a_failed_push(tmp_path):
    def factory():
        raise FileNotFoundError("no shipped model")

    rx = Receiver(Store(tmp_path / "live.db"), None, 1 << 20, 1000.0, factory, "ios", False, 120, 7 * DAY)
    assert rx.accept(enc(body()), "ios", False) == "s-1"
    deadline = time.monotonic() + 5
    while rx.crowd.state("s-1") is None and time.monotonic() < deadline:
        time.sleep(0.05)
    st = rx.state("s-1")
    assert st["messages"] == 1 and st["path"] == []
    assert any("could not start" in w and "no shipped model" in w for w in st["warnings"])


def test_restart_resumes_sessions_from_the_store(tmp_path):
    """A new Receiver on the same store holds every session as it was: messages, settings, and
    when each device was last seen (the store's receive times, not the restart's)."""
    store = Store(tmp_path / "live.db")
    rx = Receiver(store, None, 1 << 20, 1000.0, None, "android", True, 120, 7 * DAY)
    for k in range(3):
        rx.accept(enc(body(messageId=k)), "android", True)
    seen = rx.state("s-1")["devices"]["phone"]["last_seen_unix_s"]
    store.close()
    time.sleep(0.2)
    again = Receiver(Store(tmp_path / "live.db"), None, 1 << 20, 1000.0, None, "ios", False, 120, 7 * DAY)
    st = again.state("s-1")
    assert st["messages"] == 3 and st["devices"]["phone"]["samples"] == 3
    assert abs(st["devices"]["phone"]["last_seen_unix_s"] - seen) < 0.1
    assert (again.buffers["s-1"].platform, again.buffers["s-1"].standardised) == ("android", True)


def test_a_wrong_platform_fails_with_where_to_set_it(export60):
    """The push carries no platform: an iPhone's session read as Android (acceleration sign
    flipped) fails the importer's orientation check, with the way to say otherwise."""
    rp = replay.build(export60, batch_s=1.0)
    buf = SessionBuffer("wrong", "android", False)
    for m in rp.messages:
        buf.add(json.loads(json.dumps(m["payload"])))
    with pytest.raises(FormatError, match=r"read as platform android.*\?platform=android"):
        buf.recording()


def test_sensor_rows_sorted_first_arrival_kept_snapshots_unchanged():
    buf = SessionBuffer("d")
    now = time.time_ns()

    def acc(dt_ns, x):
        return {"name": "accelerometer", "time": now + dt_ns, "values": {"x": x, "y": 0.0, "z": 0.0}}

    buf.add([acc(10, 1.0), acc(20, 2.0)])
    version, snap = buf._snapshot()
    t_before = snap["Accelerometer.csv"][0].copy()
    buf.add([acc(20, 99.0), acc(5, 0.5), acc(30, 3.0)])  # a repeat of t=20 (kept: the first) and an earlier one
    buf.add([acc(30, 98.0)])
    _, snap2 = buf._snapshot()
    t, vals = snap2["Accelerometer.csv"][:2]
    assert (t - now).tolist() == [5, 10, 20, 30] and vals[:, 0].tolist() == [0.5, 1.0, 2.0, 3.0]
    assert snap2["Accelerometer.csv"][4] == 2  # duplicates counted
    np.testing.assert_array_equal(snap["Accelerometer.csv"][0], t_before)  # the old snapshot as it was


@pytest.mark.parametrize("platform,standardised", [("ios", False), ("ios", True), ("android", False)])
def test_platform_not_given_is_decided_from_the_data(tmp_path, platform, standardised):
    """A push URL without ?platform= (Sensor Logger sends none): the session is read in the one
    convention that passes the importer's checks, and gives the importer's Recording of the export
    read with its Metadata.csv."""
    walk = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=20.0), seed=2)
    folder = write_export(
        walk, tmp_path / "x", platform=platform, standardised=standardised, total_acceleration=platform == "android"
    )
    ref = next(sensorlogger.read(folder))
    rp = replay.build(folder, batch_s=1.0)
    buf = SessionBuffer("auto", AUTO)
    for m in rp.messages:
        buf.add(json.loads(json.dumps(m["payload"])))
    got = buf.recording()
    assert not buf.infer and got.meta["platform"] in (
        (platform,) if platform == "ios" and not standardised else ("ios", "android")
    )
    assert_same(ref, got)


def test_covered_until_leaves_out_a_device_that_stopped(export60):
    """Earbuds that stop sending at 10 s (taken out) do not hold the live path back; while every
    device sends, the slowest one bounds it."""
    rp = replay.build(export60, batch_s=1.0)
    buf = SessionBuffer("c", rp.platform, rp.standardised)
    for m in rp.messages[:30]:
        payload = [it for it in m["payload"] if not (it["name"] == "headphone" and m["messageId"] >= 10)]
        buf.add(json.loads(json.dumps(payload)))
        if m["messageId"] == 5:
            ends = {d: s.t[-1] for d, s in buf.recording().devices.items()}
            assert buf.covered_until() == pytest.approx(min(ends.values()), abs=0.02)
    rec = buf.recording()
    assert rec.devices["earbuds"].t[-1] < 11.0 and buf.covered_until() > 28.0


class WaitingTracker(SlowTracker):
    """Changes the path only on every third update (as LiveTracker waits for a second of data)."""

    def update(self, buf, final: bool = False) -> bool:
        self.seen.append(buf.version)
        return len(self.seen) % 3 == 0


def test_update_latency_runs_from_the_oldest_ack_to_the_update_that_changed_the_path(tmp_path):
    rx = Receiver(Store(tmp_path / "live.db"), None, 1 << 20, 1000.0, WaitingTracker, "ios", False, 120, 7 * DAY)
    t0 = time.perf_counter()
    for k in range(3):
        rx.accept(enc(body(messageId=k)), "ios", False)
        deadline = time.monotonic() + 5
        while len(getattr(rx.crowd.sessions["s-1"].tracker, "seen", [])) < k + 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.1)
    lat = rx.crowd.sessions["s-1"].latency_s
    assert len(lat) == 1 and lat[0] >= 0.2 and lat[0] <= time.perf_counter() - t0  # from the first push's ack


# ---- the fast reading (issue 61): it accepts only what the per-sample rules accept, the same samples


def _same_columns(a: dict, b: dict) -> bool:
    if set(a) != set(b):
        return False
    for f in a:
        x, y = a[f], b[f]
        if not (
            np.array_equal(x.t, y.t)
            and x.t.dtype == y.t.dtype == np.int64
            and np.array_equal(x.v, y.v, equal_nan=True)
            and x.seen == y.seen
            and x.text == y.text
        ):
            return False
    return True


def assert_fast_agrees(raw: bytes) -> None:
    """Where the fast reading accepts ``raw``, the per-sample rules accept it too, with the same
    ids, payload and samples; where it does not, parse's answer is the per-sample rules'."""
    now = time.time_ns()
    lo, hi = now - int(7 * DAY * 1e9), now + int(120 * 1e9)
    fast = push_module._fast(raw, lo, hi)
    refused: BadPush | None = None
    try:
        slow = push_module._slow(raw, now, 120, 7 * DAY)
    except BadPush as exc:
        refused = exc
    if refused is not None:
        assert fast is None, f"fast accepted what the rules refuse: {refused.message}"
        with pytest.raises(BadPush) as again:
            parse(raw, now, 120, 7 * DAY)
        assert (again.value.status, again.value.message) == (refused.status, refused.message)
        return
    slow_cols, slow_ignored = push_module.columns_of(slow.payload)
    # stored (it passed the rules), then read again by a tracker process without them: the same
    stored = push_module.parse_stored(raw)
    assert (stored.session_id, stored.device_id, stored.message_id) == (
        slow.session_id,
        slow.device_id,
        slow.message_id,
    )
    assert stored.payload == slow.payload and stored.ignored == slow_ignored
    assert _same_columns(stored.columns, slow_cols)
    if fast is not None:
        assert (fast.session_id, fast.device_id, fast.message_id) == (slow.session_id, slow.device_id, slow.message_id)
        assert fast.payload == slow.payload and fast.ignored == slow_ignored
        assert _same_columns(fast.columns, slow_cols)
    got = parse(raw, now, 120, 7 * DAY)
    assert _same_columns(got.columns, slow_cols)


def test_the_app_s_bodies_take_the_fast_reading(tmp_path):
    """The bodies a phone-only walker and a three-device one push (a simulated walk replayed as the
    app sends it) are all read the fast way, with the per-sample rules' samples."""
    export = tmp_path / "walk"
    simulated_export(export, seed=2, duration_s=20.0)
    rp = replay.build(export, batch_s=0.2)
    assert {it["name"] for m in rp.messages for it in m["payload"]} >= {"orientation", "wrist motion", "location"}
    for m in rp.messages[:40]:
        raw = json.dumps({k: v for k, v in m.items() if k[0] != "_"}).encode()
        now = time.time_ns()
        assert push_module._fast(raw, now - 10**15, now + 10**11) is not None
        assert_fast_agrees(raw)


@pytest.mark.parametrize("case", sorted(BAD))
def test_the_fast_reading_refuses_every_bad_body(case):
    assert_fast_agrees(BAD[case][0])


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    key=st.sampled_from(
        ["messageId", "sessionId", "deviceId", "payload", "name", "time", "values", "x", "qw", "extra", "latitude"]
    ),
    value=json_value,
    item=st.integers(0, 3),
)
def test_fuzz_fast_reading_never_accepts_more(key, value, item):
    doc = body()
    doc["payload"] += [
        {"name": "orientation", "time": time.time_ns(), "values": {"qw": 1.0, "qx": 0.0, "qy": 0.0, "qz": 0.0}},
        {"name": "wrist motion", "time": time.time_ns(), "values": dict.fromkeys(WEARABLE, 0.0) | {"quaternionW": 1}},
    ]
    target = doc["payload"][item]
    if key in ("name", "time", "values"):
        target[key] = value
    elif key in ("x", "qw", "extra", "latitude"):
        if isinstance(target.get("values"), dict):
            target["values"][key] = value
    else:
        doc[key] = value
    assert_fast_agrees(json.dumps(doc, allow_nan=True).encode())


@settings(max_examples=300, deadline=None)
@given(flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), min_size=1, max_size=5))
def test_fuzz_fast_reading_on_mutated_bytes(flips):
    good = bytearray(enc(body()))
    for i, b in flips:
        good[i % len(good)] = b
    assert_fast_agrees(bytes(good))
