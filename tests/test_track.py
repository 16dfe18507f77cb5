"""`wearnav track` on simulated Sensor Logger exports (issue 8, section 1).

The model is PDR (not learned: ``prepare_run`` + ``fit`` are instant), run exactly as
``wearnav train pdr`` would leave it. The recording is a simulated walk with phone, watch, earbuds
and location fixes, exported by ``wearnav.importers.sensorlogger_export.write_export``.
"""

from __future__ import annotations

import dataclasses
import json

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pymap3d
import pytest

from conftest import run_cli
from test_importers_ipin2023 import LOGS, rows_of
from wearnav import metrics
from wearnav.core.geo import PROJECTION, latlon_to_local
from wearnav.dataset import DatasetWriter
from wearnav.errors import ConfigError, WearnavWarning
from wearnav.evaluate import evaluate_sequence
from wearnav.fuse import first_fix_anchor
from wearnav.importers import ipin2023
from wearnav.importers.sensorlogger_export import ORIGIN, time_origin, write_export, zip_export
from wearnav.preprocess import align
from wearnav.recording import Recording
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.track import track
from wearnav.train.odometry import TrainConfig, fit, load_model, prepare_run

EXPORT = "2023-11-14_22-13-20"
IPIN_LOG = "IPIN2023_T3_TrainingTrial02_repetition04"  # fixes up to 70 m from the venue's origin


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("track")
    rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=60), seed=1)
    with DatasetWriter(root / "ds", {"made_by": "test_track"}) as w:
        w.add(rec, split="train")
        w.add(dataclasses.replace(rec, name="walk_val"), split="val")
    cfg = TrainConfig(model="pdr", data=str(root / "ds"))
    run = prepare_run(cfg, root / "run")
    fit(cfg, run, progress=False)
    return root, rec, run


@pytest.fixture(scope="module")
def learned_run(setup):
    """Suite-IN++ trained for a few epochs on the same walk (the fixture's train and val copies):
    a learned model's checkpoint, as `wearnav train` leaves it."""
    root, rec, _ = setup
    cfg = TrainConfig(model="suitein++", data=str(root / "ds"), epochs=12, patience=12, stride=20, seed=0, lr=3e-3)
    run = prepare_run(cfg, root / "run_suitein")
    fit(cfg, run, progress=False)
    return run


def _rot(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def test_track_recovers_truth_with_the_models_eval_ate(setup, tmp_path):
    """Track's path, rotated into the truth frame by the yaw the eval's frame alignment found
    (``frame_align="truth"``: the common frame's yaw relative to the truth, its mean over the
    walk) and started at the true start, has the ATE of the model's own eval within 0.3 m + 10 %.
    The eval rotates by that yaw at every instant (it varies by a few degrees), track by its
    mean: the two paths differ only by that variation."""
    root, rec, run = setup
    model, cfg = load_model(run)
    seq_eval = align(rec, cfg.preprocess_config())
    row, _ = evaluate_sequence(model, seq_eval, cfg.window, cfg.stride)
    psi = np.radians(seq_eval.meta["frame"]["truth"]["yaw_deg"])

    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    summary = track(folder, run, tmp_path / "out")
    traj = pd.read_csv(tmp_path / "out" / "trajectory.csv")
    t = traj["t"].to_numpy() + time_origin(rec)  # the export's clock starts at its first sample
    true = np.stack([np.interp(t, rec.truth.t, rec.truth.pos[:, k]) for k in range(2)], axis=1)
    est = traj[["x", "y"]].to_numpy() @ _rot(-np.degrees(psi)).T + true[0]
    ate_track = metrics.ate(t, est, true)
    print(f"eval ATE {row['ate']:.3f} m, track ATE {ate_track:.3f} m, yaw {np.degrees(psi):.1f}°")
    assert row["ate"] < 10.0  # the walk is ~68 m: the model does track it
    assert abs(ate_track - row["ate"]) <= 0.3 + 0.1 * row["ate"]
    assert summary["duration_s"] == pytest.approx(row["duration"], abs=0.1)
    assert summary["devices_used"] == ["phone"]  # PDR reads the first present device (issue 58 §7)
    assert summary["odometry"]["frame_align"] == "common" and summary["odometry"]["frame_reference"] == "phone"
    assert set(traj.columns) >= {"t", "x", "y", "phone", "watch", "earbuds", "east", "north"}
    assert traj[["x", "y"]].iloc[0].abs().max() < 1e-9  # integrated from (0, 0)
    assert traj["unix_time"].iloc[0] == pytest.approx(1_700_000_000.123 + traj["t"].iloc[0], abs=1e-3)
    img = mpimg.imread(tmp_path / "out" / "trajectory.png")
    assert img.shape[0] > 400 and img.std() > 0.05


def test_track_with_a_learned_checkpoint_matches_its_eval(setup, learned_run, tmp_path):
    """The same check with a learned model, given as its checkpoint file: track's path (rotated
    by the eval's truth yaw, started at the true start) has the eval's ATE within 0.3 m + 10 %."""
    _, rec, _ = setup
    model, cfg = load_model(learned_run)
    seq_eval = align(rec, cfg.preprocess_config())
    row, _ = evaluate_sequence(model, seq_eval, cfg.window, cfg.stride)
    psi = np.degrees(np.radians(seq_eval.meta["frame"]["truth"]["yaw_deg"]))
    summary = track(
        write_export(rec, tmp_path / EXPORT, platform="android"),
        learned_run / "checkpoints" / "best.ckpt",
        tmp_path / "out",
    )
    traj = pd.read_csv(tmp_path / "out" / "trajectory.csv")
    t = traj["t"].to_numpy() + time_origin(rec)
    true = np.stack([np.interp(t, rec.truth.t, rec.truth.pos[:, k]) for k in range(2)], axis=1)
    est = traj[["x", "y"]].to_numpy() @ _rot(-psi).T + true[0]
    ate_track = metrics.ate(t, est, true)
    print(f"suitein++: eval ATE {row['ate']:.3f} m, track ATE {ate_track:.3f} m")
    assert summary["model"] == "suitein++"
    assert abs(ate_track - row["ate"]) <= 0.3 + 0.1 * row["ate"]


def test_track_speed_cadence_keeps_the_models_direction_at_cadence_steps(
    setup, learned_run, tmp_path, monkeypatch, capsys
):
    """``track --speed cadence``: the learned model's path with PDR's cadence-long steps, exactly
    what ``load_model(run, speed="cadence")`` integrates, pointing where the model's own path
    points wherever both move, and ``track.json`` says which speed; PDR has no speed to take."""
    from wearnav.track import load_input, odometry

    _, rec, _ = setup
    export = write_export(rec, tmp_path / EXPORT, platform="android")
    own = track(export, learned_run, tmp_path / "own")
    hybrid = track(export, learned_run, tmp_path / "cadence", speed="cadence")
    assert own["speed"] == "model" and hybrid["speed"] == "cadence"
    a = pd.read_csv(tmp_path / "own" / "trajectory.csv")[["x", "y"]].to_numpy()
    b = pd.read_csv(tmp_path / "cadence" / "trajectory.csv")[["x", "y"]].to_numpy()
    model, cfg = load_model(learned_run, speed="cadence")
    _, _, _, _, _, xy = odometry(model, cfg, load_input(export))
    np.testing.assert_allclose(b, xy, atol=1e-4)  # trajectory.csv keeps 4 decimals
    da, db = a[10:] - a[:-10], b[10:] - b[:-10]  # 10 samples apart: the file's rounding is small there
    moving = (np.linalg.norm(da, axis=1) > 0.05) & (np.linalg.norm(db, axis=1) > 0.05)
    cos = np.sum(da * db, axis=1)[moving] / (np.linalg.norm(da, axis=1) * np.linalg.norm(db, axis=1))[moving]
    assert moving.mean() > 0.5 and np.min(cos) > 0.99
    assert abs(hybrid["odometry"]["length_m"] / own["odometry"]["length_m"] - 1) > 0.01  # the speed did change
    code, _, err = run_cli(
        monkeypatch, capsys, "track", export, "--model", "pdr", "--speed", "cadence", "--out", tmp_path / "pdr"
    )
    assert code == 2 and err.startswith("error: ") and "needs a learned model" in err and len(err.splitlines()) == 1
    from wearnav.cli import Speed
    from wearnav.train.odometry import SPEED_SOURCES

    assert [s.value for s in Speed] == list(SPEED_SOURCES)  # the option offers every source, in order


def test_geojson_lies_on_the_fixes(setup, tmp_path):
    """The anchored path at the fix times lies a median of under 5 m from the fixes. Why 5 m: the
    simulated fixes scatter about the truth by a median 2.4 m (printed), the path's own error is
    its ATE (2.6 m here), and the anchor absorbs only the common part of both; 5 m is about their
    sum (measured: 1.1 m, because the fix error is correlated over minutes and the fitted offset
    takes it up). The unanchored path (common frame, from (0, 0)) misses by 13 m, and must miss
    by at least twice as much."""
    root, rec, run = setup
    folder = write_export(rec, tmp_path / EXPORT, platform="android", total_acceleration=True)
    zpath = zip_export(folder, tmp_path / f"{EXPORT}.zip")
    summary = track(zpath, run, tmp_path / "out")
    gj = json.loads((tmp_path / "out" / "trajectory.geojson").read_text())
    lines = [f for f in gj["features"] if f["geometry"]["type"] == "LineString"]
    points = [f for f in gj["features"] if f["geometry"]["type"] == "Point"]
    assert len(lines) == 1 and len(points) == len(rec.fixes)
    lon, lat = np.array(lines[0]["geometry"]["coordinates"]).T
    assert abs(lat[0] - ORIGIN[0]) < 0.01 and abs(lon[0] - ORIGIN[1]) < 0.01  # near the written fixes
    path = latlon_to_local(lat, lon, *ORIGIN)
    flon, flat = np.array([p["geometry"]["coordinates"] for p in points]).T
    fixes = latlon_to_local(flat, flon, *ORIGIN)
    # the written fixes come back where the export put them
    np.testing.assert_allclose(fixes - fixes[0], rec.fixes.pos[:, :2] - rec.fixes.pos[0, :2], atol=0.01)
    traj = pd.read_csv(tmp_path / "out" / "trajectory.csv")
    t_fix = np.array([p["properties"]["t"] for p in points])
    inside = (t_fix >= traj.t.iloc[0]) & (t_fix <= traj.t.iloc[-1])
    at_fix = np.stack([np.interp(t_fix[inside], traj.t, path[:, k]) for k in range(2)], axis=1)
    dist = np.linalg.norm(at_fix - fixes[inside], axis=1)
    fix_noise = np.linalg.norm(
        rec.fixes.pos[:, :2]
        - np.stack([np.interp(rec.fixes.t, rec.truth.t, rec.truth.pos[:, k]) for k in range(2)], axis=1),
        axis=1,
    )
    raw = traj[["x", "y"]].to_numpy()
    raw_at_fix = np.stack([np.interp(t_fix[inside], traj.t, raw[:, k]) for k in range(2)], axis=1)
    print(
        f"median path-fix distance {np.median(dist):.2f} m (fix noise median {np.median(fix_noise):.2f} m, "
        f"unanchored {np.median(np.linalg.norm(raw_at_fix - fixes[inside], axis=1)):.2f} m); {summary['anchoring']}"
    )
    assert np.median(dist) < 5.0
    assert np.median(np.linalg.norm(raw_at_fix - fixes[inside], axis=1)) > 2 * np.median(dist)
    assert summary["anchoring"]["fixes_used"] >= 10


def test_anchor_recovers_a_known_rotation_and_offset():
    """A path that is the fixes' truth rotated by 40° and shifted, fixes with 3 m noise (one with a
    bad 50 m accuracy and a 40 m error): the fit recovers yaw and offset; the weight keeps the bad
    fix from pulling it."""
    rng = np.random.default_rng(0)
    t = np.arange(0, 120, 0.04)
    truth = np.stack([30 * np.sin(t / 20), 0.8 * t], axis=1) + [100.0, -50.0]
    path = (truth - truth[0]) @ _rot(-40).T  # the odometry frame: yawed by −40°, starting at 0
    fix_t = np.arange(0, 120, 1.0)
    fixes = np.stack([np.interp(fix_t, t, truth[:, k]) for k in range(2)], axis=1) + rng.normal(0, 3, (120, 2))
    acc = np.full(120, 4.0)
    fixes[5] += [40.0, 0.0]
    acc[5] = 50.0
    fit = first_fix_anchor(t, path, fix_t, fixes, acc)
    assert fit.info["heading_offset_deg"] == pytest.approx(40.0, abs=3.0)
    assert fit.info["heading_offset_deg"] - 40.0 == pytest.approx(0.0, abs=4 * fit.info["yaw_std_deg"])
    assert fit.info["fixes_used"] == 61  # the first 60 s
    err = np.linalg.norm(fit.xy - truth, axis=1)
    assert np.median(err) < 2.0


@pytest.mark.real_data
def test_geojson_and_csv_agree_with_pymap3d_on_a_real_ipin_log(setup, shared_data, tmp_path):
    """Issue 26, item 1: on a real IPIN 2023 log (imported to .h5, tracked by PDR), the imported
    fixes and truth are pymap3d's WGS-84 east-north-up of the raw lat/lon about the recording's
    origin, and every GeoJSON point of track's output, taken back by ``pymap3d.geodetic2enu``, lies
    on the CSV's east/north (path) or the recording's fixes: all to 1 cm. The old equirectangular
    projection missed by about 0.2 % of the distance from the origin here (up to 13 cm at 70 m)."""
    import lzma

    _, _, run = setup
    log = shared_data / "ipin2023_track3" / LOGS / f"{IPIN_LOG}.txt.xz"
    (rec,) = list(ipin2023.read(log))
    lat0, lon0 = rec.meta["origin_lat"], rec.meta["origin_lon"]
    assert rec.meta["projection"] == PROJECTION

    def enu(lat, lon):
        e, n, _ = pymap3d.geodetic2enu(np.asarray(lat, float), np.asarray(lon, float), 0.0, lat0, lon0, 0.0)
        return np.stack([e, n], axis=1)

    with lzma.open(log, "rt", encoding="utf-8", errors="replace") as f:
        lines = f.read().splitlines()
    raw = enu(*np.array([[float(r[3]), float(r[4])] for r in rows_of(lines, "GNSS")]).T)
    gap = np.min(np.linalg.norm(rec.fixes.pos[:, None, :2] - raw[None], axis=2), axis=1)
    assert np.max(gap) <= 0.01 and np.max(np.linalg.norm(rec.fixes.pos, axis=1)) > 50  # metres away
    posi = np.array([[float(r[3]), float(r[4])] for r in rows_of(lines, "POSI")])
    np.testing.assert_allclose(rec.truth.pos, enu(posi[:, 0], posi[:, 1]), atol=0.01)

    rec.save(tmp_path / "ipin.h5")
    summary = track(tmp_path / "ipin.h5", run, tmp_path / "out")
    # a real phone-only walk given the phone+watch+earbuds PDR run: no warning (issue 38: PDR was
    # trained on nothing, so missing devices and training data say nothing about it; no re-import;
    # PDR's own path is plausible for the steps it counts)
    assert summary["warnings"] == []
    assert summary["geojson"].endswith("trajectory.geojson")
    # the phone's rotation vector is east/magnetic north/up: the smoother's heading has a 0° prior
    assert summary["anchoring"]["config"]["heading_prior_deg"] == 0.0
    traj = pd.read_csv(tmp_path / "out" / "trajectory.csv")
    gj = json.loads((tmp_path / "out" / "trajectory.geojson").read_text())
    (line,) = [f for f in gj["features"] if f["geometry"]["type"] == "LineString"]
    lon, lat = np.array(line["geometry"]["coordinates"]).T
    path = traj[["east", "north"]].to_numpy()
    assert len(lat) == len(path) and np.ptp(path, axis=0).max() > 20
    assert np.max(np.linalg.norm(enu(lat, lon) - path, axis=1)) <= 0.01
    flon, flat = np.array([f["geometry"]["coordinates"] for f in gj["features"] if f["geometry"]["type"] == "Point"]).T
    assert np.max(np.linalg.norm(enu(flat, flon) - rec.fixes.pos[:, :2], axis=1)) <= 0.01


def test_old_projection_needs_reimport_in_info_and_track(setup, tmp_path, monkeypatch, capsys):
    """A recording with a lat/lon origin but no ``meta["projection"]`` (imported before the
    WGS-84 ENU converter): ``wearnav info`` (recording and dataset) and ``wearnav track`` say in
    one line that it needs re-import and how; track.json lists it under ``warnings``. The same
    recording with the current projection: no such line."""
    root, rec, run_dir = setup
    old = dataclasses.replace(
        rec, name="old", meta={**rec.meta, "source": "ipin2023", "origin_lat": ORIGIN[0], "origin_lon": ORIGIN[1]}
    )
    new = dataclasses.replace(old, name="new", meta={**old.meta, "projection": PROJECTION})
    old.save(tmp_path / "old.h5")
    new.save(tmp_path / "new.h5")
    with DatasetWriter(tmp_path / "ds", {"made_by": "test_track"}) as w:
        w.add(old)
        w.add(new)

    def reimport_lines(err):
        return [ln for ln in err.splitlines() if "needs re-import" in ln]

    for src in (tmp_path / "old.h5", tmp_path / "ds"):
        code, out, err = run_cli(monkeypatch, capsys, "info", src)
        assert code == 0, err
        (ln,) = reimport_lines(err)
        assert ln.startswith("warning: ") and "wearnav import ipin2023" in ln and "equirectangular" in ln
    assert "1 of 2 recordings (old)" in ln
    code, out, err = run_cli(monkeypatch, capsys, "info", tmp_path / "new.h5")
    assert code == 0 and reimport_lines(err) == []

    code, out, err = run_cli(
        monkeypatch, capsys, "track", tmp_path / "old.h5", "--model", run_dir, "--out", tmp_path / "o_old"
    )
    assert code == 0, err
    (ln,) = reimport_lines(err)
    assert "wearnav import ipin2023" in ln
    warned = json.loads((tmp_path / "o_old" / "track.json").read_text())["warnings"]
    assert len(warned) == 1 and warned[0].startswith("old: needs re-import")
    code, out, err = run_cli(
        monkeypatch, capsys, "track", tmp_path / "new.h5", "--model", run_dir, "--out", tmp_path / "o_new"
    )
    assert code == 0 and reimport_lines(err) == []
    assert json.loads((tmp_path / "o_new" / "track.json").read_text())["warnings"] == []


run = run_cli


def test_track_command_subsets_and_one_line_errors(setup, tmp_path, monkeypatch, capsys):
    root, rec, run_dir = setup
    # watch and earbuds only (no phone, no fixes), from the imported .h5 in a dataset folder
    sub = Recording(name="nophone", devices={d: rec.devices[d] for d in ("watch", "earbuds")})
    write_export(sub, tmp_path / "sub" / EXPORT, platform="ios")
    code, out, err = run(monkeypatch, capsys, "import", "sensorlogger", tmp_path / "sub", "--out", tmp_path / "ds")
    assert code == 0, err
    code, out, err = run(
        monkeypatch,
        capsys,
        "track",
        tmp_path / "ds",
        "--name",
        EXPORT,
        "--model",
        run_dir / "checkpoints" / "best.ckpt",
        "--out",
        tmp_path / "o1",
    )
    assert code == 2 and "no such run folder or checkpoint" in err  # pdr has no checkpoint file
    code, out, err = run(
        monkeypatch, capsys, "track", tmp_path / "ds", "--name", EXPORT, "--model", run_dir, "--out", tmp_path / "o1"
    )
    assert code == 0, err
    assert "model: pdr on the watch;" in out and "path in the watch's world frame" in out  # PDR reads one
    traj = pd.read_csv(tmp_path / "o1" / "trajectory.csv")
    assert (traj["phone"] == 0).all() and (traj["watch"] == 1).all()
    assert not (tmp_path / "o1" / "trajectory.geojson").exists()
    # one-line errors: unknown name, no usable stream, corrupt checkpoint
    code, _, err = run(
        monkeypatch, capsys, "track", tmp_path / "ds", "--name", "nope", "--model", run_dir, "--out", tmp_path / "o2"
    )
    assert code == 2 and "no recording named 'nope'" in err and err.count("\n") == 1
    only_phone = TrainConfig(model="pdr", data=str(root / "ds"), devices=("phone",))
    phone_run = prepare_run(only_phone, tmp_path / "phone_run")
    code, _, err = run(
        monkeypatch, capsys, "track", tmp_path / "ds", "--name", EXPORT, "--model", phone_run, "--out", tmp_path / "o3"
    )
    assert code == 2 and "no IMU stream the model can use" in err and err.count("\n") == 1
    ronin = TrainConfig(model="ronin", data=str(root / "ds"), devices=("watch",))
    ronin_run = prepare_run(ronin, tmp_path / "ronin_run")
    (ronin_run / "checkpoints").mkdir()
    (ronin_run / "checkpoints" / "best.ckpt").write_bytes(b"not a checkpoint")
    code, _, err = run(
        monkeypatch,
        capsys,
        "track",
        tmp_path / "ds",
        "--name",
        EXPORT,
        "--model",
        ronin_run / "checkpoints" / "best.ckpt",
        "--out",
        tmp_path / "o4",
    )
    assert code == 2 and "corrupt or incompatible checkpoint" in err and err.count("\n") == 1


def test_track_anchorings_and_a_walk_without_fixes(setup, tmp_path):
    """Issue 25: `track` smooths by default (each point's σ in the CSV and GeoJSON, what was used in
    track.json), `--anchor first-fixes` gives the old anchoring, and a recording without fixes
    keeps the path from (0, 0) and says so (a warning, not silence)."""
    _, rec, run = setup
    folder = write_export(rec, tmp_path / EXPORT, platform="android")
    smooth = track(folder, run, tmp_path / "smooth")
    a = smooth["anchoring"]
    assert a["method"] == "smooth" and a["requested"] == "smooth"
    assert {"fixes_used", "fixes_down_weighted", "scale", "heading_offset_deg"} <= set(a)
    assert 0.5 < a["scale"] < 2.0
    traj = pd.read_csv(tmp_path / "smooth" / "trajectory.csv")
    assert traj["sigma_m"].gt(0).all() and traj["sigma_m"].lt(50).all()
    gj = json.loads((tmp_path / "smooth" / "trajectory.geojson").read_text())
    line = next(f for f in gj["features"] if f["geometry"]["type"] == "LineString")
    assert len(line["properties"]["sigma_m"]) == len(line["geometry"]["coordinates"])
    first = track(folder, run, tmp_path / "first", anchor="first-fixes")
    assert first["anchoring"]["method"] == "first-fixes"
    assert "sigma_m" not in pd.read_csv(tmp_path / "first" / "trajectory.csv").columns
    with pytest.raises(ConfigError):
        track(folder, run, tmp_path / "bad", anchor="magic")
    # fixes that lag the walker (docs/design.md, "The fixes' lag"): the smoother takes the lag given
    assert a["fix_lag_s"] == 0.0
    late = track(folder, run, tmp_path / "late", fix_lag_s=4.0)
    assert late["anchoring"]["fix_lag_s"] == 4.0 and late["anchoring"]["method"] == "smooth"
    assert not np.allclose(pd.read_csv(tmp_path / "late" / "trajectory.csv")["east"], traj["east"])
    with pytest.raises(ConfigError, match="--fix-lag"):
        track(folder, run, tmp_path / "bad", fix_lag_s=-1.0)
    h5 = dataclasses.replace(rec, fixes=None).save(tmp_path / "nofix.h5")
    with pytest.warns(WearnavWarning, match="no location fixes"):
        bare = track(h5, run, tmp_path / "bare")
    assert bare["anchoring"]["method"] == "none"
    assert "east" not in pd.read_csv(tmp_path / "bare" / "trajectory.csv").columns
    # trajectory.html: the anchored path at 1 point a second (and the last), the kept fixes, the
    # activity classify finds; without fixes the odometry's own frame and no fixes
    for out, csv_cols, anchor in (("smooth", ["east", "north"], "smooth"), ("bare", ["x", "y"], "none")):
        assert "trajectory.html" in json.loads((tmp_path / out / "track.json").read_text())["files"]
        data = page_data(tmp_path / out / "trajectory.html")
        traj = pd.read_csv(tmp_path / out / "trajectory.csv")
        idx = list(range(0, len(traj), 25)) + ([len(traj) - 1] if (len(traj) - 1) % 25 else [])
        assert data["anchor"] == anchor and len(data["path"]) == len(idx)
        assert np.allclose([p[1:3] for p in data["path"]], traj[csv_cols].to_numpy()[idx], atol=1.5e-3)
        assert [a["label"] for a in data["activity"]] and data["activity"][-1]["end_s"] > traj["t"].iloc[-1] - 5
    assert len(page_data(tmp_path / "smooth" / "trajectory.html")["fixes"]) > 10
    assert page_data(tmp_path / "bare" / "trajectory.html")["fixes"] == []


def page_data(html_file) -> dict:
    """The data a trajectory.html draws (its inline JSON)."""
    text, marker = html_file.read_text(), '<script id="wearnav-data" type="application/json">'
    start = text.index(marker) + len(marker)
    return json.loads(text[start : text.index("</script>", start)].replace("<\\/", "</"))
