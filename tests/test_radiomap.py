"""The radio map (issue 60 §2–§3) on a tiny synthetic building whose truth is known: the survey
placement between surveyed points, the map's accuracy and calibrated σ on held-out walks, a map of
another site that does not fit, radio positions as location fixes, and the CLI end to end."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np
import pytest

from conftest import make_stream, run_cli
from wearnav.dataset import DatasetWriter
from wearnav.errors import FormatError
from wearnav.fuse import radiobuild, radiofixes, radiofloor, radiomap, radioscans
from wearnav.fuse.survey import positions_between
from wearnav.recording import Fixes, Recording, Trajectory, WifiScans

# 16 access points on two floors of a 40 m × 20 m building; RSSI = -35 - 25 log10(d) - 18 dB per floor
# between, plus 2 dB noise; below -95 dBm a phone does not hear it.
AP_XY = [(x, y) for x in (0.0, 13.0, 26.0, 40.0) for y in (0.0, 20.0)]
APS = {f"02:00:00:00:{f:02x}:{k:02x}": (x, y, f) for f in (0, 1) for k, (x, y) in enumerate(AP_XY)}
SCAN_S = 2.0


def rssi_at(xy: np.ndarray, floor: int, rng, aps=APS) -> tuple[list[str], list[float]]:
    names, values = [], []
    for name, (x, y, f) in aps.items():
        d = max(float(np.hypot(xy[0] - x, xy[1] - y)), 1.0)
        r = -35 - 25 * np.log10(d) - 18 * abs(f - floor) + 2 * rng.standard_normal()
        if r > -95:
            names.append(name)
            values.append(float(round(r)))
    return names, values


def synthetic_walk(name: str, corners, floor: int, seed: int, aps=APS, fixes=False) -> Recording:
    """A walk at 1.2 m/s along ``corners`` on ``floor``: surveyed points every second (so the straight
    line between them is the truth), a scan every 2 s, a phone IMU standing still (the survey's PDR
    then barely moves and the straight line is used)."""
    rng = np.random.default_rng(seed)
    corners = np.asarray(corners, np.float64)
    seg = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    s_at = np.concatenate([[0], np.cumsum(seg)])
    duration = s_at[-1] / 1.2
    t_truth = np.arange(0.0, duration, 1.0)
    pos = np.stack([np.interp(t_truth * 1.2, s_at, corners[:, j]) for j in range(2)], axis=1)
    t, bssid, rssi = [], [], []
    for ts in np.arange(1.0, duration - 1.0, SCAN_S):
        xy = np.array([np.interp(ts * 1.2, s_at, corners[:, j]) for j in range(2)])
        names, values = rssi_at(xy, floor, rng, aps)
        t += [ts] * len(names)
        bssid += names
        rssi += values
    n = len(t)
    wifi = WifiScans(t, bssid, ["site"] * n, np.full(n, 2437.0), rssi, np.array(t) - 0.1)
    truth = Trajectory(t_truth, pos, floor=np.full(t_truth.size, float(floor)))
    fx = Fixes(t_truth[::5], pos[::5] + 3.0, np.full(pos[::5].shape[0], 8.0)) if fixes else None
    stream = make_stream(int(duration * 50), 50.0, seed=seed)
    return Recording(
        name=name, devices={"phone": stream}, truth=truth, wifi=wifi, fixes=fx, meta={"source": "synthetic"}
    )


def survey(n_lines=6):
    """Survey walks: lanes along x at several y on both floors, out and back."""
    walks = []
    for f in (0, 1):
        for k, y in enumerate(np.linspace(1.0, 19.0, n_lines)):
            walks.append(
                synthetic_walk(f"survey_f{f}_{k}", [(1.0, y), (39.0, y), (39.0, 20 - y), (1.0, 20 - y)], f, 10 * f + k)
            )
    return walks


@pytest.fixture(scope="module")
def built():
    return radiobuild.build(survey(), radiomap.RadioMapConfig(cv_folds=4))


# ---- the survey placement ----------------------------------------------------------------------


def test_placement_follows_the_odometry_around_a_corner_the_straight_line_cuts():
    # truth at A (t=0) and C (t=20): the walker went A → B (t=10) → C, an L; the odometry is that L
    # turned by 30° and 20 % short, from (0, 0)
    a, b, c = np.array([0.0, 0.0]), np.array([12.0, 0.0]), np.array([12.0, 12.0])
    t_odo = np.linspace(0, 20, 201)
    true = np.where(t_odo[:, None] <= 10, a + (b - a) * t_odo[:, None] / 10, b + (c - b) * (t_odo[:, None] - 10) / 10)
    rot = np.array([[np.cos(0.5236), -np.sin(0.5236)], [np.sin(0.5236), np.cos(0.5236)]])
    odo = 0.8 * true @ rot.T
    truth = Trajectory([0.0, 20.0], np.stack([a, c]), floor=[0.0, 0.0])
    xy, floor, ok, info = positions_between(truth, t_odo, odo, np.array([5.0, 10.0, 15.0]))
    np.testing.assert_allclose(xy, [[6.0, 0.0], [12.0, 0.0], [12.0, 6.0]], atol=1e-9)
    assert ok.all() and info["segments_odometry"] == 1
    line, _, _, info = positions_between(truth, np.empty(0), np.empty((0, 2)), np.array([10.0]))
    np.testing.assert_allclose(line, [[6.0, 6.0]])  # what a straight line says: 8.5 m off the corner
    assert info["segments_straight"] == 1


def test_placement_leaves_out_floor_changes_long_gaps_and_outside_times():
    truth = Trajectory([0.0, 10.0, 20.0, 400.0], [[0, 0], [10, 0], [10, 10], [0, 10]], floor=[0, 0, 1, 1])
    xy, floor, ok, info = positions_between(
        truth, np.empty(0), np.empty((0, 2)), np.array([-1.0, 5.0, 15.0, 100.0, 401.0])
    )
    np.testing.assert_array_equal(ok, [False, True, False, False, False])
    np.testing.assert_allclose(xy[1], [5.0, 0.0])
    assert floor[1] == 0 and info["segments_not_placed"] == 2


# ---- the map -------------------------------------------------------------------------------------


def test_map_places_held_out_walks_of_a_known_building(built):
    card = built.card
    assert card["scans"] > 200 and len(card["access_points"]) == len(APS)
    assert card["validation"]["floor_right"] >= 0.95
    errors, right, inside = [], [], []
    for f in (0, 1):  # diagonal walks, never surveyed
        rec = synthetic_walk(f"test_f{f}", [(2.0, 2.0), (38.0, 18.0), (20.0, 10.0)], f, 99 + f)
        pos = built.locate(rec.wifi)
        assert len(pos) == pos.info["scans"] > 10
        true = np.stack([np.interp(pos.t, rec.truth.t, rec.truth.pos[:, j]) for j in range(2)], axis=1)
        err = np.linalg.norm(pos.xy - true, axis=1)
        errors.append(err)
        right.append(pos.floor == f)
        inside.append(err <= pos.accuracy_m)
    err = np.concatenate(errors)
    assert np.median(err) < 2.5 and np.percentile(err, 95) < 6.0
    assert np.mean(np.concatenate(right)) >= 0.95
    assert 0.45 <= np.mean(np.concatenate(inside)) <= 0.9  # σ calibrated to 68 % on held-out survey walks


def test_map_round_trips_through_its_folder(built, tmp_path):
    folder = built.save(tmp_path / "map")
    assert {p.name for p in folder.iterdir()} == {"radiomap.npz", "card.json", "README.md"}
    back = radiomap.RadioMap.load(folder)
    rec = synthetic_walk("probe", [(5.0, 5.0), (30.0, 15.0)], 1, 7)
    a, b = built.locate(rec.wifi), back.locate(rec.wifi)
    np.testing.assert_allclose(a.xy, b.xy)
    np.testing.assert_allclose(a.sigma_m, b.sigma_m)
    assert "access points" in (folder / "README.md").read_text()
    (tmp_path / "bad").mkdir()
    with pytest.raises(FormatError, match="not a radio map folder"):
        radiomap.RadioMap.load(tmp_path / "bad")


def test_a_map_of_another_site_does_not_fit(built):
    other = {name.replace("02:", "0a:", 1): v for name, v in APS.items()}
    rec = synthetic_walk("elsewhere", [(2.0, 2.0), (30.0, 10.0)], 0, 5, aps=other, fixes=True)
    assert not built.fits(rec) and len(built.locate(rec.wifi)) == 0
    same, radio, info, warns = radiofixes.with_radio_fixes(rec, built)
    assert same is rec and not radio.any() and info["used"] is False
    assert warns == [f"elsewhere: {radiomap.NO_FIT}"]


def test_radio_positions_join_the_fixes(built):
    rec = synthetic_walk("joined", [(2.0, 2.0), (30.0, 10.0)], 1, 6, fixes=True)
    out, radio, info, warns = radiofixes.with_radio_fixes(rec, built)
    assert not warns and info["used"] and info["positions"] == radio.sum() > 5
    assert len(out.fixes) == len(rec.fixes) + radio.sum() and np.all(np.diff(out.fixes.t) > 0)
    assert np.all(np.isnan(out.fixes.floor[~radio])) and np.all(out.fixes.floor[radio] == 1)
    np.testing.assert_array_equal(out.fixes.t[~radio], rec.fixes.t)  # the phone's fixes unchanged
    bare = radiofixes.with_radio_fixes(synthetic_walk("bare", [(2.0, 2.0), (30.0, 10.0)], 0, 8), built)[0]
    assert bare.fixes is not None and np.all(np.isfinite(bare.fixes.accuracy))  # no GNSS: the radio is the start
    # beside the phone's fixes a radio position weighs as RADIO_BESIDE_FIXES of its radius (σ by groups);
    # alone, its radius (σ by the one scale)
    alone = radiofixes.with_radio_fixes(dataclasses.replace(rec, fixes=None), built)[0].fixes
    assert alone is not None
    grouped, scaled = (built.locate(rec.wifi, by_group=g).accuracy_m for g in (True, False))
    assert built.card["sigma_calibration"] and not np.allclose(grouped, scaled)  # the two differ here
    np.testing.assert_allclose(out.fixes.accuracy[radio], radiofixes.RADIO_BESIDE_FIXES * grouped)
    np.testing.assert_allclose(alone.accuracy, scaled)
    floors = radiofloor.floor_at(np.array([0.0, 2.0, 4.0, 6.0]), np.array([0.0, 1.0, 0.0, 0.0]), np.array([2.0, 50.0]))
    np.testing.assert_array_equal(floors, [0.0, 0.0])  # one odd scan does not change floor


# ---- the command line ----------------------------------------------------------------------------


def test_cli_builds_a_map_of_a_tiny_dataset_in_seconds(tmp_path, monkeypatch, capsys):
    data, out = tmp_path / "survey", tmp_path / "map"
    with DatasetWriter(data) as w:
        for rec in survey(n_lines=3):
            w.add(rec)
    start = time.perf_counter()
    code, stdout, err = run_cli(monkeypatch, capsys, "radiomap", "build", data, "--out", out)
    assert code == 0, err
    assert time.perf_counter() - start < 15
    said = json.loads(stdout)
    card = json.loads((out / "card.json").read_text())
    assert said["walks"] == len(card["walks"]) == 6 and said["access_points"] == len(APS)
    assert card["validation"]["n"] > 0 and card["config"]["model"] == "knn"
    code, _, err = run_cli(monkeypatch, capsys, "radiomap", "build", data, "--out", data)
    assert code == 2 and "exists and is not a radio map folder" in err


@pytest.mark.slow  # two `track` runs: ~13 s on two busy cores
def test_track_takes_radio_positions_and_says_when_a_map_does_not_fit(built, tmp_path):
    from wearnav.track import track

    folder = built.save(tmp_path / "map")
    # no GNSS, no start: the radio positions alone place the path
    rec = synthetic_walk("radio_only", [(2.0, 2.0), (38.0, 2.0)], 0, 11)
    rec = Recording(rec.name, rec.devices, wifi=rec.wifi, meta=rec.meta)  # no truth either
    summary = track(rec.save(tmp_path / "radio_only.h5"), "pdr", tmp_path / "t1", radiomap=folder)
    assert summary["radiomap"]["used"] and summary["radiomap"]["positions"] > 10
    # placed (the IMU of this walk stands still, so the smoother may fall back to a rigid fit)
    assert summary["anchoring"]["method"] in ("smooth", "rigid") and summary["path"]["frame"].startswith("placed")
    fixes = (tmp_path / "t1" / "fixes.csv").read_text().splitlines()
    assert fixes[0].endswith("source,floor") and all(",radio map," in row for row in fixes[1:])
    traj = np.genfromtxt(tmp_path / "t1" / "trajectory.csv", delimiter=",", names=True)
    assert set(np.unique(traj["floor"])) == {0.0}
    assert np.median(np.abs(traj["north"] - 2.0)) < 3.0  # on the corridor the walk took
    # a map of another site: a warning, not used, the phone's fixes place the path
    other = {name.replace("02:", "0a:", 1): v for name, v in APS.items()}
    away = synthetic_walk("away", [(2.0, 2.0), (30.0, 10.0)], 0, 12, aps=other, fixes=True)
    with pytest.warns(UserWarning, match="does not fit this recording: no access point in common"):
        summary = track(away.save(tmp_path / "away.h5"), "pdr", tmp_path / "t2", radiomap=folder)
    assert summary["radiomap"] == {
        "map": str(folder),
        "used": False,
        "access_points_in_map": len(APS),
        "why": radiomap.NO_FIT,
    }
    assert summary["anchoring"]["fix_status"]["used"] > 0


def test_the_barometer_follows_the_floor_from_the_start_most_wifi_votes_agree_with():
    from wearnav.fuse.floors import FloorLevels
    from wearnav.recording import Pressure

    # 0-120 s on floor 0, a stair down to -1 at 120-130 s, on -1 until 240 s; 0.4 hPa per floor
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 240.0, 0.5)
    level = np.interp(t, [0, 120, 130, 240], [0.0, 0.0, 0.4, 0.4])
    pressure = Pressure(t, 1000.0 + level + 0.01 * rng.standard_normal(t.size))
    levels = FloorLevels({0: 0.0, -1: 0.4, -2: 0.8}, 0.4)
    t_scan = np.arange(2.0, 240.0, 4.0)
    truth = np.where(t_scan < 125.0, 0.0, -1.0)
    votes = truth.copy()
    wrong = rng.random(t_scan.size) < 0.35  # a third of the Wi-Fi votes name the floor above or below
    votes[wrong] = np.clip(truth[wrong] + rng.choice([-1.0, 1.0], wrong.sum()), -2, 0)
    times = np.arange(0.0, 240.0, 1.0)
    want = np.where(times < 125.0, 0.0, -1.0)
    got, info = radiofloor.floor_over_time(pressure, levels, t_scan, votes, times)
    assert info["start_floor"] == 0 and np.mean(got == want) > 0.97  # wrong only around the stair
    alone, info = radiofloor.floor_over_time(None, levels, t_scan, votes, times)
    assert info["floor_by"] == "Wi-Fi votes" and np.mean(alone == want) < np.mean(got == want)


def test_a_map_keeps_the_floor_levels_of_survey_walks_with_a_barometer(built, tmp_path):
    assert built.floor_levels is None  # the synthetic survey has no barometer: the votes alone
    built.card["floor_levels"] = {"levels_hpa": {"0": 0.0, "1": -0.4}, "step_hpa": 0.4, "fit": {}}
    try:
        again = radiomap.RadioMap.load(built.save(tmp_path / "m"))
        assert again.floor_levels is not None and again.floor_levels.levels_hpa == {0: 0.0, 1: -0.4}
    finally:
        built.card["floor_levels"] = None


def test_phone_fixes_that_disagree_with_the_radio_positions_lose_weight():
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 120.0, 1.0)
    truth = np.stack([1.2 * t, np.zeros_like(t)], axis=1)
    scan_t = np.arange(0.5, 120.0, 3.0)
    sigma = np.full(scan_t.size, 2.0)
    pos = radiomap.RadioPositions(
        scan_t,
        np.stack([1.2 * scan_t, np.zeros_like(scan_t)], axis=1) + 2.0 * rng.standard_normal((scan_t.size, 2)),
        sigma,
        np.zeros(scan_t.size),
        np.full(scan_t.size, 10),
        {},
    )
    claimed = np.full(t.size, 5.0)  # a 68 % radius of 5 m: σ 3.3 m per axis
    honest = truth + (5.0 / radiomap.RADIUS_68) * rng.standard_normal(truth.shape)
    assert radiofixes.phone_accuracy_scale(t, honest, claimed, pos) < 1.2  # honest fixes: barely touched (sampling)
    off = truth + 12.0 * rng.standard_normal(truth.shape)  # ~4x worse than claimed (underground)
    scale = radiofixes.phone_accuracy_scale(t, off, claimed, pos)
    assert scale is not None and 2.5 < scale < 6.0
    # with the grown accuracy, 68 % of the distances fall inside the combined 68 % radius
    k = np.abs(scan_t[None, :] - t[:, None]).argmin(axis=1)
    near = np.abs(scan_t[k] - t) <= radiofixes.PAIR_S
    d = np.linalg.norm(off[near] - pos.xy[k[near]], axis=1)
    combined = radiomap.RADIUS_68 * np.hypot(scale * claimed[near] / radiomap.RADIUS_68, sigma[k[near]])
    assert abs(np.mean(d <= combined) - 0.68) < 0.05
    assert radiofixes.phone_accuracy_scale(t[:3], off[:3], claimed[:3], pos) is None  # too few pairs


def test_sigma_is_calibrated_per_group_of_raw_sigma_not_by_one_scale():
    rng = np.random.default_rng(7)
    raw = rng.uniform(1.0, 20.0, 4000)
    true_sigma = 3.0 + 0.3 * raw  # the errors grow with the raw σ, but far slower than in proportion
    err = true_sigma * np.sqrt(rng.chisquare(2, raw.size))  # a circular Gaussian's radius
    cal = radiomap.sigma_calibration(raw, err)
    assert cal is not None and np.all(np.diff(cal["sigma_m"]) >= 0) and np.all(np.diff(cal["sigma_raw_m"]) > 0)
    sigma = np.interp(raw, cal["sigma_raw_m"], cal["sigma_m"])
    for lo, hi in ((1, 5), (8, 12), (16, 20)):  # 68 % inside the 68 % radius in every part of the range
        k = (raw >= lo) & (raw < hi)
        assert abs(np.mean(err[k] <= radiomap.RADIUS_68 * sigma[k]) - 0.68) < 0.08
    one_scale = np.percentile(err / raw, 68) / radiomap.RADIUS_68 * raw
    k = raw > 16
    assert np.mean(err[k] <= radiomap.RADIUS_68 * one_scale[k]) > 0.85  # one scale overstates the widest
    assert radiomap.sigma_calibration(raw[:20], err[:20]) is None


def test_a_walks_floor_votes_become_one_sequence_that_changes_only_where_the_votes_stay_changed():
    rng = np.random.default_rng(11)
    truth = np.r_[np.zeros(40), np.ones(40)]  # one floor change halfway
    votes = truth.copy()
    stray = rng.choice(80, 12, replace=False)  # 15 % of the votes name the other floor
    votes[stray] = 1 - votes[stray]
    floors = np.array([0.0, 1.0])
    got = radiofloor.floor_sequence(votes, floors, vote_right=0.85, switch=0.01)
    assert np.mean(got == truth) >= 0.95 and np.count_nonzero(np.diff(got)) == 1
    # a survey that never changed floor within a walk still lets a long-held change through
    assert radiofloor.floor_sequence(truth, floors, 0.99, 1e-5).tolist() == truth.tolist()
    assert radiofloor.floor_sequence(np.r_[np.zeros(30), [1.0], np.zeros(30)], floors, 0.99, 1e-5).max() == 0.0


def test_floor_switch_rate_counts_changes_between_a_walks_consecutive_scans():
    scans = radioscans.Scans(
        t=np.array([0.0, 2.0, 4.0, 6.0, 0.0, 2.0]),
        scan=np.arange(6),
        bssid=np.array(["a"] * 6, dtype=object),
        rssi_dbm=np.full(6, -60.0),
        xy=np.zeros((6, 2)),
        floor=np.array([0.0, 0.0, 1.0, 1.0, 2.0, 2.0]),
        walk=np.array(["w1"] * 4 + ["w2"] * 2, dtype=object),
    )
    assert radiofloor.floor_switch_rate(scans.t, scans.walk, scans.floor) == pytest.approx(
        (1 + 1) / (4 + 2)
    )  # 1 change in 4 pairs


def test_a_scan_whose_floor_the_sequence_changes_keeps_the_sigma_asked_for(built):
    """`locate(by_group=False)` (without GNSS: the map's one scale, decision 0050) held for every scan,
    also where the floor sequence overrules a stray vote and the positions are predicted again (that
    second prediction had fallen back to σ by groups)."""
    walk = synthetic_walk("down", [(2.0, 10.0), (38.0, 10.0)], 0, 21).wifi
    stray = synthetic_walk("up", [(18.0, 10.0), (26.0, 10.0)], 1, 22).wifi  # its first scan: heard upstairs
    k = stray.t == stray.t[0]
    t_mid = float(np.median(np.unique(walk.t))) + 0.5
    t = np.concatenate([walk.t[walk.t < t_mid], np.full(k.sum(), t_mid), walk.t[walk.t >= t_mid]])
    pick = [walk.t < t_mid, None, walk.t >= t_mid]

    def joined(a, b):
        return np.concatenate([a[pick[0]], b[k], a[pick[2]]])

    wifi = WifiScans(
        t, *(joined(getattr(walk, c), getattr(stray, c)) for c in ("bssid", "ssid", "freq_mhz", "rssi_dbm"))
    )
    scans = radioscans.scans_of(wifi, built.cfg.stale_s)
    x, _ = radioscans.fingerprints(scans, built.bssids, built.cfg.missing_dbm)
    votes = built.predict(x)[2]
    assert votes.tolist().count(1.0) == 1  # the stray scan votes upstairs ...
    scaled, grouped = built.locate(wifi, by_group=False), built.locate(wifi, by_group=True)
    assert set(scaled.floor.tolist()) == {0.0}  # ... and the sequence puts it downstairs
    np.testing.assert_allclose(scaled.sigma_m, built.predict(x, scaled.floor, by_group=False)[1])
    assert not np.allclose(scaled.sigma_m, grouped.sigma_m)
