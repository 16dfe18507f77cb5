"""Real-building odometry benchmark (wearnav.bench.real) on a stand-in building made from the
simulator: dense truth thinned to surveyed points every few seconds, recordings grouped into
"floors", the phone's world frame turned by a known yaw as a magnetic-north frame would be."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wearnav import runs
from wearnav.bench.decompose import along_across
from wearnav.bench.real import RealBench, run_benchmark
from wearnav.bench.real_page import frame_name
from wearnav.bench.real_sites import estimate_site_yaw, prepare_data, split_of
from wearnav.core.rotations import from_wxyz, to_wxyz
from wearnav.dataset import Dataset, write_dataset
from wearnav.errors import ConfigError, ValidationError
from wearnav.preprocess import PreprocessConfig, align
from wearnav.preprocess.frames import rotate_stacked
from wearnav.recording import Trajectory
from wearnav.simulate import simulate_dataset
from wearnav.train.odometry import load_model

POINT_EVERY_S = 5.0


def _building(recs, yaw_deg: float):
    """Phone only, truth thinned to points every POINT_EVERY_S, the phone's world frame yawed by
    ``yaw_deg`` against the truth frame (the simulator's drawn per-recording offset, a test's
    bookkeeping, taken out first), a ``floor_name`` per recording."""
    out = []
    for i, rec in enumerate(recs):
        drawn = rec.meta["devices"]["phone"]["quat_yaw_offset_deg"]
        rz = Rotation.from_euler("z", yaw_deg - drawn, degrees=True)
        s = rec.devices["phone"]
        s = dataclasses.replace(s, quat=to_wxyz(rz * from_wxyz(s.quat)))
        keep = np.unique(np.searchsorted(rec.truth.t, np.arange(rec.truth.t[0], rec.truth.t[-1], POINT_EVERY_S)))
        truth = Trajectory(rec.truth.t[keep], rec.truth.pos[keep])
        meta = {**rec.meta, "floor_name": "F9" if i % 4 == 0 else f"F{i % 3}", "source": "standin"}
        meta.pop("split", None)
        out.append((dataclasses.replace(rec, devices={"phone": s}, truth=truth, meta=meta), ""))
    return out


def _simulate(dest, seed: int, modes: tuple[str, ...], n: int | None = None, **kw) -> Dataset:
    """The first ``n`` walks in ``modes`` of the "tiny" preset for ``seed``, each as the whole preset
    makes it, without simulating the rest (``kw``: :func:`simulate_dataset`'s, e.g. corridor_m)."""
    return simulate_dataset(
        "tiny", dest, seed, progress=False, select=lambda plan: [w for w in plan if w.config.mode in modes][:n], **kw
    )


@pytest.fixture(scope="module")
def building(tmp_path_factory):
    """Seven walks (two held out on "F9", the rest split into train and val), and another building
    of the same walks in reverse order; ``sim``: the simulator's dataset they came from."""
    root = tmp_path_factory.mktemp("real")
    sim = _simulate(root / "sim", 2, ("STW", "DRW"), 7)
    recs = [sim.load(n) for n in sim.names]
    write_dataset(root / "building", _building(recs, 40.0))
    write_dataset(root / "other", _building(recs[::-1], -25.0))
    return root


def test_split_by_place_is_deterministic_and_holds_out_whole_groups():
    assert split_of("a", "F2", {"F2"}) == "test"
    names = [f"trace{i}" for i in range(200)]
    splits = [split_of(n, "F1", {"F2"}) for n in names]
    assert splits == [split_of(n, "F1", {"F2"}) for n in names]
    assert 0.1 < splits.count("val") / len(splits) < 0.3 and "test" not in splits


def test_prepare_data_refuses_unknown_groups_and_missing_grouping(building, tmp_path):
    with pytest.raises(ValidationError, match="not in the data"):
        prepare_data(building / "building", tmp_path / "a", group_by="floor_name", test_groups=("F7",), progress=False)
    with pytest.raises(ConfigError, match="group-by"):
        prepare_data(building / "building", tmp_path / "b", progress=False)
    out, info = prepare_data(
        building / "building", tmp_path / "c", group_by="floor_name", test_groups=("F9",), progress=False
    )
    m = Dataset.open(out).manifest
    floors = {n: Dataset.open(out).load(n).meta["floor_name"] for n in m.name}
    assert all((floors[n] == "F9") == (s == "test") for n, s in zip(m.name, m.split))
    assert set(m.split) == {"train", "val", "test"} and info["groups"]["F9"] == {"test": int((m.split == "test").sum())}


def test_preprocess_joins_points_by_straight_lines_and_turns_the_input(building):
    ds = Dataset.open(building / "building")
    rec = ds.load(ds.names[0])
    sparse = align(rec, PreprocessConfig(devices=("phone",), frame_align="none"))
    joined = align(rec, PreprocessConfig(devices=("phone",), frame_align="none", truth_max_gap=60.0))
    inside = (joined.t >= rec.truth.t[0]) & (joined.t <= rec.truth.t[-1])
    assert np.isfinite(joined.pos[inside]).all() and np.isnan(sparse.pos[inside]).mean() > 0.9
    mid = 0.5 * (rec.truth.pos[0, :2] + rec.truth.pos[1, :2])
    k = np.argmin(np.abs(joined.t - 0.5 * (rec.truth.t[0] + rec.truth.t[1])))
    assert joined.pos[k] == pytest.approx(mid, abs=0.05)
    turned = align(rec, PreprocessConfig(devices=("phone",), frame_align="none", yaw_deg=40.0))
    assert turned.imu[0] == pytest.approx(rotate_stacked(sparse.imu[0], -np.deg2rad(40.0)), abs=1e-4)


def test_site_yaw_follows_a_turn_of_the_input_frame(building, tmp_path):
    """The PDR estimate is equivariant: the same traces with the phone's world frame turned by a
    further 30° give a yaw 30° larger (the sign convention of wearnav.preprocess.frames)."""
    ds = Dataset.open(building / "building")
    base = estimate_site_yaw(building / "building", split="")
    recs = [
        (
            dataclasses.replace(
                r,
                devices={
                    "phone": dataclasses.replace(
                        r.devices["phone"],
                        quat=to_wxyz(Rotation.from_euler("z", 30, degrees=True) * from_wxyz(r.devices["phone"].quat)),
                    )
                },
            ),
            "",
        )
        for r in (ds.load(n) for n in ds.names)
    ]
    write_dataset(tmp_path / "turned", recs)
    turned = estimate_site_yaw(tmp_path / "turned", split="")
    assert base["segments"] == turned["segments"] > 20
    assert ((turned["yaw_deg"] - base["yaw_deg"] + 180) % 360 - 180) == pytest.approx(30.0, abs=0.5)
    # the drawn 40° is found up to PDR's own heading bias on simulated gait
    assert abs(base["yaw_deg"] - 40.0) < 25.0


@pytest.mark.slow
def test_benchmark_end_to_end_resumes_and_reports_both_buildings(building, tmp_path):
    out = tmp_path / "bench"
    bench = RealBench(models=("pdr", "suitein++"), epochs=1, stride=25)
    kw = dict(
        group_by="floor_name",
        test_groups=("F9",),
        test_group_by="floor_name",
        test_test_groups=("F9",),
        bench=bench,
        progress=False,
    )
    msgs = []
    page = run_benchmark(building / "building", out, building / "other", echo=msgs.append, **kw)
    text = page.read_text()
    assert "Held-out groups of the training building" in text and "Another building, never trained on" in text
    doc = json.loads((out / "results.json").read_text())
    for site in ("main", "other"):
        table = {r["method"]: r for r in doc["sites"][site]["table"]}
        # the learned model is also scored as the hybrid with PDR's speed (issue 34)
        assert {"pdr", "suitein++", "suitein++ · PDR speed", "raw phone fixes"} <= set(table)
        for r in table.values():
            assert r["points"] > 0 and 0 <= r["median (m)"] <= r["p95 (m)"] < 1e3
        # a path's own arc is never shorter than its chords between the same surveyed times
        assert table["pdr"]["arc ratio"] >= table["pdr"]["length ratio"] - 1e-9 > 0
        # whether each learned run beat standing still on validation (PDR is not learned)
        assert table["pdr"]["beats standing still"] == "not learned"
        assert table["suitein++"]["beats standing still"] in ("yes", "NO")
    # the user protocol, the smoother paired by walk against each other path, and again on the
    # training walks for the models that never trained on them (PDR, not the learned model here)
    up = doc["sites"]["main"]["user_protocol"]
    assert {(r["model"], r["smoother minus"]) for r in up["paired"]} >= {
        ("pdr", "raw phone fixes"),
        ("suitein++", "raw phone fixes"),
        ("suitein++ · PDR speed", "raw phone fixes"),
    }
    # why, per walk: speed and heading between surveyed points, with its figure
    assert "Why, per walk" in text and (out / "main_speed_ratio.png").is_file()
    assert "suitein++ · PDR speed" in text.split("Why, per walk")[1].split("User protocol")[0]
    assert all(r["walks"] == table["pdr"]["traces"] for r in up["paired"])
    train_rows = [r["path"] for r in up["train_walks"]["table"]]
    assert train_rows[0] == "raw phone fixes" and any(p.startswith("pdr ·") for p in train_rows)
    assert not any(p.startswith("suitein++") for p in train_rows)
    assert "training walks, for the models that never trained" in text
    # every scored trace is a test-group trace, scored from its first point on
    m = runs.read_metrics(next((out / "runs").glob("pdr-*")) / "eval_main")
    test = set(Dataset.open(out / "data" / "main").split("test").names)
    assert {r["name"] for r in m["splits"]["test"]["sequences"]} == test
    assert m["preprocess"]["yaw_deg"] == doc["sites"]["main"]["yaw"]["yaw_deg"]
    # the other building is scored with its own yaw
    mo = runs.read_metrics(next((out / "runs").glob("pdr-*")) / "eval_other")
    assert mo["preprocess"]["yaw_deg"] == doc["sites"]["other"]["yaw"]["yaw_deg"] != m["preprocess"]["yaw_deg"]
    # a world-frame learned run is not scored along where the phone points, nor can it be loaded so
    # (issue 34: only a heading-frame model's speed is one along the phone's pointing)
    world_run = next((out / "runs").glob("suitein++-*"))
    assert not (world_run / "eval_main_pointing").exists() and not (world_run / "eval_main_snapped").exists()
    for speed in ("pointing", "snapped"):
        with pytest.raises(ConfigError, match="heading frame"):
            load_model(world_run, speed=speed)
    msgs.clear()
    run_benchmark(building / "building", out, building / "other", echo=msgs.append, **kw)
    assert sum("complete, skipped" in s for s in msgs) == 2
    # sim-to-real: the same suite gains a row for the model trained on the simulator only
    sim_bench = dataclasses.replace(bench, models=("suitein++",), train_data=str(building / "sim"))
    run_benchmark(building / "building", out, building / "other", echo=msgs.append, **{**kw, "bench": sim_bench})
    doc = json.loads((out / "results.json").read_text())
    methods = [r["method"] for r in doc["sites"]["main"]["table"]]
    sim_label = "suitein++ · simulator `sim` (commit " + methods[3].split("(commit ")[1]
    hybrids = (" · PDR speed", " · cadence speed")
    assert methods[:6] == [
        "suitein++",
        *("suitein++" + h for h in hybrids),
        sim_label,
        *(sim_label + h for h in hybrids),
    ]
    assert methods[6:] == ["pdr", "raw phone fixes"]
    sim_run = [p for p in (out / "runs").glob("suitein++-*") if "sim" in runs.read_config(p)["config"]["train"]["data"]]
    assert len(sim_run) == 1 and runs.read_config(sim_run[0])["config"]["preprocess"]["frame_align"] == "truth"


def test_cli_real_odometry_bad_group_is_one_line(building, tmp_path, monkeypatch, capsys):
    from conftest import run_cli

    code, out, err = run_cli(
        monkeypatch,
        capsys,
        "bench",
        "real-odometry",
        "--data",
        building / "building",
        "--out",
        tmp_path / "o",
        "--group-by",
        "floor_name",
        "--test-groups",
        "F77",
        "--models",
        "pdr",
    )
    assert code == 2 and err.count("\n") == 1 and "F77" in err


@pytest.mark.slow
def test_cli_real_odometry_reports_progress_without_a_terminal(building, tmp_path):
    """Issue 22: the suite was silent for minutes with stderr on a pipe; now each long step logs
    done/total and the time left (the interval made short here)."""
    import os
    import re
    import subprocess
    import sys
    from pathlib import Path

    env = dict(
        os.environ,
        PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"),
        OMP_NUM_THREADS="1",
        WEARNAV_PROGRESS_INTERVAL_S="0",
    )
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "wearnav",
            "bench",
            "real-odometry",
            "--data",
            str(building / "building"),
            "--out",
            str(tmp_path / "o"),
            "--group-by",
            "floor_name",
            "--test-groups",
            "F9",
            "--models",
            "pdr",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    assert any(re.fullmatch(r"prepare building: \d+ rec, \d+ s elapsed", l) for l in lines), lines
    assert any(re.fullmatch(r"preprocess: \d+/\d+ rec, \d+ s elapsed, about \d+ s left", l) for l in lines), lines
    assert "\r" not in res.stderr


@pytest.mark.slow
def test_a_heading_frame_model_is_also_scored_as_its_speed_along_the_phones_pointing(building, tmp_path):
    """issue 34: a learned heading-frame model's path, its PDR-speed hybrid, and its own speed along
    where the phone points, the last with its own site yaw (as pdr-pointing's) from the training
    traces. (That a world-frame run is not scored so and cannot be loaded that way is checked on
    the world-frame suitein++ run of test_benchmark_end_to_end_resumes_and_reports_both_buildings.)"""
    out = tmp_path / "bench"
    bench = RealBench(models=("ronin",), epochs=1, stride=25, heading_frame=True)
    run_benchmark(
        building / "building", out, group_by="floor_name", test_groups=("F9",), bench=bench, progress=False, echo=print
    )
    doc = json.loads((out / "results.json").read_text())
    table = {r["method"]: r for r in doc["sites"]["main"]["table"]}
    assert {
        "ronin",
        "ronin · PDR speed",
        "ronin · its speed, pointing",
        "ronin · cadence speed, pointing within 30°",
    } <= set(table)
    run = next((out / "runs").glob("ronin-*"))
    own = json.loads((run / "site_yaw_eval_main_pointing.json").read_text())
    assert own["by"] == "the model itself, speed pointing"
    assert table["ronin · its speed, pointing"]["site yaw (°)"] == own["yaw_deg"]
    assert table["ronin"]["site yaw (°)"] == doc["sites"]["main"]["yaw"]["yaw_deg"]  # trained under PDR's
    pointing = runs.read_metrics(run / "eval_main_pointing")
    assert pointing["speed"] == "pointing" and pointing["preprocess"]["yaw_deg"] == own["yaw_deg"]
    snapped = json.loads((run / "site_yaw_eval_main_snapped.json").read_text())  # its own yaw, too
    assert table["ronin · cadence speed, pointing within 30°"]["site yaw (°)"] == snapped["yaw_deg"]
    # the same speeds, another direction: each trace's path is as long along its samples
    for f in sorted((run / "eval_main" / "trajectories" / "test").glob("*.csv")):
        lengths = []
        for ev in ("eval_main", "eval_main_pointing"):
            xy = np.loadtxt(run / ev / "trajectories" / "test" / f.name, delimiter=",", skiprows=1, usecols=(1, 2))
            lengths.append(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())
        assert lengths[1] == pytest.approx(lengths[0], rel=0.02)


@pytest.mark.slow
def test_seeds_suite_pairs_each_path_with_pdr_by_walk(building, tmp_path):
    """`bench real-odometry --seeds`: a suite per seed sharing one prepared data folder, and one page
    with each path's statistics over the seeds and its difference from PDR, paired by walk."""
    from wearnav.bench.real_seeds import run_seeds

    out = tmp_path / "seeds"
    bench = RealBench(models=("pdr", "ronin"), epochs=1, stride=25)
    page = run_seeds(
        building / "building",
        out,
        (0, 1),
        bench,
        progress=False,
        echo=lambda s: None,
        group_by="floor_name",
        test_groups=("F9",),
    )
    assert (out / "seed-0" / "results.md").is_file() and (out / "seed-1" / "results.md").is_file()
    assert (out / "seed-1" / "data").resolve() == (out / "data").resolve()
    ronin = [p.name for s in (0, 1) for p in (out / f"seed-{s}" / "runs").glob("ronin-*")]
    assert len(set(ronin)) == 2  # one run per seed, different hashes
    doc = json.loads((out / "results.json").read_text())
    rows = {r["path"]: r for r in doc["sites"]["main"]["known_start"]}
    assert set(rows) >= {"ronin", "ronin · PDR speed", "pdr", "raw phone fixes"}
    assert rows["ronin"]["seeds"] == 2 and "±" in rows["ronin"]["median (m)"] and "±" in rows["ronin"]["arc ratio"]
    assert rows["pdr"]["minus PDR, median (m)"] == "—"
    # PDR's speed with ronin's direction, paired by walk with PDR: a difference and its interval
    d = rows["ronin · PDR speed"]["minus PDR, median (m)"]
    mid, lo, hi = (float(v) for v in d.replace("[", "").replace("]", "").replace(",", "").split())
    assert lo <= mid <= hi
    smoother = {r["smoother of"]: r for r in doc["sites"]["main"]["smoother"]}
    assert {"ronin", "pdr"} <= set(smoother)
    assert "over 2 seeds" in page.read_text()
    # the title says what sets the suite apart: where it was scored, how it read the fixes (at the
    # lag their training walks show, where they show one) and how long it trained
    lags = {c.get("fix_lag_s") for s in ("seed-0", "seed-1") for c in _calibrations(out / s)}
    lagged = ", the fixes read at the site's lag" if any(lags) else ""
    assert page.read_text().splitlines()[0].endswith(f"tested on standin{lagged} (1 epoch at most)")
    if any(lags):
        assert "s before its time stamp (the fixes' lag on the site's training walks" in page.read_text()
    # a loss other than the papers' MSE is named there too
    from dataclasses import replace

    from wearnav.bench.real_seeds import seeds_page

    polar = seeds_page(out, {s: out / f"seed-{s}" for s in (0, 1)}, replace(bench, vel_loss="polar"))
    assert "the learned models with the `polar` loss" in polar.read_text().splitlines()[0]


def _calibrations(suite) -> list[dict]:
    """The smoother's calibrations a suite used at its main site (results.json)."""
    doc = json.loads((suite / "results.json").read_text())
    return list(doc["sites"]["main"].get("calibration", {}).values())


@pytest.mark.slow
def test_map_aware_rows_where_the_site_has_floor_plans(tmp_path):
    """A site whose recordings carry floor plans (here: the simulator's corridors along each route)
    scores every path also map-aware, at the same points, with the walk-paired difference on the page."""
    sim = _simulate(tmp_path / "sim", 3, ("STW",), corridor_m=3.0)
    recs = [sim.load(n) for n in sim.names]
    built = _building(recs, 40.0)
    for rec, _ in built:
        assert rec.plans  # the corridors survive the stand-in's rewrite
    write_dataset(tmp_path / "building", built)
    out = tmp_path / "bench"
    bench = RealBench(models=("pdr",), epochs=1, stride=25)
    run_benchmark(
        tmp_path / "building", out, group_by="floor_name", test_groups=("F9", "F1"), bench=bench, progress=False
    )
    doc = json.loads((out / "results.json").read_text())
    table = {r["method"]: r for r in doc["sites"]["main"]["table"]}
    assert {"pdr", "pdr · map-aware"} <= set(table)
    assert table["pdr · map-aware"]["points"] == table["pdr"]["points"] > 0
    assert table["pdr · map-aware"]["median (m)"] < table["pdr"]["median (m)"]
    text = (out / "results.md").read_text()
    assert "map-aware minus map-less" in text
    m = runs.read_metrics(next((out / "runs").glob("pdr-*")) / "eval_main_map")
    assert m["map_aware"]["of"] == "eval_main" and m["map_aware"]["config"]["particles"] > 0
    # the error split along the walk and across it, for both rows at the same points
    assert "along, median (m)" in text and "across, p95 (m)" in text
    run, data = next((out / "runs").glob("pdr-*")), out / "data" / "main"
    along, across = along_across(run / "eval_main", data)
    along_map, across_map = along_across(run / "eval_main_map", data)
    assert along.size == along_map.size > 0 and across.size == along.size
    assert np.median(np.abs(across_map)) < np.median(np.abs(across))  # the corridor holds the path across it
    assert "along, signed median (m)" in text


def test_pages_say_whose_heading_frame_the_learned_models_take():
    """The first device of the layout gives the frame; the real walks carry the phone alone, so a
    model framed by the earbuds on the simulator takes the phone's there, and the pages say so."""
    assert frame_name(("phone", "watch", "earbuds")) == frame_name(None) == "the phone's heading frame"
    said = frame_name(("earbuds", "phone", "watch"))
    assert "of the earbuds" in said and "the phone's on the real walks" in said
