"""ILC2 importer on slices of the real traces, plus one-line errors on broken copies."""

from __future__ import annotations

import gzip
import json
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import error_line, run_cli
from wearnav.dataset import Dataset
from wearnav.errors import FormatError, MissingFileError, ValidationError, WearnavWarning
from wearnav.importers import ilc2, import_dataset

F4_TRACE = "site1/F4/path_data_files/5ddb653fc5b77e0006b17906.txt.gz"
B1_FLOOR = "site1/B1"


@pytest.fixture(scope="module")
def ilc2_root(shared_data):
    return shared_data / "ilc2_indoor_location"


@pytest.fixture(scope="module")
def trace_path(ilc2_root):
    return ilc2_root / F4_TRACE


@pytest.fixture(scope="module")
def trace_lines(trace_path):
    with gzip.open(trace_path, "rt", encoding="utf-8") as f:
        return f.read().splitlines()


@pytest.fixture(scope="module")
def rec(trace_path):
    (r,) = list(ilc2.read(trace_path))
    return r


def rows_of(lines, kind):
    return [ln.split("\t") for ln in lines if not ln.startswith("#") and ln.split("\t")[1] == kind]


def write_trace(path, lines):
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ---- real data -------------------------------------------------------------------------------


def test_trace_streams_match_the_file(rec, trace_lines):
    acc_rows = rows_of(trace_lines, "TYPE_ACCELEROMETER")
    s = rec.devices["phone"]
    assert rec.name == "5ddb653fc5b77e0006b17906"
    assert len(s) == len(acc_rows)  # nothing dropped in a clean trace
    np.testing.assert_allclose(s.acc[0], [float(v) for v in acc_rows[0][2:5]], rtol=1e-6)
    assert 49.0 < s.rate < 51.0
    assert s.gyro is not None and s.quat is not None
    np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-5)
    assert 8.5 < np.median(np.linalg.norm(s.acc, axis=1)) < 10.5
    # Clock: relative to the earliest row, absolute start kept in meta.
    t_first_acc_ms = int(acc_rows[0][0])
    assert rec.meta["t0_unix_ms"] + round(s.t[0] * 1000) == t_first_acc_ms
    assert min(s.t[0], rec.truth.t[0]) == 0.0


def test_waypoints_are_the_truth(rec, trace_lines):
    wps = rows_of(trace_lines, "TYPE_WAYPOINT")
    assert len(rec.truth) == len(wps) >= 2
    np.testing.assert_allclose(rec.truth.pos, [[float(w[2]), float(w[3])] for w in wps])
    np.testing.assert_allclose(rec.truth.t * 1000 + rec.meta["t0_unix_ms"], [int(w[0]) for w in wps])
    assert rec.truth.pos.shape[1] == 2
    assert np.all(rec.truth.floor == 3)  # F4 -> 3 (F1 = 0)


def test_meta(rec, ilc2_root):
    m = rec.meta
    assert m["source"] == "ilc2" and "MIT" in m["licence"]
    assert m["site_id"] == "5dd3d7732a57a34356595932" and m["site"] == "site1"
    assert m["floor_name"] == "F4" and m["floor_index"] == 3
    assert m["device"] == "OPPO PBCM10"
    assert m["mode"] == "walk" and m["placement"] == "handheld"
    info = json.loads((ilc2_root / "site1/F4/floor_info.json").read_text())["map_info"]
    assert m["map_size_m"] == [info["width"], info["height"]]
    assert m["dropped_duplicates"] == {} and m["dropped_uncovered"] == 0
    json.dumps(m)


def test_quaternion_is_world_from_device(rec):
    """Gravity ends up on world +z, and the gyro matches the quaternion's body-frame rate."""
    s = rec.devices["phone"]
    rot = Rotation.from_quat(np.column_stack([s.quat[:, 1:], s.quat[:, :1]]))
    acc_world = rot.apply(s.acc).mean(axis=0)
    assert abs(acc_world[2] - 9.8) < 0.5 and np.hypot(*acc_world[:2]) < 0.6
    body_rate = (rot[:-1].inv() * rot[1:]).as_rotvec() / np.diff(s.t)[:, None]
    gyro = 0.5 * (s.gyro[:-1] + s.gyro[1:])
    for k in range(3):
        assert np.corrcoef(body_rate[:, k], gyro[:, k])[0, 1] > 0.6


def test_folder_import_floor_and_limit(ilc2_root, tmp_path):
    ds = import_dataset("ilc2", ilc2_root / B1_FLOOR, tmp_path / "out", limit=3, progress=False)
    assert len(ds) == 3 and len(set(ds.names)) == 3
    assert set(ds.manifest["source"]) == {"ilc2"}
    for name in ds.names:
        r = ds.load(name)
        assert r.meta["floor_index"] == -1 and r.truth is not None and np.all(r.truth.floor == -1)
        assert r.meta["file"].startswith("path_data_files/")
    again = Dataset.open(tmp_path / "out").load(ds.names[0])
    assert again.devices["phone"].quat is not None


def test_find_traces_prefers_the_plain_copy(tmp_path, trace_path):
    folder = tmp_path / "site" / "F1" / "path_data_files"
    folder.mkdir(parents=True)
    (folder / "abc.txt.gz").write_bytes(trace_path.read_bytes())
    (folder / "abc.txt").write_bytes(gzip.decompress(trace_path.read_bytes()))
    (tmp_path / "notes.txt").write_text("not a trace")
    assert ilc2.find_traces(tmp_path) == [folder / "abc.txt"]
    (r,) = list(ilc2.read(tmp_path))
    assert r.name == "abc" and r.meta["floor_name"] == "F4"  # header wins over the folder name


# ---- deliberate handling of timestamps --------------------------------------------------------


def test_duplicated_timestamp_is_dropped_and_counted(tmp_path, trace_lines):
    lines = list(trace_lines)
    i = next(k for k, ln in enumerate(lines) if "\tTYPE_ACCELEROMETER\t" in ln)
    dup = lines[i].split("\t")
    dup[2] = "5.0"  # same time, other value: the first one is kept
    lines.insert(i + 1, "\t".join(dup))
    (r,) = list(ilc2.read(write_trace(tmp_path / "dup.txt", lines)))
    assert r.meta["dropped_duplicates"] == {"TYPE_ACCELEROMETER": 1}
    assert len(r.devices["phone"]) == len(rows_of(trace_lines, "TYPE_ACCELEROMETER"))
    assert r.devices["phone"].acc[0, 0] == pytest.approx(float(lines[i].split("\t")[2]))


def synthetic_trace(n=300, gyro_shift_ms=0, with_w=False):
    """A small trace: phone flat, turning slowly about z; optional gyro clock shift and w column."""
    t0 = 1_600_000_000_000
    lines = [
        f"#\tstartTime:{t0}",
        "#\tSiteID:s\tSiteName:x\tFloorId:f\tFloorName:B2",
        "#\tBrand:Acme\tModel:P1",
        f"{t0}\tTYPE_WAYPOINT\t1.0\t2.0",
    ]
    for k in range(n):
        ts = t0 + 20 + 20 * k
        yaw = 0.002 * k
        lines.append(f"{ts}\tTYPE_ACCELEROMETER\t0.01\t0.02\t9.81\t3")
        lines.append(f"{ts + gyro_shift_ms}\tTYPE_GYROSCOPE\t0.0\t0.0\t0.1\t3")
        rv = [0.0, 0.0, np.sin(yaw / 2)] + ([np.cos(yaw / 2)] if with_w else [])
        lines.append(f"{ts}\tTYPE_ROTATION_VECTOR\t" + "\t".join(f"{v:.9f}" for v in rv) + "\t3")
        if k % 7 == 0:
            lines.append(f"{ts}\tTYPE_WIFI\tssid\t00:11\t-50\t2412\t{ts}")
    lines.append(f"{t0 + 20 * n + 40}\tTYPE_WAYPOINT\t3.0\t4.0")
    lines.append(f"#\tendTime:{t0 + 20 * n + 60}")
    return lines


def test_synthetic_trace_with_w_and_shifted_gyro(tmp_path):
    lines = synthetic_trace(gyro_shift_ms=100, with_w=True)
    (r,) = list(ilc2.read(write_trace(tmp_path / "syn.txt", lines)))
    s = r.devices["phone"]
    # Gyro starts 100 ms after the accelerometer: the first 5 acc samples cannot be covered.
    assert r.meta["dropped_uncovered"] == 5 and len(s) == 295
    np.testing.assert_allclose(s.gyro, np.tile([0, 0, 0.1], (295, 1)), atol=1e-6)
    yaw = 2 * np.arctan2(s.quat[:, 3], s.quat[:, 0])
    np.testing.assert_allclose(yaw, 0.002 * np.arange(5, 300), atol=1e-5)
    assert r.meta["floor_index"] == -2 and r.meta["device"] == "Acme P1"
    np.testing.assert_allclose(r.truth.pos, [[1, 2], [3, 4]])


# ---- one-line errors --------------------------------------------------------------------------


def test_missing_path(tmp_path):
    with pytest.raises(MissingFileError) as e:
        list(ilc2.read(tmp_path / "nope"))
    assert "nope" in error_line(e.value)


def test_wrong_folder(tmp_path):
    (tmp_path / "a.csv").write_text("x,y\n1,2\n")
    with pytest.raises(FormatError, match="no ILC2 traces") as e:
        list(ilc2.read(tmp_path))
    error_line(e.value)


def test_empty_file(tmp_path):
    (tmp_path / "e.txt").write_text("")
    with pytest.raises(FormatError, match="empty file") as e:
        list(ilc2.read(tmp_path / "e.txt"))
    assert "e.txt" in error_line(e.value)


def test_truncated_gz(tmp_path, trace_path):
    data = trace_path.read_bytes()
    bad = tmp_path / "cut.txt.gz"
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match="truncated or corrupt") as e:
        list(ilc2.read(bad))
    assert "cut.txt.gz" in error_line(e.value)


def test_nan_row(tmp_path, trace_lines):
    lines = list(trace_lines)
    i = [k for k, ln in enumerate(lines) if "\tTYPE_GYROSCOPE\t" in ln][10]
    parts = lines[i].split("\t")
    parts[3] = "NaN"
    lines[i] = "\t".join(parts)
    with pytest.raises(FormatError, match="TYPE_GYROSCOPE.*NaN") as e:
        list(ilc2.read(write_trace(tmp_path / "nan.txt", lines)))
    assert "nan.txt" in error_line(e.value)


def test_non_numeric_value(tmp_path, trace_lines):
    lines = [
        ln.replace("\tTYPE_ACCELEROMETER\t", "\tTYPE_ACCELEROMETER\tx", 1) if k == 20 else ln
        for k, ln in enumerate(trace_lines)
    ]
    with pytest.raises(FormatError) as e:
        list(ilc2.read(write_trace(tmp_path / "txt.txt", lines)))
    error_line(e.value)


def test_time_going_backwards(tmp_path, trace_lines):
    lines = list(trace_lines)
    idx = [k for k, ln in enumerate(lines) if "\tTYPE_ACCELEROMETER\t" in ln]
    lines[idx[5]], lines[idx[6]] = lines[idx[6]], lines[idx[5]]
    with pytest.raises(ValidationError, match="TYPE_ACCELEROMETER: timestamps go backwards") as e:
        list(ilc2.read(write_trace(tmp_path / "back.txt", lines)))
    assert "back.txt" in error_line(e.value)


def test_too_many_duplicates_is_broken(tmp_path):
    lines = [ln for ln in synthetic_trace()]
    acc = [k for k, ln in enumerate(lines) if "\tTYPE_ACCELEROMETER\t" in ln]
    for k in acc[1::2]:  # every other accelerometer row takes its predecessor's time
        prev = lines[acc[acc.index(k) - 1]].split("\t")[0]
        lines[k] = prev + lines[k][lines[k].index("\t") :]
    with pytest.raises(ValidationError, match="duplicated"):
        list(ilc2.read(write_trace(tmp_path / "dups.txt", lines)))


def test_wrong_format_file(tmp_path, shared_data):
    ipin = sorted((shared_data / "ipin2023_track3").rglob("*.txt.xz"))[0]
    bad = tmp_path / "log.txt.xz"
    bad.write_bytes(ipin.read_bytes())
    with pytest.raises(FormatError, match="not an ILC2 trace") as e:
        list(ilc2.read(bad))
    assert "log.txt.xz" in error_line(e.value)


def test_not_a_rotation_vector(tmp_path):
    lines = [
        ln.replace("TYPE_ROTATION_VECTOR\t0.000000000", "TYPE_ROTATION_VECTOR\t3.000000000") for ln in synthetic_trace()
    ]
    assert sum("VECTOR\t3.0" in ln for ln in lines) == 300
    with pytest.raises(FormatError, match="not a rotation vector"):
        list(ilc2.read(write_trace(tmp_path / "rv.txt", lines)))


def test_cli_prints_one_line_and_exits_2(tmp_path, monkeypatch, capsys):
    from wearnav import cli

    (tmp_path / "e.txt").write_text("")
    monkeypatch.setattr(
        sys, "argv", ["wearnav", "import", "ilc2", str(tmp_path / "e.txt"), "--out", str(tmp_path / "out")]
    )
    with pytest.raises(SystemExit) as e:
        cli.main()
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()  # tqdm's bar may precede it
    errors = [ln for ln in err if ln.startswith("error: ")]
    assert errors == [err[-1]] and "e.txt: empty file" in err[-1]


# ---- floor plans of either layout; a plan that cannot be read costs the plan only (issue 56) ----

# A floor's outline as a lon/lat box, and the size floor_info.json gives that box (m).
LON0, LAT0, DLON, DLAT = 120.1, 30.29, 0.0002, 0.0001
PLAN_W_M, PLAN_H_M = 20.0, 10.0
OUTLINE_M, SHOP_M = (0.0, 0.0, 20.0, 10.0), (8.0, 4.0, 12.0, 7.0)  # rectangles in plan metres
N_SAMPLES = 300  # 6 s at 50 Hz: track's windows are 4 s


def lonlat_ring(x0, y0, x1, y1):
    """The rectangle (x0, y0)-(x1, y1) in plan metres as a closed lon/lat ring."""
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    return [[LON0 + x / PLAN_W_M * DLON, LAT0 + y / PLAN_H_M * DLAT] for x, y in corners]


def feature(geometry, properties):
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def plan_text(layout, floor):
    """geojson_map.json of one floor in a given layout: site1's (the outline says ``"type": "floor"``,
    first), site2's (the outline's properties name the floor, the shops carry ``poi_no``,
    ``two_class``, ``center``; here after the shops), site2's with the floor named on the shops too,
    one with nothing labelled, or broken ones."""
    outline = {"type": "MultiPolygon", "coordinates": [[lonlat_ring(*OUTLINE_M)]]}
    shop = {"type": "Polygon", "coordinates": [lonlat_ring(*SHOP_M)]}
    centre = np.mean(lonlat_ring(*SHOP_M)[:4], axis=0).tolist()
    site2_shop = {"poi_no": "10012", "two_class": "catering", "center": centre, "name": "tea"}
    feats = {
        "site1": [
            feature(outline, {"Vr": "000200", "category": "floor", "name": floor, "type": "floor"}),
            feature(shop, {"id": "5dd3", "name": "B277", "display": "B277", "category": ["5d35"], "points": []}),
        ],
        "site2": [feature(shop, site2_shop), feature(outline, {"floor": floor})],
        "site2-floor-on-shops": [feature(shop, site2_shop | {"floor": floor}), feature(outline, {"floor": floor})],
        "unlabelled": [feature(shop, {}), feature(outline, {})],
        "points only": [feature({"type": "Point", "coordinates": centre}, {"name": "tea"})],
        "no outline": [  # two rooms side by side: neither holds the other
            feature({"type": "Polygon", "coordinates": [lonlat_ring(0.0, 0.0, 9.0, 10.0)]}, {}),
            feature({"type": "Polygon", "coordinates": [lonlat_ring(11.0, 0.0, 20.0, 10.0)]}, {}),
        ],
    }
    if layout == "not JSON":  # a download cut short
        return '{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": {"type": "Multi'
    return json.dumps({"type": "FeatureCollection", "features": feats[layout]})


def write_floor(root, floor, layout, n_traces=2):
    """<root>/site2/<floor>/ with ``n_traces`` short synthetic traces, floor_info.json and a plan."""
    folder = root / "site2" / floor
    (folder / "path_data_files").mkdir(parents=True)
    lines = [ln.replace("FloorName:B2", f"FloorName:{floor}") for ln in synthetic_trace(n=N_SAMPLES)]
    for k in range(n_traces):
        write_trace(folder / "path_data_files" / f"{floor.lower()}trace{k}.txt", lines)
    (folder / "floor_info.json").write_text(json.dumps({"map_info": {"height": PLAN_H_M, "width": PLAN_W_M}}))
    (folder / "geojson_map.json").write_text(plan_text(layout, floor))
    return folder


def plan_area_m2(plan):
    from wearnav.plans import plan_geometry

    return plan_geometry(plan).area


READABLE = ["site1", "site2", "site2-floor-on-shops", "unlabelled"]
UNREADABLE = ["points only", "no outline", "not JSON"]


@pytest.mark.parametrize("layout", READABLE)
def test_both_plan_layouts_give_the_floor_minus_its_shops(tmp_path, layout):
    """Whichever way the outline is labelled (or not at all), the plan is the outline minus the shop,
    in floor_info.json's metres (issue 56: site2's ``"floor": "B1"`` outline refused the whole site)."""
    write_floor(tmp_path, "B1", layout)
    recs = list(ilc2.read(tmp_path))
    assert len(recs) == 2
    for r in recs:
        (plan,) = r.plans
        assert r.meta["plan"] == plan.name == "site2_B1" and plan.floor == -1 and "no_plan" not in r.meta
        x0, y0, x1, y1 = OUTLINE_M
        sx0, sy0, sx1, sy1 = SHOP_M
        assert plan_area_m2(plan) == pytest.approx((x1 - x0) * (y1 - y0) - (sx1 - sx0) * (sy1 - sy0), rel=1e-6)
        np.testing.assert_allclose(np.concatenate(plan.polygons[0]).min(0), [x0, y0], atol=1e-6)
        np.testing.assert_allclose(np.concatenate(plan.polygons[0]).max(0), [x1, y1], atol=1e-6)


@pytest.mark.parametrize("layout", UNREADABLE)
def test_a_plan_that_cannot_be_read_costs_the_plan_not_the_walks(tmp_path, layout):
    """Every trace imports without a plan; ``meta["no_plan"]`` says why and one warning per floor."""
    write_floor(tmp_path, "F3", layout)
    with pytest.warns(WearnavWarning) as caught:
        ds = import_dataset("ilc2", tmp_path, tmp_path / "out", progress=False)
    assert len(ds) == 2
    lines = [str(w.message) for w in caught if "geojson_map.json" in str(w.message)]
    assert len(lines) == 1 and "F3" in lines[0] and "\n" not in lines[0], lines
    for name in ds.names:
        r = ds.load(name)
        assert r.plans == [] and "plan" not in r.meta and r.devices["phone"].acc.shape[0] == N_SAMPLES
        assert "geojson_map.json" in r.meta["no_plan"] and r.meta["no_plan"] in lines[0]


def test_one_folder_holding_both_layouts_imports_every_trace(tmp_path, monkeypatch, capsys):
    """`wearnav import ilc2` on site1's layout, site2's and a broken plan side by side: every trace is
    imported, the readable floors keep their plan, the broken one says why in one warning line."""
    write_floor(tmp_path / "src", "B1", "site2")
    write_floor(tmp_path / "src", "F1", "site1")
    write_floor(tmp_path / "src", "F2", "not JSON")
    code, _, err = run_cli(monkeypatch, capsys, "import", "ilc2", tmp_path / "src", "--out", tmp_path / "out")
    assert code == 0, err
    warned = [ln for ln in err.splitlines() if ln.startswith("warning: ")]
    assert len(warned) == 1 and "F2" in warned[0] and "geojson_map.json" in warned[0], err
    ds = Dataset.open(tmp_path / "out")
    assert len(ds) == 6
    by_floor = {}
    for name in ds.names:
        r = ds.load(name)
        by_floor.setdefault(r.meta["floor_name"], []).append(r)
    for floor in ("B1", "F1"):
        assert all(r.meta["plan"] == f"site2_{floor}" and len(r.plans) == 1 for r in by_floor[floor])
    # The two layouts of the same floor give the same plan.
    np.testing.assert_allclose(by_floor["B1"][0].plans[0].polygons[0][0], by_floor["F1"][0].plans[0].polygons[0][0])
    assert all(r.plans == [] and "not JSON" in r.meta["no_plan"] for r in by_floor["F2"])


def test_track_on_a_recording_whose_plan_was_unreadable_says_no_plan(tmp_path, monkeypatch, capsys):
    """`track --map auto` says there is no plan and why (the importer's reason), in track.json and on stderr."""
    write_floor(tmp_path / "src", "F2", "no outline", n_traces=1)
    with pytest.warns(WearnavWarning):
        ds = import_dataset("ilc2", tmp_path / "src", tmp_path / "data", progress=False)
    reason = ds.load(ds.names[0]).meta["no_plan"]
    out = tmp_path / "t"
    code, _, err = run_cli(monkeypatch, capsys, "track", tmp_path / "data", "--model", "pdr", "--out", out)
    assert code == 0, err
    summary = json.loads((out / "track.json").read_text())
    assert summary["map"]["from"].startswith("no plan") and reason in summary["map"]["from"]
    assert summary["map"]["plans"] == [] and not summary["map"].get("used")
    assert any(ln.startswith("warning: ") and "no plan" in ln and reason in ln for ln in err.splitlines()), err


@pytest.mark.parametrize("relabel", ["site2", "unlabelled"])
def test_a_real_floor_relabelled_gives_the_same_plan(ilc2_root, tmp_path, relabel):
    """site1's F2 written the way site2 labels its plan (the outline last, ``"floor": "F2"``, shops with
    ``poi_no``/``two_class``/``center``), or with no labels at all, gives exactly site1's plan."""
    real = ilc2_root / "site1/F2"
    doc = json.loads((real / "geojson_map.json").read_text())
    outline = [f for f in doc["features"] if f["properties"].get("type") == "floor"]
    shops = [f for f in doc["features"] if f["properties"].get("type") != "floor"]
    if relabel == "site2":
        for k, f in enumerate(shops):
            f["properties"] = {"poi_no": str(k), "two_class": "shop", "center": f["properties"]["point"]}
        outline[0]["properties"] = {"floor": "F2"}
    else:
        for f in shops + outline:
            f["properties"] = {}
    folder = tmp_path / "F2"
    folder.mkdir()
    (folder / "geojson_map.json").write_text(json.dumps({"type": "FeatureCollection", "features": shops + outline}))
    (folder / "floor_info.json").write_bytes((real / "floor_info.json").read_bytes())
    (mine, why), (theirs, _) = ilc2.floor_plan(folder, "x", 1), ilc2.floor_plan(real, "x", 1)
    assert mine is not None and theirs is not None, why
    assert len(mine.polygons) == len(theirs.polygons) > 1
    for a, b in zip(mine.polygons, theirs.polygons):
        assert len(a) == len(b) and all(np.array_equal(r, s) for r, s in zip(a, b))
