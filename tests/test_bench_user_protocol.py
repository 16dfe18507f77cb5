"""wearnav.bench.user_protocol: the path-length ratio, the calibration per site, the per-walk errors and
the walk-paired comparison."""

import numpy as np
import pytest

from wearnav.bench.user_protocol import arc_ratio, score_path


def test_score_path_errors_and_length_ratio():
    t = np.arange(0.0, 10.0, 0.1)
    truth_t = np.array([0.0, 5.0, 9.0])
    truth = np.array([[0.0, 0.0], [5.0, 0.0], [9.0, 0.0]])
    path = np.stack([0.5 * t, np.full_like(t, 1.0)], 1)  # half the speed, 1 m off to the side
    err, ratio = score_path(t, path, truth_t, truth)
    np.testing.assert_allclose(err, [np.hypot(2.5, 1), np.hypot(4.5, 1)])  # from the second point on
    assert abs(ratio - 0.5) < 1e-9


def test_arc_ratio_tells_a_slow_path_from_a_wandering_one():
    """The chord ratio (score_path's) counts a path that zigzags between the surveyed points as
    short; the arc ratio (the path's own length over the truth's polyline) does not, and a path
    that is truly slow is short by both."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.05)
    truth_t = np.array([0.0, 5.0, 10.0])
    truth = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    # at the truth's speed (1 m/s) along a zigzag of ±30° (half a second each way): the arc is the
    # walked distance, the chords between surveyed times cos 30° of it
    heading = np.where(np.floor(t / 0.5) % 2 == 0, np.pi / 6, -np.pi / 6)
    v = np.stack([np.cos(heading), np.sin(heading)], 1)
    zig = np.vstack([[0.0, 0.0], np.cumsum(v[:-1] * 0.05, axis=0)])
    assert abs(arc_ratio(t, zig, truth_t, truth) - 1.0) < 0.01
    assert abs(score_path(t, zig, truth_t, truth)[1] - np.cos(np.pi / 6)) < 0.02
    slow = np.stack([0.8 * t, np.zeros_like(t)], 1)
    assert (
        abs(arc_ratio(t, slow, truth_t, truth) - 0.8) < 1e-9
        and abs(score_path(t, slow, truth_t, truth)[1] - 0.8) < 1e-9
    )
    assert np.isnan(arc_ratio(t, slow, truth_t, np.zeros((3, 2))))  # a truth that does not move


def test_site_calibration_uses_walks_the_model_never_trained_on(tmp_path, monkeypatch):
    """A learned model on its own building: its validation walks; anywhere else (another building,
    PDR): the site's training walks. Stored per site, reused, redone when the walks change."""
    from wearnav.bench import user_protocol

    calls = []

    def fake(run, data, split, speed="model"):
        calls.append((str(data), split))
        return {"odometry_walk_m_per_sqrt_s": 0.5, "walks": 3, "sigma_scale": 1.2, "fix_lag_s": 2.0}

    monkeypatch.setattr(user_protocol, "calibrate", fake)
    site, other = tmp_path / "ipin", tmp_path / "mix"
    run = tmp_path / "run"
    run.mkdir()
    c = user_protocol.site_calibration(run, "main", site, site)
    assert calls == [(str(site), "val")] and c["split"] == "val"
    assert (run / "fuse_calibration_main.json").is_file()
    user_protocol.site_calibration(run, "main", site, site)
    assert len(calls) == 1  # reused
    stored = run / "fuse_calibration_main.json"  # one from before the fixes' lag is redone
    stored.write_text(stored.read_text().replace('"fix_lag_s"', '"lag_before"'))
    user_protocol.site_calibration(run, "main", site, site)
    assert len(calls) == 2
    c = user_protocol.site_calibration(run, "main", site, other)
    assert calls[-1] == (str(site), "train") and "not trained on" in c["method"]
    user_protocol.site_calibration(run, "test", site, None)
    assert calls[-1] == (str(site), "train") and (run / "fuse_calibration_test.json").is_file()


@pytest.mark.slow
def test_user_protocol_keeps_each_walks_errors_and_pairs_the_smoother_by_walk(monkeypatch):
    """Per trace: every anchoring's errors and the raw fixes' at the same surveyed points; the
    concatenated errors are those traces'; the paired rows give the smoother minus each other path."""
    from wearnav import fuse
    from wearnav.bench import user_protocol as up
    from wearnav.simulate.config import WalkConfig
    from wearnav.simulate.walk import simulate_recording

    recs = [
        simulate_recording(WalkConfig(name=f"w{k}", mode="STW", placement="HD", duration_s=60.0), seed=k)
        for k in range(3)
    ]

    def paths(run, data, split, speed="model"):
        for k, rec in enumerate(recs):
            t = rec.truth.t[::10]
            xy = rec.truth.pos[::10, :2] - rec.truth.pos[0, :2]
            c, s = np.cos(0.3 + 0.1 * k), np.sin(0.3 + 0.1 * k)
            drift = np.stack([0.02 * (t - t[0]), np.zeros_like(t)], axis=1)
            yield rec, t, 0.9 * xy @ np.array([[c, -s], [s, c]]).T + drift

    monkeypatch.setattr(up, "_paths", paths)
    r = up.user_protocol("unused", "unused", cfg=fuse.FuseConfig())
    names = [rec.name for rec in recs]
    for a in fuse.ANCHORS:
        assert list(r[a]["by_trace"]) == names
        np.testing.assert_allclose(np.concatenate([r[a]["by_trace"][n] for n in names]), r[a]["errors"])
    np.testing.assert_allclose(r[up.RAW_FIXES]["by_trace"][names[1]], up.fix_point_errors(recs[1]), atol=1e-3)
    # whether each point's error is inside the 68 % radius of the smoother's σ, at the scored points
    inside = r["smooth"]["inside_68"]
    assert len(inside) == len(r["smooth"]["errors"]) and 0.0 < np.mean(inside) <= 1.0
    rows = up.paired_rows({"pdr": r})
    assert [row["smoother minus"] for row in rows] == [
        up.RAW_FIXES,
        up.ANCHOR_LABEL["first-fixes"],
        up.ANCHOR_LABEL["rigid"],
    ]
    smooth = np.concatenate([r["smooth"]["by_trace"][n] for n in names])
    rigid = np.concatenate([r["rigid"]["by_trace"][n] for n in names])
    expect = np.nanpercentile(smooth, 50) - np.nanpercentile(rigid, 50)
    point, low, high = (float(x.strip("[],")) for x in rows[2]["median (m)"].split())
    assert point == pytest.approx(expect, abs=0.006) and low <= point <= high and rows[2]["walks"] == 3


def test_the_page_says_at_what_lag_the_smoother_read_the_fixes():
    from wearnav.bench.real_page import _fix_lag_line

    cal = {
        "fix_lag_s": 3.5,
        "fix_lag_walks": 28,
        "fix_median_m_at_0": 6.26,
        "fix_median_m_at_lag": 5.48,
        "split": "train",
    }
    line = _fix_lag_line({"suitein++": cal, "pdr": cal})[0]
    assert "3.5 s before its time stamp" in line and "28 walks" in line and "6.26 m at 0 s" in line
    assert "`track --fix-lag`" in line
    assert _fix_lag_line({"pdr": {"odometry_walk_m_per_sqrt_s": 0.4}}) == []  # one from before the lag
