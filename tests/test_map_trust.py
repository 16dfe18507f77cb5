"""A floor plan that never misleads (issue 57): the filter's verdict on plans that fit and plans that do
not, the fallback `track` makes, the referee that bounds the map-aware path by the odometry's drift."""

import numpy as np
import pytest
from shapely import affinity
from shapely.geometry import LineString

from conftest import make_stream
from test_plans import l_walk
from wearnav.fuse.mapcheck import DOUBTFUL, FITS, NO_FIT, check_map_path, diagnostics
from wearnav.fuse.particles import MapConfig, map_filter
from wearnav.plans import Walkable, plan_from_geometry
from wearnav.recording import Recording
from wearnav.track.maps import map_path

L_LINE = [(0, 1), (39, 1), (39, 40)]  # the L of tests/test_plans.py: 2-m-wide corridors


def l_geom():
    return LineString(L_LINE).buffer(1.0, cap_style="flat", join_style="mitre")


WRONG_PLANS = {
    "shifted north by a corridor's width": affinity.translate(l_geom(), 0, 2.5),
    "shifted south-east by a corridor's width": affinity.translate(l_geom(), 3, -2.5),
    "corridors elsewhere: turned 90° about the start": affinity.rotate(l_geom(), 90, origin=(1, 1)),
    "corridors elsewhere: the corner 19 m early": LineString([(0, 1), (20, 1), (20, 40)]).buffer(
        1.0, cap_style="flat", join_style="mitre"
    ),
}


def good_odometry(seed=0):
    """A walk whose odometry is nearly right (3° off, full length): the map-less path is good, so a
    plan that is not where the walk is can only make it worse."""
    return l_walk(scale=1.0, heading_err_deg=3.0, seed=seed)


def run(geom, t, true, odo, **cfg):
    w = Walkable.of(plan_from_geometry("p", 0, geom))
    return map_filter(t, odo, {None: w}, true[0], 0.0, cfg=MapConfig(particles=400, **cfg))


def test_a_plan_that_fits_still_helps_and_says_it_fits():
    t, true, odo = l_walk()  # short and turned: the map-less path leaves the corridor
    res = run(l_geom(), t, true, odo)
    verdict = check_map_path(res)
    err_free = np.linalg.norm(odo + true[0] - true, axis=1)
    err_map = np.linalg.norm(res.xy - true, axis=1)
    assert verdict.status == FITS and verdict.reason == "" and verdict.use_map
    assert np.median(err_map) < 0.5 * np.median(err_free)
    d = diagnostics(res)
    assert 0 < d["wall_kill_mean"] < 0.2 and 0 <= d["open_share"] <= 1 and d["lineages_left"] >= 1


@pytest.mark.parametrize("name", list(WRONG_PLANS))
def test_a_plan_that_is_not_where_the_walk_is_is_not_used(name):
    t, true, odo = good_odometry()
    verdict = check_map_path(run(WRONG_PLANS[name], t, true, odo))
    assert verdict.status == NO_FIT and not verdict.use_map
    assert "placed without the plan" in verdict.reason


@pytest.mark.parametrize("name", list(WRONG_PLANS))
def test_track_ends_near_the_mapless_path_with_a_warning_where_the_plan_does_not_fit(name):
    t, true, odo = good_odometry()
    stream = make_stream(int(t.size), 10.0)
    rec = Recording(name="walk", devices={"phone": stream}, plans=[plan_from_geometry("p", 0, WRONG_PLANS[name])])
    start = (float(true[0, 0]), float(true[0, 1]), 0.0)  # east along the corridor
    placed, info, warns = map_path(rec, t, odo, "auto", start)
    mapless = placed_mapless(t, odo, start)
    assert info["used"] is False and info["trust"]["status"] == NO_FIT
    assert any("placed without the plan" in w for w in warns)
    assert placed is not None and placed.method == "start"
    assert np.linalg.norm(placed.xy[-1] - mapless[-1]) < 0.5
    err_track = np.median(np.linalg.norm(placed.xy - true, axis=1))
    assert err_track <= 1.1 * np.median(np.linalg.norm(mapless - true, axis=1))


def placed_mapless(t, odo, start):
    from wearnav.fuse.particles import start_heading_offset

    yaw = start_heading_offset(t, odo, np.radians(start[2]))
    c, s = np.cos(yaw), np.sin(yaw)
    return (odo - odo[0]) @ np.array([[c, s], [-s, c]]) + np.asarray(start[:2])


def test_track_uses_a_plan_that_fits_and_says_so():
    t, true, odo = l_walk()
    rec = Recording(
        name="walk", devices={"phone": make_stream(int(t.size), 10.0)}, plans=[plan_from_geometry("p", 0, l_geom())]
    )
    placed, info, warns = map_path(rec, t, odo, "auto", (float(true[0, 0]), float(true[0, 1]), 0.0))
    assert info["used"] is True and info["trust"]["status"] == FITS and not warns
    assert placed is not None and placed.method == "map"
    assert set(placed.info["diagnostics"]) >= {"wall_kill_mean", "ess_min", "spread_max_m", "heading_turned_deg"}


def test_the_referee_keeps_the_cloud_within_the_odometrys_drift():
    """A plan whose only corridor bends away from the walk: the walls drag the cloud along it; the
    referee holds it within reach of the map-less path, and the verdict doubts it."""
    t, true, odo = good_odometry()
    # a corridor along the walk's first 12 m that then turns 45° south-east and runs on for 60 m
    geom = LineString([(0, 1), (12, 1), (55, -42)]).buffer(1.5, cap_style="flat", join_style="mitre")
    free = run(geom, t, true, odo, referee_rel=None)
    held = run(geom, t, true, odo, referee_rel=0.2, referee_m=3.0)
    mapless = odo - odo[0] + true[0]
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(mapless, axis=0), axis=1))])
    reach = np.maximum(3.0, 0.2 * walked)
    dev_free = np.linalg.norm(free.xy - mapless, axis=1)
    dev_held = np.linalg.norm(held.xy - mapless, axis=1)
    assert np.max(dev_free / reach) > 1.5  # without the referee the walls take the path far away
    assert np.max(dev_held / reach) < 1.2  # with it, the path stays within (about) the reach
    assert held.info["referee_share"] > 0
    assert check_map_path(held, MapConfig(doubt_rel=0.1, doubt_m=2.0)).status in (DOUBTFUL, NO_FIT)


def test_the_filter_records_what_it_saw_per_step():
    t, true, odo = l_walk()
    res = run(l_geom(), t, true, odo)
    s = res.steps
    n = s["t"].size
    assert s["ess"].shape == s["wall_kill"].shape == s["filter_spread_m"].shape == (n,)
    assert s["filter_xy"].shape == s["referee"].shape == (n, 2)
    assert np.all((s["ess"] > 0) & (s["ess"] <= 1)) and np.all((s["wall_kill"] >= 0) & (s["wall_kill"] <= 1))
    assert bool(s["start_walkable"].all())
    assert res.info["heading_turned_deg"] is not None and res.info["wall_kill_mean"] == pytest.approx(
        float(s["wall_kill"][1:].mean()), abs=1e-4
    )


@pytest.mark.slow
def test_leave_one_floor_out_suite_chooses_on_the_other_floors_and_reports_every_floor(monkeypatch, tmp_path):
    """`bench map-lofo`'s folds on written walks (two floors of the same L, the model's odometry
    replaced by l_walk's): every floor scored with settings chosen on the other, wrong plans warned."""
    from wearnav.bench import map_lofo as ml

    monkeypatch.setattr(ml, "GRID", ((0.5, 1.0, 0.1), (1.0, 1.04, 0.2)))
    walks, plans = [], {}
    for floor in ("A", "B"):
        plans[floor] = Walkable.of(plan_from_geometry(floor, 0, l_geom()))
        for seed in range(2):
            t, true, odo = l_walk(seed=seed + (10 if floor == "B" else 0))
            k = np.arange(0, t.size, 50)
            walks.append(ml.Walk(f"{floor}{seed}", floor, t, odo - odo[0], t[k], true[k]))
    yaws = {f: ml.site_yaw([w for w in walks if w.floor != f]) for f in plans}
    grid_rows = ml._grid_errors(walks, plans, yaws, progress=False)
    folds = [ml._jsonable(ml.fold(f, walks, plans, grid_rows)) for f in sorted(plans)]
    summary = ml.summarise(folds)
    assert [f["floor"] for f in summary["floors"]] == ["A", "B"]
    for f in summary["floors"]:
        assert tuple(f["chosen"][k] for k in list(f["chosen"])[:3]) in ml.GRID
        assert f["track"]["median_m"] < f["mapless"]["median_m"]  # the L's plan fits: it helps
    wrong = {r["plan"]: r for r in summary["wrong_plans"]}
    assert set(wrong) == {*ml.MOVES, ml.OTHER_FLOOR}
    assert wrong["turned 90°"]["warned_share"] == 1.0  # an L turned about the start never fits
    text = ml.page(summary, "written walks", len(walks))
    assert "Generated by `wearnav bench map-lofo`" in text and "| A |" in text and "| B |" in text
    ml.plot(summary, tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 1000


def test_a_plan_the_fixes_disagree_with_is_not_used():
    """Where fixes were weighed in, the verdict reads how far the path lies from them in their own 68 %
    radii: a path 3 radii from most fixes is not used (the walls and the fixes disagree), a path
    inside them is; on a real filter run with a fitting plan the figure stays under 1."""
    from wearnav.fuse.config import RADIUS_68
    from wearnav.fuse.particles import MapResult

    tk = np.arange(0.0, 60.0, 0.5)
    path = np.stack([tk, np.zeros_like(tk)], axis=1)
    ft = np.arange(0.0, 60.0, 5.0)
    sigma = np.full(ft.size, 2.0)
    steps = {"t": tk, "wall_kill": np.full(tk.size, 0.05), "path_xy": path, "fix_t": ft, "fix_sigma_m": sigma}

    def verdict(offset_radii):
        fxy = np.stack([ft, np.full(ft.size, offset_radii * RADIUS_68 * 2.0)], axis=1)
        res = MapResult(path, np.ones(tk.size), np.full(tk.size, np.nan), {}, steps | {"fix_xy": fxy})
        return check_map_path(res)

    far, near = verdict(3.0), verdict(0.5)
    assert far.status == NO_FIT and "disagree" in far.reason and far.figures["fixes_off_in_68_radii"] == 3.0
    assert near.status == FITS and near.figures["fixes_off_in_68_radii"] == 0.5
    t, true, odo = good_odometry()
    k = np.arange(0, t.size, 20)
    fixes = (t[k], true[k] + np.random.default_rng(1).normal(0, 1.0, (k.size, 2)), np.full(k.size, 2.5))
    right = map_filter(t, odo, {None: Walkable.of(plan_from_geometry("p", 0, l_geom()))}, None, None, fixes=fixes)
    assert check_map_path(right).figures["fixes_off_in_68_radii"] < 1.0 and check_map_path(right).use_map
