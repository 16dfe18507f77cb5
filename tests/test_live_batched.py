"""Issue 61 §2: a crowd tick's preprocessing for every due session at once, kept equal to the
per-session path it replaces.

The pieces (each against the step it replaces, on a simulated phone-only Sensor Logger session
pushed in 0.2-s messages): the update's Recording from the buffer's arrays
(:func:`wearnav.live.lean.lean_recording` vs the importer's step, ``SessionBuffer.recording``),
the stacked zero-phase low-pass (:func:`wearnav.preprocess.batch.lowpass_many` vs scipy's
``sosfiltfilt``) and the batched alignment (:func:`~wearnav.preprocess.batch.align_many` vs
``align``); and the whole: the same pushes through a :class:`wearnav.live.crowd.Crowd` (batched)
and through one :class:`~wearnav.live.tracker.LiveTracker` per session updated alone the way
before (``batched = False``), the paths compared.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.live import crowd
from wearnav.live.activity import label_windows
from wearnav.live.bench import walker_export
from wearnav.live.buffer import DECIDE_S, RECHECK_S, SessionBuffer
from wearnav.live.lean import lean_recording
from wearnav.live.models import SharedModels, classify_windows, predict_windows
from wearnav.live.replay import build
from wearnav.live.tracker import LiveTracker
from wearnav.preprocess import _lowpass, align
from wearnav.preprocess.batch import align_many, lowpass_many
from wearnav.report.trajectory_page import page_points
from wearnav.track import odometry_preprocess

MESSAGES = 250  # 50 s of pushes: past the quaternion decision (10 s), several fixes and smoother solves
CROWD_MESSAGES = 160  # 32 s of each of three sessions: three smoother solves, the input's warnings (30 s)


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    root = tmp_path_factory.mktemp("live_batched")
    simulated_export(root / "export", seed=5, duration_s=60.0)
    return build(walker_export(root / "export", "phone"), batch_s=0.2, start_ns=time.time_ns())


@pytest.fixture(scope="module")
def models():
    m = SharedModels("cpu")
    m.preload()
    return m


def slices(rp, every: int = 11):
    """(buffer, t_from) as an update asks for them: a growing session, slices of different lengths."""
    buf = SessionBuffer("s", rp.platform, rp.standardised)
    for i, msg in enumerate(rp.messages[:MESSAGES]):
        buf.add(msg["payload"])
        if i >= 60 and i % every == 0:
            covered = buf.covered_until()
            yield buf, max(0.0, covered - 11.0 - (i % 7) * 0.7)


def test_lean_recording_is_the_importers_step(replay):
    buf = SessionBuffer("s", replay.platform, replay.standardised)
    template, compared = None, 0
    for i, msg in enumerate(replay.messages[:MESSAGES]):
        buf.add(msg["payload"])
        if i % 9:
            continue
        if template is None:
            template = buf.recording()
            continue
        t_from = max(0.0, buf.covered_until() - 12.0)
        rec = buf.recording(t_from)  # first: before the decision, it checks the direction lean then reads in
        lean = lean_recording(buf, t_from, template)
        # the quaternion direction is decided after 10-12 s (DECIDE_S + the session's phase ×
        # RECHECK_S): from then on always lean
        if i * 0.2 > DECIDE_S + RECHECK_S + 1.0:
            assert lean is not None
        if lean is None:
            continue
        compared += 1
        a, b = lean.devices["phone"], rec.devices["phone"]
        for name in ("t", "acc", "gyro", "quat"):
            assert getattr(a, name).dtype == getattr(b, name).dtype
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert (lean.fixes is None) == (rec.fixes is None)
        if rec.fixes is not None:
            np.testing.assert_array_equal(lean.fixes.t, rec.fixes.t)
            np.testing.assert_array_equal(lean.fixes.pos, rec.fixes.pos)
        assert (lean.meta["origin_lat"], lean.meta["origin_lon"]) == (rec.meta["origin_lat"], rec.meta["origin_lon"])
    assert compared > 20


def test_motion_span_bounds_every_streams_span(replay):
    """``SessionBuffer.motion_span_s`` (from the raw sample times) is never less than the span of a
    device's stream in the Recording, so a tracker skipping the Recording while it is too short
    to start (``LiveTracker.begin``) skips only what ``_start`` would refuse."""
    buf = SessionBuffer("s", replay.platform, replay.standardised)
    compared = 0
    for i, msg in enumerate(replay.messages[:40]):
        buf.add(msg["payload"])
        if i < 2:
            continue
        span = buf.motion_span_s()
        for s in buf.recording().devices.values():
            assert float(s.t[-1] - s.t[0]) <= span + 1e-9
            compared += 1
    assert compared > 30 and buf.motion_span_s() > 5.0


def test_stacked_lowpass_is_sosfiltfilt_for_ragged_lengths():
    rng = np.random.default_rng(0)
    xs = [rng.normal(size=(n, 6)) for n in (29, 30, 31, 47, 400, 1203)]
    for x, y in zip(xs, lowpass_many(xs, 100.0, 25.0)):
        np.testing.assert_allclose(y, _lowpass(x, 100.0, 25.0), rtol=0, atol=1e-12)
    assert np.abs(lowpass_many(xs, 100.0, 25.0)[-1] - xs[-1]).max() > 0.1  # it filtered


@pytest.mark.parametrize("task", ["odometry", "classify"])
def test_align_many_is_align_on_the_trackers_slices(replay, models, task):
    """The phone model's input (world frame, its common frame and heading frame) and the activity
    classifier's (the device's own axes)."""
    from wearnav import pretrained

    if task == "odometry":
        _, cfg = models.resolve(pretrained.model_path(None, "odometry", ("phone",), True), "odometry")
        pcfg = odometry_preprocess(cfg)
    else:
        pcfg = models.resolve(pretrained.model_path("activity", "classify"), "classify")[1].preprocess_config()
    items = []
    for buf, t_from in slices(replay):
        rec = buf.recording(t_from)
        t = np.arange(int(np.ceil((t_from + 1.0) * pcfg.rate)), int(buf.covered_until() * pcfg.rate)) / pcfg.rate
        items.append((rec, pcfg, t))
    assert len({len(t) for _, _, t in items}) > 3  # ragged
    for (rec, c, t), got in zip(items, align_many(items)):
        want = align(rec, c, t)
        np.testing.assert_array_equal(got.mask, want.mask)
        np.testing.assert_allclose(got.imu, want.imu, rtol=0, atol=1e-5)
        assert (got.yaw is None) == (want.yaw is None) == (not pcfg.heading_frame)
        if want.yaw is not None:  # the phone model's heading frame
            np.testing.assert_allclose(got.yaw, want.yaw, rtol=0, atol=1e-9)
        assert got.meta == want.meta  # the frame's record too (one device: its own frame)


def test_a_due_labels_input_is_the_whole_sessions(replay, models):
    """The update's Recording starts a short context before the odometry's first window not yet final
    (ONE_DEVICE_CONTEXT_S); where an activity label is due it reaches back as far as the label's
    windows and their filters' edges need (:func:`wearnav.live.activity.label_input`), so the
    classifier sees the windows the whole session gives at that time, every label."""
    tr = LiveTracker(models=models)
    buf = SessionBuffer("s", replay.platform, replay.standardised)
    labels = 0
    for msg in replay.messages[:MESSAGES]:
        buf.add(msg["payload"])
        step = tr.begin(buf)
        if step is None:
            continue
        got = tr.activity_windows(step)  # None where no label is due
        if got is not None:
            want = label_windows(tr.classifier, buf.recording(), step.covered)
            assert want is not None
            a, b = got.inputs()["x"].numpy(), want.inputs()["x"].numpy()
            assert a.shape == b.shape and np.abs(a - b).max() < 1e-5
            labels += 1
        vel = predict_windows(tr.model, step.x, step.mask) if step.x is not None else None
        tr.finish(step, vel, None if got is None else (got, classify_windows(tr.classifier[0], [got])[0]))
    assert labels >= 15  # 50 s of pushes, a label every ACTIVITY_EVERY_S


def test_a_batched_crowd_keeps_every_sessions_path_within_a_tenth_of_a_metre(replay, models):
    """Three sessions of one walk, started 0, 7 and 19 pushes apart (so a tick stacks slices of
    different lengths), through one Crowd (lean Recording, one alignment for all) and through a
    tracker per session updated alone the old way: the same path, final and provisional, and the
    same activity label."""
    starts = {"a": 0, "b": 7, "c": 19}
    old = {sid: LiveTracker(models=models) for sid in starts}
    for tr in old.values():
        tr.batched = False
    cr = crowd.Crowd(lambda: LiveTracker(models=models))
    cr.stop()  # ticks run here
    bufs = {sid: tuple(SessionBuffer(sid, replay.platform, replay.standardised) for _ in "nb") for sid in starts}
    worst, checked = 0.0, 0
    for k in range(CROWD_MESSAGES + max(starts.values())):
        for sid, s0 in starts.items():
            i = k - s0
            if 0 <= i < CROWD_MESSAGES:
                for b in bufs[sid]:
                    b.add(replay.messages[i]["payload"])
                cr.poke(sid, bufs[sid][0])
                old[sid].update(bufs[sid][1])
        cr.tick()
        if k % 25 == 0:
            for sid in starts:
                if sid in cr.sessions and cr.sessions[sid].tracker is not None:
                    tr = cr.sessions[sid].tracker
                    t_new, xy_new, sig_new, _ = tr.path()
                    t_old, xy_old, *_ = old[sid].path()
                    # the page's points, settled ones kept between updates: page_points of the whole path
                    if tr.cfg is not None:
                        assert tr._snapshot()["path"] == page_points(t_new, xy_new, sig_new, tr.cfg.rate)
                    assert len(t_new) == len(t_old)
                    if len(t_new):
                        np.testing.assert_allclose(t_new, t_old, rtol=0, atol=1e-9)
                        worst = max(worst, float(np.abs(xy_new - xy_old).max()))
                        checked += 1
    for sess in cr.sessions.values():  # the sessions end: their last windows made final
        sess.last_push -= 2 * crowd.SESSION_END_S
    cr.tick()
    for sid in starts:
        old[sid].update(bufs[sid][1], final=True)
        new = cr.sessions[sid].tracker
        assert new.batched and new.fixes
        assert new.activity is not None and new.activity == old[sid].activity  # the label, its time, confidence
        t_new, xy_new, sig_new, method = new.path()
        t_old, xy_old, _, method_old = old[sid].path()
        assert new._snapshot()["path"] == page_points(t_new, xy_new, sig_new, new.cfg.rate)
        assert method == method_old != "none" and len(t_new) == len(t_old) > 600
        worst = max(worst, float(np.abs(xy_new - xy_old).max()))
        checked += 1
    print(f"batched crowd vs per-session: {checked} paths compared, largest difference {worst:.2e} m")
    assert checked > 20 and worst < 0.1


def test_one_sessions_failing_alignment_fails_only_that_session(replay, models, monkeypatch):
    """The batched alignment raising (one session's input) is retried session by session: that
    session's page says why, the other's path grows."""
    from wearnav.live import tracker as live_tracker

    real = live_tracker.align_many

    def picky(items):
        if any(rec.name == "bad" for rec, _, _ in items):
            raise ValueError("bad input")
        return real(items)

    monkeypatch.setattr(live_tracker, "align_many", picky)
    cr = crowd.Crowd(lambda: LiveTracker(models=models, activity_model=None))
    cr.stop()
    bufs = {sid: SessionBuffer(sid, replay.platform, replay.standardised) for sid in ("good", "bad")}
    for msg in replay.messages[:100]:
        for sid, buf in bufs.items():
            buf.add(msg["payload"])
            cr.poke(sid, buf)
        cr.tick()
    assert len(cr.sessions["good"].tracker.odo.t) > 100 and cr.sessions["good"].error is None
    assert not cr.sessions["bad"].tracker.odo.t and "bad input" in cr.state("bad")["warnings"][-1]


def _checks(replay, sid: str, n_msgs: int = 80) -> tuple[np.ndarray, SessionBuffer]:
    """The session time (``covered_until``) of every whole-session check of ``sid`` over its first
    ``n_msgs`` messages, sliced as the tracker does."""
    at: list[float] = []
    buf = SessionBuffer(sid, replay.platform, replay.standardised)
    full = buf._full
    buf._full = lambda snap: at.append(buf.covered_until()) or full(snap)  # type: ignore[method-assign]
    for msg in replay.messages[:n_msgs]:  # 0.2 s each
        buf.add(msg["payload"])
        if buf.covered_until() > 1.0:
            buf.recording(max(0.0, buf.covered_until() - 4.0))
    return np.asarray(at), buf


def test_the_quaternion_checks_fall_on_each_sessions_own_grid(replay, monkeypatch):
    """Before the decision a whole session whose check could not tell the directions apart (both
    passed: here every check is made to say so) is checked again once per ``RECHECK_S`` of data, on a
    grid offset by the session's phase (slices in between read in the direction last found), and
    the direction is decided at ``DECIDE_S`` + phase × ``RECHECK_S``: sessions that start together
    check in different ticks (issue 61)."""
    from wearnav.importers import sensorlogger_build as slb

    real = slb._check_orientation
    monkeypatch.setattr(slb, "_check_orientation", lambda *a: (*real(*a)[:2], False))
    for sid in ("walker-1", "walker-2", "walker-3"):
        at, buf = _checks(replay, sid)
        assert 0.0 <= buf.phase < 1.0
        decide = DECIDE_S + buf.phase * RECHECK_S
        assert buf._quat_inverted is not None and at[-1] >= decide and at[-1] < decide + 0.5  # decided once, then
        slots = np.floor(at[:-1] / RECHECK_S + buf.phase)
        assert len(at) >= 5 and len(at) <= 7 and np.all(np.diff(slots) >= 1)  # one check per slot of the grid
    phases = sorted(
        SessionBuffer(s, replay.platform, replay.standardised).phase for s in ("walker-1", "walker-2", "walker-3")
    )
    assert phases[-1] - phases[0] > 0.1  # three ids, three places on the grid


def test_a_clear_quaternion_check_is_not_redone_before_the_decision(replay):
    """A walk rotates the phone enough for its first check to tell the two directions apart (one
    passes, the other fails): the next whole-session check is the decision, at ``DECIDE_S`` + phase ×
    ``RECHECK_S`` (issue 61); a slice then reads the quaternions as the whole session's checked
    reading does."""
    at, buf = _checks(replay, "walker-1")
    decide = DECIDE_S + buf.phase * RECHECK_S
    assert len(at) == 2 and at[0] < RECHECK_S + 1.0 and decide <= at[1] < decide + 0.5
    assert buf._provisional is not None and buf._quat_inverted == buf._provisional[1]
    whole = buf.recording()  # the importer's checked reading of the whole session
    part = buf.recording(4.0)
    np.testing.assert_allclose(part.devices["phone"].quat, whole.devices["phone"].quat[-len(part.devices["phone"].t) :])


def test_each_sessions_second_solve_and_label_come_early_by_its_phase(replay, models):
    """The smoother is solved at a session's first update, then ``FUSE_EVERY_S`` of data apart,
    the second solve early by the session's phase × ``FUSE_EVERY_S``; the activity label likewise
    every ``ACTIVITY_EVERY_S`` (issue 61: sessions that start together do not all solve or label in
    one tick)."""
    from wearnav.live.tracker import ACTIVITY_EVERY_S, FUSE_EVERY_S, STEP_S

    for sid in ("walker-1", "walker-2"):
        buf = SessionBuffer(sid, replay.platform, replay.standardised)
        tr = LiveTracker(models=models)
        solved: list[float] = []
        labelled: list[float] = []
        fuse, label = tr._fuse, tr._label
        tr._fuse = lambda fuse=fuse, tr=tr, solved=solved: solved.append(tr._seen_s) or fuse()  # type: ignore[method-assign]
        tr._label = lambda w, p, c, label=label, labelled=labelled: labelled.append(c) or label(w, p, c)  # type: ignore[method-assign]
        for msg in replay.messages[:200]:  # 40 s
            buf.add(msg["payload"])
            tr.update(buf)
        for done, period in ((solved, FUSE_EVERY_S), (labelled, ACTIVITY_EVERY_S)):
            gaps = np.diff(done)  # the covered time of each run's update
            assert len(gaps) >= 2
            early = (1.0 - buf.phase) * period
            assert abs(gaps[0] - early) <= STEP_S + 0.3 and np.all(np.abs(gaps[1:] - period) <= STEP_S + 0.3)
