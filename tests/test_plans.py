"""Floor plans (wearnav.plans), the map-aware particle filter (wearnav.fuse.particles) and
`track --map` end to end (issue 36)."""

import json
import re

import numpy as np
import pytest
from shapely.geometry import LineString

from conftest import run_cli
from wearnav.core import geo
from wearnav.errors import FormatError, ValidationError
from wearnav.fuse.particles import MapConfig, map_filter, start_heading_offset
from wearnav.plans import Walkable, plan_from_geometry, plan_geometry, read_geojson_plan
from wearnav.recording import FloorPlan, Recording

ORIGIN = (49.46, 11.11)


def square(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def l_corridor() -> FloorPlan:
    """An L of 2-m-wide corridors: east along y in [0, 2] to x = 40, then north along x in [38, 40]."""
    geom = LineString([(0, 1), (39, 1), (39, 40)]).buffer(1.0, cap_style="flat", join_style="mitre")
    return plan_from_geometry("L", 0, geom)


def test_walkable_grid_matches_the_polygons():
    plan = FloorPlan("room", 0, [[square(0, 0, 10, 6), square(4, 2, 6, 4)]])  # a pillar in a room
    w = Walkable.of(plan, cell_m=0.1)
    pts = np.array([[1, 1], [5, 3], [9.5, 5.5], [-1, 3], [10.5, 3], [4.5, 1.5]])
    assert w.inside(pts).tolist() == [True, False, True, False, False, True]
    assert w.area_m2 == pytest.approx(56.0)
    assert w.grid.sum() * 0.01 == pytest.approx(56.0, rel=0.03)
    s = w.sample(500, np.random.default_rng(0))
    assert w.inside(s).all()
    assert plan_geometry(plan).area == pytest.approx(56.0)


def write_plan(path, features):
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return path


def lonlat_feature(poly_local, kind, floor=None):
    lat, lon = geo.local_to_latlon(poly_local, *ORIGIN)
    ring = np.stack([lon, lat], axis=1).tolist()
    props = {"kind": kind} | ({} if floor is None else {"floor": floor})
    return {"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": [ring + ring[:1]]}}


def test_user_geojson_plan_is_placed_in_the_local_frame(tmp_path):
    f = write_plan(
        tmp_path / "plan.geojson",
        [lonlat_feature(square(0, 0, 20, 10), "walkable"), lonlat_feature(square(5, 3, 8, 6), "obstacle")],
    )
    (plan,) = read_geojson_plan(f, *ORIGIN)
    geom = plan_geometry(plan)
    assert geom.area == pytest.approx(200 - 9, rel=1e-3)
    assert geom.bounds == pytest.approx((0, 0, 20, 10), abs=0.01)
    w = Walkable.of(plan)
    assert w.inside(np.array([[1, 1], [6.5, 4.5]])).tolist() == [True, False]


@pytest.mark.parametrize(
    "features, msg",
    [
        (
            [
                {
                    "type": "Feature",
                    "properties": {},
                    "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0]]]},
                }
            ],
            "kind",
        ),  # fmt: skip
        ([lonlat_feature(square(0, 0, 5, 5), "obstacle")], "no polygon with 'kind': 'walkable'"),
        ([lonlat_feature(square(0, 0, 5, 5), "walkable", floor="first")], "not an integer"),
    ],
)
def test_bad_user_plans_are_refused(tmp_path, features, msg):
    with pytest.raises(FormatError, match=msg):
        read_geojson_plan(write_plan(tmp_path / "p.geojson", features), *ORIGIN)


def l_walk(scale=0.85, heading_err_deg=12.0, seed=0):
    """The true path along the L's centre line at 1.2 m/s, and an odometry of it that is short and
    turned (the learned models' errors on unseen buildings)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 65, 0.1)
    s = 1.2 * t
    true = np.where(
        s[:, None] < 38, np.stack([1 + s, np.full_like(s, 1)], 1), np.stack([np.full_like(s, 39), 1 + (s - 38)], 1)
    )
    true = np.stack([np.minimum(true[:, 0], 39), np.minimum(true[:, 1], 40)], 1)
    a = np.radians(heading_err_deg)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    odo = (true - true[0]) @ rot.T * scale + 0.05 * np.cumsum(rng.standard_normal(true.shape), axis=0) * 0.1
    return t, true, odo


def test_particle_filter_keeps_a_short_turned_path_in_the_corridor():
    t, true, odo = l_walk()
    w = Walkable.of(l_corridor())
    # the scale as a state (walls_only_scale None) takes the odometry's 15 % shortfall up
    cfg = MapConfig(particles=500, scale_log_sigma=0.2, walls_only_scale=None)
    res = map_filter(t, odo, {None: w}, true[0], 0.0, cfg=cfg)
    free = odo + true[0]
    err_free = np.linalg.norm(free - true, axis=1)
    err_map = np.linalg.norm(res.xy - true, axis=1)
    assert w.inside(free).mean() < 0.5  # the odometry alone leaves the corridor
    assert w.inside(res.xy).mean() > 0.95
    assert np.median(err_map) < 0.5 * np.median(err_free)
    assert err_map[-1] < 3.0 < err_free[-1]
    assert res.info["resamples"] > 0 and 0 < res.info["wall_share"] < 1


def test_with_the_walls_alone_the_scale_is_fixed_and_with_a_fix_it_is_a_state():
    t, true, odo = l_walk(scale=1.0)
    w = Walkable.of(l_corridor())
    cfg = MapConfig(particles=300)
    alone = map_filter(t, odo, {None: w}, true[0], 0.0, cfg=cfg)
    assert alone.info["scale"] == "fixed (walls only)" and alone.info["scale_median"] == cfg.walls_only_scale
    fixes = (t[::100], true[::100], np.full(t[::100].size, 3.0))
    fixed = map_filter(t, odo, {None: w}, true[0], 0.0, fixes=fixes, cfg=cfg)
    assert fixed.info["scale"] == "a state" and fixed.info["fixes_used"] == t[::100].size
    assert np.linalg.norm(alone.xy - true, axis=1).max() < 3.0  # a right-length odometry stays on the walk
    with pytest.raises(ValidationError, match="walls_only_scale"):
        MapConfig(walls_only_scale=0.0)


def test_start_heading_offset_turns_the_first_metres_onto_the_heading():
    t = np.arange(50) * 0.1
    xy = np.stack([np.zeros(50), 0.12 * np.arange(50)], 1)  # north in the odometry's frame
    assert np.degrees(start_heading_offset(t, xy, 0.0)) == pytest.approx(-90.0)


def test_particle_filter_needs_a_start():
    t, true, odo = l_walk()
    with pytest.raises(ValidationError, match="needs a start"):
        map_filter(t, odo, {None: Walkable.of(l_corridor())}, None, None)


def test_ilc2_import_keeps_the_floor_plan(shared_data):
    from wearnav.importers.ilc2 import read

    floor = shared_data / "ilc2_indoor_location" / "site1" / "F2"
    recs = list(read(floor, limit=3))
    inside = []
    for rec in recs:
        assert rec.meta["plan"] == "site1_F2" and rec.plans[0].floor == 1
        inside.append(Walkable.of(rec.plans[0]).inside(rec.truth.pos).mean())
    assert np.mean(inside) > 0.95  # the waypoints were surveyed in the walkable space


def test_track_with_a_users_geojson_plan_stays_in_the_corridor(tmp_path, monkeypatch, capsys):
    """A simulated walk in a corridor drawn around its own route: `track --map FILE --start` keeps the
    path inside, where the odometry alone leaves it."""
    from wearnav.simulate import WalkConfig, simulate_recording

    rec = simulate_recording(WalkConfig(name="corridor", mode="STW", placement="HD", duration_s=90.0), seed=4)
    assert rec.truth is not None
    rec.fixes = None
    rec.devices = {"phone": rec.devices["phone"]}
    rec.meta["origin_lat"], rec.meta["origin_lon"] = ORIGIN
    rec.meta["projection"] = geo.PROJECTION
    pos = rec.truth.pos[:, :2]
    corridor = LineString(pos[::20]).buffer(1.5)
    lat, lon = geo.local_to_latlon(np.asarray(corridor.exterior.coords), *ORIGIN)
    feat = {
        "type": "Feature",
        "properties": {"kind": "walkable"},
        "geometry": {"type": "Polygon", "coordinates": [np.stack([lon, lat], 1).tolist()]},
    }
    plan = write_plan(tmp_path / "corridor.geojson", [feat])
    src = rec.save(tmp_path / "walk.h5")
    k = int(np.searchsorted(np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1)), 3.0))
    head = np.degrees(np.arctan2(*(pos[k + 1] - pos[0])[::-1]))
    start = f"{pos[0, 0]:.3f},{pos[0, 1]:.3f},{head:.2f}"
    code, out, err = run_cli(
        monkeypatch,
        capsys,
        "track",
        str(src),
        "--model",
        "pdr",
        "--out",
        str(tmp_path / "t"),
        "--map",
        str(plan),
        "--start",
        start,
    )
    assert code == 0, err
    summary = json.loads((tmp_path / "t" / "track.json").read_text())
    assert summary["anchoring"]["method"] == "map" and summary["map"]["used"]
    import pandas as pd

    table = pd.read_csv(tmp_path / "t" / "trajectory.csv")
    placed = table[["east", "north"]].to_numpy()
    (walk_plan,) = read_geojson_plan(plan, *ORIGIN)
    w = Walkable.of(walk_plan)
    assert w.inside(placed).mean() > 0.9
    true_at = np.stack([np.interp(table.t, rec.truth.t, pos[:, i]) for i in range(2)], 1)
    assert np.median(np.linalg.norm(placed - true_at, axis=1)) < 3.0
    page = (tmp_path / "t" / "trajectory.html").read_text()
    assert re.search(r'"plan":\s*\[\[\[\[', page)  # the plan's rings are drawn under the path


def test_track_start_is_checked(tmp_path, monkeypatch, capsys):
    code, _, err = run_cli(monkeypatch, capsys, "track", str(tmp_path), "--out", str(tmp_path / "o"), "--start", "1,2")
    assert code == 2 and "X,Y,HEADING_DEG" in err


def test_recording_plans_survive_save(tmp_path, small_recording):
    small_recording.plans = [l_corridor()]
    back = Recording.load(small_recording.save(tmp_path / "r.h5"))
    assert plan_geometry(back.plans[0]).area == pytest.approx(plan_geometry(l_corridor()).area, rel=1e-4)


def test_simulated_walk_carries_its_corridors(tmp_path, monkeypatch, capsys):
    """`simulate --corridor-m`: the walk's own route as corridors; `track --map auto --start` keeps the
    PDR path in them and nearer the truth than the same path without the plan."""
    import pandas as pd

    from wearnav.simulate import WalkConfig, simulate_recording

    rec = simulate_recording(
        WalkConfig(name="sim", mode="STW", placement="HD", phone_hold="texting", duration_s=90.0, corridor_m=3.0),
        seed=0,
    )
    assert rec.truth is not None and rec.meta["plan"] == "sim_corridors"
    w = Walkable.of(rec.plans[0])
    pos = rec.truth.pos[:, :2]
    assert w.inside(pos).mean() > 0.99
    rec.fixes = None
    src = rec.save(tmp_path / "sim.h5")
    k = int(np.searchsorted(np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1)), 3.0))
    head = np.degrees(np.arctan2(*(pos[k + 1] - pos[0])[::-1]))
    start = f"{pos[0, 0]:.3f},{pos[0, 1]:.3f},{head:.2f}"
    errs = {}
    for plan in ("auto", "none"):
        out = tmp_path / plan
        code, _, err = run_cli(monkeypatch, capsys, "track", str(src), "--model", "pdr", "--out", str(out), "--map", plan, "--start", start)  # fmt: skip
        assert code == 0, err
        table = pd.read_csv(out / "trajectory.csv")
        true_at = np.stack([np.interp(table.t, rec.truth.t, pos[:, i]) for i in range(2)], 1)
        if plan == "auto":
            placed = table[["east", "north"]].to_numpy()
            assert w.inside(placed).mean() > 0.9
        else:  # no plan, no fixes: the odometry placed by the start alone (issue 56 §4)
            summary = json.loads((out / "track.json").read_text())
            assert summary["map"]["plans"] == [] and summary["anchoring"]["method"] == "start"
            xy = table[["x", "y"]].to_numpy()
            from wearnav.fuse.particles import start_heading_offset

            a = start_heading_offset(table.t.to_numpy(), xy, np.radians(head))
            turned = (xy - xy[0]) @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + pos[0]
            placed = table[["east", "north"]].to_numpy()
            assert np.abs(placed - turned).max() < 1e-3  # the odometry turned and moved to the start
        errs[plan] = float(np.median(np.linalg.norm(placed - true_at, axis=1)))
    assert errs["auto"] < 0.5 * errs["none"]  # measured: 0.62 against 3.60 m


def test_the_path_changes_plan_where_the_floor_changes():
    """Floor 0: a corridor east to a stair hall; floor 1: the stair hall and a corridor north. The walker
    goes east, changes floor in the hall, then north; the odometry is turned by 12°. With the floor over
    time given (as the barometer gives it), each part is kept in its own floor's corridor."""
    f0 = FloorPlan("F0", 0, [[square(0, 0, 20, 2)], [square(18, 0, 24, 6)]])
    f1 = FloorPlan("F1", 1, [[square(18, 0, 24, 6)], [square(19, 6, 21, 40)]])
    t = np.arange(0, 60, 0.1)
    east = np.stack([1 + 1.0 * t, np.full_like(t, 1.0)], 1)
    north = np.stack([np.full_like(t, 20.0), 1 + 1.0 * (t - 19)], 1)
    true = np.where((t < 19)[:, None], east, north)
    a = np.radians(12.0)
    odo = (true - true[0]) @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    grids = {0: Walkable.of(f0), 1: Walkable.of(f1)}
    res = map_filter(
        t,
        odo,
        grids,
        true[0],
        0.0,
        floor_at=lambda ts: np.where(np.asarray(ts) < 20, 0.0, 1.0),
        cfg=MapConfig(particles=500),
    )
    assert res.floor[0] == 0 and res.floor[-1] == 1
    upper = t >= 21
    assert grids[1].inside(res.xy[upper]).mean() > 0.95
    assert np.median(np.linalg.norm(res.xy - true, axis=1)) < 1.5
    assert np.linalg.norm(res.xy[-1] - true[-1]) < 0.5 * np.linalg.norm(odo[-1] + true[0] - true[-1])
