"""wearnav.fuse: the smoother recovers a walk's heading offset and scale from noisy fixes with
outliers, and says what it did on degenerate inputs."""

import numpy as np
import pytest

from wearnav import fuse
from wearnav.errors import ValidationError
from wearnav.fuse import live as fuse_live
from wearnav.recording import ANDROID_ENU_FRAME


def walk(duration_s=600.0, seed=0):
    """A 1.2 m/s walk along a rectangle-ish loop with turns: times (N,), truth (N, 2) m."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 0.5)
    heading = np.cumsum(np.where(rng.random(t.size) < 0.01, rng.choice([-1, 1], t.size) * np.pi / 2, 0.0))
    heading += 0.05 * np.sin(0.05 * t)
    v = 1.2 * np.stack([np.cos(heading), np.sin(heading)], 1)
    truth = np.concatenate([[[0.0, 0.0]], np.cumsum(v[:-1] * 0.5, axis=0)]) + [100.0, -50.0]
    return t, truth


def odometry_of(truth, scale=0.8, yaw_deg=30.0):
    """The truth seen by an odometry that is short by ``scale`` and turned by ``yaw_deg``, from (0, 0)."""
    yaw = np.radians(yaw_deg)
    r = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    return scale * (truth - truth[0]) @ r.T


def fixes_of(t, truth, sigma_m=3.0, outliers=0.1, seed=1):
    rng = np.random.default_rng(seed)
    ft = t[::2] + 0.3
    ft = ft[ft <= t[-1]]
    z = np.stack([np.interp(ft, t, truth[:, k]) for k in range(2)], 1) + rng.normal(0, sigma_m, (ft.size, 2))
    bad = rng.random(ft.size) < outliers
    z[bad] += rng.normal(0, 60.0, (bad.sum(), 2))
    return ft, z, np.full(ft.size, 1.515 * sigma_m), bad


def test_scale_and_offset_recovered_with_outliers():
    t, truth = walk()
    xy = odometry_of(truth)
    ft, z, acc, bad = fixes_of(t, truth)
    res = fuse.smooth(t, xy, ft, z, acc)
    assert res.method == "smooth" and not res.warnings
    # stated tolerances: the true scale of the odometry is 1/0.8, the offset -30°
    assert res.info["scale"] == pytest.approx(1 / 0.8, rel=0.03)
    assert res.info["heading_offset_deg"] == pytest.approx(-30.0, abs=2.0)
    err = np.linalg.norm(res.xy - truth, axis=1)
    assert np.median(err) < 2.0
    # the outliers (60 m σ) are dropped as jumps (issue 18 §5) or down-weighted, and hardly any good fix is
    caught = res.info["fixes_down_weighted"] + res.info["fixes_dropped"].get("jump", 0)
    assert caught >= 0.8 * bad.sum()
    assert caught <= bad.sum() + 0.05 * (~bad).sum()
    assert np.all(np.isfinite(res.sigma_m)) and np.all(res.sigma_m > 0)


def test_smooth_beats_rigid_and_first_fixes_on_a_short_path():
    t, truth = walk()
    xy = odometry_of(truth)
    ft, z, acc, _ = fixes_of(t, truth)
    errs = {a: np.median(np.linalg.norm(fuse.fuse(t, xy, ft, z, acc, a).xy - truth, axis=1)) for a in fuse.ANCHORS}
    assert errs["smooth"] < errs["rigid"] < errs["first-fixes"] + 1e-9


def test_no_fixes_leaves_the_path_and_warns():
    t, truth = walk(120.0)
    xy = odometry_of(truth)
    res = fuse.smooth(t, xy, np.empty(0), np.empty((0, 2)), np.empty(0))
    assert res.method == "none" and "no location fix" in res.warnings[0]
    np.testing.assert_array_equal(res.xy, xy)


def test_fixes_outside_the_span_are_ignored_and_counted():
    t, truth = walk(120.0)
    xy = odometry_of(truth)
    res = fuse.smooth(t, xy, np.array([-50.0, 500.0]), np.zeros((2, 2)), np.ones(2))
    assert res.method == "none" and res.info["fixes_outside_span"] == 2


def test_one_fix_shifts_only():
    t, truth = walk(120.0)
    xy = odometry_of(truth)
    res = fuse.smooth(t, xy, np.array([10.0]), np.array([[5.0, 7.0]]), np.array([3.0]))
    assert res.warnings and "heading unknown" in res.warnings[0]
    np.testing.assert_allclose([np.interp(10.0, t, res.xy[:, k]) for k in range(2)], [5.0, 7.0], atol=1e-9)
    np.testing.assert_allclose(res.xy - res.xy[0], xy - xy[0], atol=1e-9)  # not rotated


def test_identical_fixes_do_not_collapse_the_path():
    t, truth = walk(300.0)
    xy = odometry_of(truth)
    ft = np.arange(0.0, 300.0, 1.0)
    res = fuse.smooth(t, xy, ft, np.tile([3.0, 4.0], (ft.size, 1)), np.full(ft.size, 5.0))
    length = np.sum(np.linalg.norm(np.diff(res.xy, axis=0), axis=1))
    assert length > 0.5 * np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))  # scale held by its prior
    assert res.warnings  # said, not silent
    assert res.info["fixes_repeated"] == ft.size - 1


def test_nan_accuracy_takes_the_median():
    t, truth = walk(300.0)
    xy = odometry_of(truth)
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.0)
    acc[::3] = np.nan
    res = fuse.smooth(t, xy, ft, z, acc)
    assert res.method == "smooth" and res.info["fixes_nan_accuracy"] == int(np.ceil(ft.size / 3))
    assert res.info["scale"] == pytest.approx(1 / 0.8, rel=0.05)
    np.testing.assert_allclose(fuse.fix_sigma_m(np.array([np.nan, 3.03, -1.0])), [2.0, 2.0, 2.0])


def test_fixes_that_all_disagree_fall_back_to_first_fixes():
    t, truth = walk(300.0)
    xy = odometry_of(truth)
    rng = np.random.default_rng(3)
    ft = np.arange(0.0, 300.0, 1.0)
    z = rng.uniform(-500, 500, (ft.size, 2))  # each fix anywhere, claiming 3 m
    res = fuse.smooth(t, xy, ft, z, np.full(ft.size, 3.0))
    assert res.method == "first-fixes"
    assert any("disagree" in w for w in res.warnings)


def test_fixed_lag_agrees_with_batch_and_stays_in_its_window():
    """The fixed-lag smoother (a 120-s window, updated every 20 s on a 10-min walk, an odometry
    random walk and 5 % outlier fixes) ends within 0.5 m median / 1.5 m at the 95th percentile of
    the batch smoother's path, recovers the scale, and never solves more than its window."""
    t, truth = walk(600.0, seed=2)
    rng = np.random.default_rng(3)
    xy = odometry_of(truth) + np.cumsum(rng.normal(0, 0.1 * np.sqrt(0.5), (t.size, 2)), axis=0)
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.05)
    inc = fuse_live.IncrementalFuser(lag_s=120.0, step_s=30.0)
    fi, nodes = 0, []
    for k in range(t.size):
        inc.add_odometry(t[k], xy[k])
        while fi < ft.size and ft[fi] <= t[k]:
            inc.add_fix(ft[fi], *z[fi], acc[fi])
            fi += 1
        if k % 40 == 39 or k == t.size - 1:
            res = inc.result()
            nodes.append(res.info.get("nodes", 0))
    batch = fuse.smooth(t, xy, ft, z, acc)
    gap = np.linalg.norm(res.xy - batch.xy, axis=1)
    assert res.method == "smooth-fixed-lag" and res.xy.shape == xy.shape
    assert np.median(gap) < 0.5 and np.percentile(gap, 95) < 1.5
    assert res.info["scale"] == pytest.approx(1.25, rel=0.03)
    assert res.info["slices_marginalised"] >= 10 and max(nodes) <= 120 + 30 + 2
    with pytest.raises(ValidationError):
        inc.add_odometry(t[0], xy[0])


def test_fixed_lag_before_any_fix_is_the_batch_fallback():
    t, truth = walk(120.0)
    inc = fuse_live.IncrementalFuser(lag_s=60.0, step_s=30.0)
    for k in range(t.size):
        inc.add_odometry(t[k], odometry_of(truth)[k])
    res = inc.result()
    assert res.method == "none" and res.warnings


def test_odometry_walk_sigma_recovers_a_known_random_walk_and_is_read_back(tmp_path):
    """Odometry = truth turned, scaled, shifted, plus a 2-D random walk of 0.3 m/√s per axis,
    scored at truth points every 5 s: the calibration gives 0.3 / 0.8 within 15 % (the walk is in
    the odometry's units, the smoother's in metres after the scale 1/0.8); a run folder's
    calibration file sets the smoother's config, a bad one leaves the defaults."""
    rng = np.random.default_rng(4)
    walks = []
    for k in range(5):
        t, truth = walk(600.0, seed=k)
        rw = np.cumsum(rng.normal(0, 0.3 * np.sqrt(0.5), (t.size, 2)), axis=0)
        walks.append((t, odometry_of(truth) + rw, t[::10], truth[::10]))
    cal = fuse.odometry_walk_sigma(walks)
    assert cal["walks"] == 5 and cal["odometry_walk_m_per_sqrt_s"] == pytest.approx(0.3 / 0.8, rel=0.15)
    assert fuse.odometry_walk_sigma([]) == {"odometry_walk_m_per_sqrt_s": None, "walks": 0}
    (tmp_path / fuse.CALIBRATION_JSON).write_text('{"odometry_walk_m_per_sqrt_s": 0.21}')
    cfg, read = fuse.config_for(tmp_path)
    assert cfg.odometry_walk_m_per_sqrt_s == 0.21 and read["odometry_walk_m_per_sqrt_s"] == 0.21
    (tmp_path / fuse.CALIBRATION_JSON).write_text('{"odometry_walk_m_per_sqrt_s": "x"}')
    assert fuse.config_for(tmp_path) == (fuse.FuseConfig(), None)
    (tmp_path / fuse.CALIBRATION_JSON).write_text('{"odometry_walk_m_per_sqrt_s": 0.21, "sigma_scale": 1.7}')
    assert fuse.config_for(tmp_path)[0] == fuse.FuseConfig(odometry_walk_m_per_sqrt_s=0.21, sigma_scale=1.7)


def test_fix_lag_is_found_on_walks_with_truth_and_read_back(tmp_path):
    """Fixes that show where the walker was 3 s before their time stamp, with 2 m of noise: the
    calibration finds 3 s (to its 0.5-s grid), the error at that lag is below the error at 0, and
    a run folder's calibration sets the smoother's ``fix_lag_s``. Fixes on time give 0."""
    late, on_time = [], []
    for k in range(4):
        t, truth = walk(300.0, seed=k)
        ft = t[::2]
        late_z = np.stack([np.interp(ft - 3.0, t, truth[:, j]) for j in range(2)], 1)
        noise = np.random.default_rng(k).normal(0, 2.0, late_z.shape)
        late.append((ft, late_z + noise, t[::10], truth[::10]))
        on_time.append((ft, truth[::2] + noise, t[::10], truth[::10]))
    cal = fuse.fix_lag_of(late)
    assert cal["fix_lag_s"] == pytest.approx(3.0, abs=0.5) and cal["fix_lag_walks"] == 4
    assert cal["fix_median_m_at_lag"] < cal["fix_median_m_at_0"]
    assert fuse.fix_lag_of(on_time)["fix_lag_s"] == pytest.approx(0.0, abs=0.5)
    assert fuse.fix_lag_of([])["fix_lag_s"] is None
    (tmp_path / fuse.CALIBRATION_JSON).write_text('{"odometry_walk_m_per_sqrt_s": 0.21, "fix_lag_s": 3.5}')
    assert fuse.config_for(tmp_path)[0].fix_lag_s == 3.5


def test_sigma_scale_makes_the_68_percent_radius_hold_68_percent():
    """Errors 2 × what σ says (2-D Gaussian): the calibrated scale is 2 within 5 %, and with it the
    68 % radius holds 68 % of them; it scales the σ a smoothed path reports, not the path."""
    rng = np.random.default_rng(7)
    z = np.linalg.norm(rng.normal(0.0, 2.0, (20000, 2)), axis=1)  # error / σ with σ understated 2×
    cal = fuse.sigma_scale_of(np.r_[z, np.nan])
    assert cal["sigma_scale"] == pytest.approx(2.0, rel=0.05) and cal["sigma_points"] == z.size
    assert np.mean(z < fuse.RADIUS_68 * cal["sigma_scale"]) == pytest.approx(0.68, abs=0.02)
    assert fuse.sigma_scale_of([]) == {"sigma_scale": None, "sigma_points": 0}
    t, truth = walk(300.0)
    ft, fz, acc, _ = fixes_of(t, truth, outliers=0.0)
    one = fuse.smooth(t, odometry_of(truth), ft, fz, acc)
    two = fuse.smooth(t, odometry_of(truth), ft, fz, acc, fuse.FuseConfig(sigma_scale=2.0))
    np.testing.assert_array_equal(one.xy, two.xy)
    np.testing.assert_allclose(two.sigma_m, 2.0 * one.sigma_m)
    with pytest.raises(ValidationError, match="sigma_scale"):
        fuse.FuseConfig(sigma_scale=0.0)


def test_bias_share_moves_the_fix_error_into_the_bias():
    """bias_share: the bias prior's σ is √share · the fixes' median σ (so it follows the reported
    accuracy), and on fixes whose error is what the share models (1 Hz, 3 m per axis, correlated
    over 20 s, reported right) the scale is recovered; a share of 1 (no white error) is refused."""
    t, truth = walk(300.0)
    rng = np.random.default_rng(5)
    ft = np.arange(0.3, t[-1], 1.0)
    b, a = np.zeros((ft.size, 2)), np.exp(-1.0 / 20.0)
    for k in range(1, ft.size):
        b[k] = a * b[k - 1] + np.sqrt(1 - a * a) * 3.0 * rng.normal(size=2)
    z = np.stack([np.interp(ft, t, truth[:, j]) for j in range(2)], 1) + b
    xy = odometry_of(truth)
    for acc in (4.5, 45.0):
        res = fuse.smooth(t, xy, ft, z, np.full(ft.size, acc), fuse.FuseConfig(**fuse.MEASURED_FIX_BIAS))
        assert res.method == "smooth", res.warnings
        assert res.info["fix_bias_sigma_m"] == pytest.approx(np.sqrt(0.9) * acc / fuse.RADIUS_68)
        if acc < 10:  # fixes reported 10× too wide say little about the scale
            assert res.info["scale"] == pytest.approx(
                1.25, rel=0.05
            )  # correlated fixes tell less: the ±5 % prior pulls
    assert fuse.smooth(t, xy, ft, z, np.full(ft.size, 4.5)).info["fix_bias_sigma_m"] == fuse.FuseConfig().bias_sigma_m
    with pytest.raises(ValidationError):
        fuse.FuseConfig(bias_share=1.0)


def cached_start(t, truth):
    """Clean 1-Hz fixes, and the same with a cached first fix (400 m away, claiming 5 m) and a wide
    second one (1500 m, 700 m off) put before them, as a phone's first fixes often are."""
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.0)
    bad_t = np.concatenate([ft[0] - np.array([0.2, 0.1]), ft])
    bad_z = np.concatenate([z[:1] + [[400.0, -60.0], [500.0, 500.0]], z])
    bad_acc = np.concatenate([[5.0, 1500.0], acc])
    return (ft, z, acc), (bad_t, bad_z, bad_acc)


@pytest.mark.parametrize("anchor", list(fuse.ANCHORS))
def test_a_cached_and_a_wide_first_fix_do_not_move_any_anchoring(anchor):
    """Issue 18 §5: with a cached first fix and a wide second one, every anchoring gives the path it
    gives without them (to 1 mm: the same fixes reach the fit) and says which fixes it dropped and
    why; the per-fix statuses cover every fix given."""
    t, truth = walk(300.0)
    t = t + 1.0  # the bad fixes fall inside the walk
    xy = odometry_of(truth)
    clean, bad = cached_start(t, truth)
    ref, res = fuse.fuse(t, xy, *clean, anchor), fuse.fuse(t, xy, *bad, anchor)
    assert res.method == ref.method == anchor
    assert np.max(np.linalg.norm(res.xy - ref.xy, axis=1)) < 1e-3
    assert res.info["fixes_dropped_index"] == {"wide": [1], "jump": [0]}
    assert res.info["fixes_dropped"] == {"wide": 1, "jump": 1}
    assert len(res.fixes.status) == len(bad[0]) and list(res.fixes.status[:2]) == ["dropped", "dropped"]
    assert list(res.fixes.reason[:2]) == ["jump", "wide"]
    n = res.info["fix_status"]
    assert n["dropped"] == 2 and sum(n.values()) == len(bad[0])
    assert n["used"] == res.info["fixes_used"]


def test_first_fixes_anchor_on_the_first_minute_of_good_fixes():
    """First-fix anchoring fits the good fixes of the first 60 s after the dropped ones (61 at 1 Hz),
    marks the later ones unused, and lies on the truth (2 m median; the same without the bad fixes)."""
    t, truth = walk(300.0)
    t = t + 1.0
    xy = odometry_of(truth, scale=1.0)
    _, bad = cached_start(t, truth)
    res = fuse.first_fix_anchor(t, xy, *bad)
    assert res.info["fixes_used"] == 61
    assert res.info["fix_status"] == {"used": 61, "down-weighted": 0, "unused": len(bad[0]) - 63, "dropped": 2}
    assert set(res.fixes.reason[res.fixes.status == "unused"]) == {"after the first 60 s of good fixes"}
    assert np.all(res.fixes.weight[res.fixes.status == "used"] == 1.0)
    assert np.median(np.linalg.norm(res.xy - truth, axis=1)) < 2.0


def test_smooth_marks_down_weighted_fixes_with_their_weight():
    """The smoother's per-fix weight is its robust (Cauchy) weight: below DOWNWEIGHT exactly where
    the status says down-weighted, and those are mostly the outliers."""
    t, truth = walk()
    ft, z, acc, bad = fixes_of(t, truth, outliers=0.03)
    res = fuse.smooth(t, odometry_of(truth), ft, z, acc)
    st, w = res.fixes.status, res.fixes.weight
    assert np.array_equal(st == "down-weighted", (w < fuse.DOWNWEIGHT) & res.fixes.kept)
    assert res.info["fixes_down_weighted"] == int(np.sum(st == "down-weighted"))
    assert np.all(w[st == "used"] >= fuse.DOWNWEIGHT) and np.all(w[st == "dropped"] == 0)
    caught = (st != "used") & bad
    assert caught.sum() >= 0.8 * bad.sum() and ((st != "used") & ~bad).sum() <= 0.05 * (~bad).sum()


def test_heading_prior_only_where_the_frame_is_north_referenced(tmp_path):
    """Android's rotation vector (ILC2, IPIN) is east/magnetic north/up: a 0° prior for a path in the
    phone's frame; none for another device's frame, the simulator or an undocumented frame."""
    android = {"quat_frame": ANDROID_ENU_FRAME}
    assert fuse.known_heading_deg(android) == 0.0 and fuse.known_heading_deg(android, None) == 0.0
    assert fuse.known_heading_deg(android, "watch") is None
    assert fuse.known_heading_deg({"quat_frame": "Sensor Logger orientation, ..."}) is None
    assert fuse.known_heading_deg({}) is None
    (tmp_path / fuse.CALIBRATION_JSON).write_text('{"odometry_walk_m_per_sqrt_s": 0.5}')
    cfg, _ = fuse.config_for(tmp_path, android, "phone")
    assert cfg.heading_prior_deg == 0.0 and cfg.odometry_walk_m_per_sqrt_s == 0.5
    assert fuse.config_for(None, {"source": "simulator"})[0] == fuse.FuseConfig()


def test_heading_prior_holds_the_heading_where_the_fixes_turn_the_path():
    """Wide fixes (8 m per axis, as indoors) whose error also turns a 90-s walk by 40° about its
    middle pull the fitted heading off. A prior at the true heading weighs in by its σ: at 15° it
    moves the estimate toward the truth, at 3° it holds it within 15° and the path's error falls."""
    t, truth = walk(90.0, seed=3)
    xy = odometry_of(truth, scale=1.0, yaw_deg=0.0)  # the odometry's frame is east/north: offset 0
    ft, z, acc, _ = fixes_of(t, truth, sigma_m=8.0, outliers=0.0)
    c = truth.mean(axis=0)
    r = np.radians(40.0)
    z = (z - c) @ np.array([[np.cos(r), -np.sin(r)], [np.sin(r), np.cos(r)]]).T + c
    free = fuse.smooth(t, xy, ft, z, acc)
    loose = fuse.smooth(t, xy, ft, z, acc, fuse.FuseConfig(heading_prior_deg=0.0))
    tight = fuse.smooth(t, xy, ft, z, acc, fuse.FuseConfig(heading_prior_deg=0.0, heading_prior_sigma_deg=3.0))
    assert abs(free.info["heading_offset_deg"]) > 25.0
    assert abs(loose.info["heading_offset_deg"]) < abs(free.info["heading_offset_deg"]) - 1.0
    assert abs(tight.info["heading_offset_deg"]) < 15.0  # the drift and heading walk still turn the rest
    err = lambda res: np.median(np.linalg.norm(res.xy - truth, axis=1))
    assert err(tight) < err(loose) < err(free)


def _drifting_odometry(t, truth, walk_m_per_sqrt_s, seed):
    """The truth from (0, 0) with a random-walk position error of the given σ per axis per √s."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, walk_m_per_sqrt_s * np.sqrt(np.diff(t, prepend=t[0]))[:, None], (t.size, 2))
    return truth - truth[0] + np.cumsum(steps, axis=0)


def _gauss_markov(t, sigma, correlation_s, seed):
    """A stationary Gauss–Markov error (2-D) of σ per axis at times ``t``, as the smoother assumes."""
    rng = np.random.default_rng(seed + 100)
    b = np.zeros((t.size, 2))
    b[0] = rng.normal(0.0, sigma, 2)
    for k in range(1, t.size):
        a = np.exp(-(t[k] - t[k - 1]) / correlation_s)
        b[k] = a * b[k - 1] + rng.normal(0.0, sigma * np.sqrt(1 - a * a), 2)
    return b


def test_each_points_sigma_covers_its_error_and_grows_where_fixes_are_missing():
    """Where the walk's noise is what the smoother assumes (odometry random walk, fixes with white
    noise and a slowly varying bias),
    the 68 % radius of each point's σ holds about 68 % of the errors (0.69 over 30 walks; with
    the global unknowns' covariance alone it held 0.95–1.0), and the σ grows in a 3-min stretch
    without fixes: the odometry's own drift counts."""
    cfg = fuse.FuseConfig(odometry_walk_m_per_sqrt_s=0.3, scale_prior_log_sigma=0.05)
    inside, ratio = [], []
    for seed in range(12):
        t, truth = walk(600.0, seed=seed)
        xy = _drifting_odometry(t, truth, 0.3, seed)
        ft, z, acc, _ = fixes_of(t, truth, sigma_m=4.0, outliers=0.0, seed=seed)
        z = z + _gauss_markov(ft, cfg.bias_sigma_m, cfg.bias_correlation_s, seed)
        gap = (ft > 300.0) & (ft < 480.0)
        res = fuse.smooth(t, xy, ft[~gap], z[~gap], acc[~gap], cfg)
        assert np.isfinite(res.sigma_m).all() and (res.sigma_m > 0).all()
        err = np.linalg.norm(res.xy - truth, axis=1)
        inside.append(np.mean(err < fuse.RADIUS_68 * res.sigma_m))
        in_gap = (t > 360.0) & (t < 420.0)
        near = (t > 100.0) & (t < 250.0)
        ratio.append(np.median(res.sigma_m[in_gap]) / np.median(res.sigma_m[near]))
    assert 0.55 < np.mean(inside) < 0.82
    assert min(ratio) > 1.2
