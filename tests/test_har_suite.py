"""HAR benchmark plumbing beyond the quick real-data test (tests/test_har.py): the simulator's
placement dataset as a built-in benchmark dataset, ``--jobs 2`` giving the same runs as one
process, and `wearnav classify` on a Sensor Logger export end to end."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
import yaml

from conftest import run_cli
from wearnav import runs
from wearnav.bench import har
from wearnav.bench.executor import Execution
from wearnav.dataset import Dataset
from wearnav.errors import ConfigError
from wearnav.simulate.config import PHONE_HOLDS
from wearnav.simulate.presets import SINGLE_HOLDS, plan_placement_dataset
from wearnav.train.classify import split_view

SIM = har.DATASETS["sim-placement"]


@pytest.fixture(autouse=True)
def one_thread():
    """Tiny models on a shared 2-core machine: two spinning OpenMP threads only wait on each other."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


@pytest.fixture(scope="module")
def sim_quick(tmp_path_factory) -> Path:
    """The --quick simulated placement dataset (4 walkers × 6 walks of 20–25 s), generated once."""
    out = tmp_path_factory.mktemp("simq")
    return har.import_data(SIM, Path("unused"), out, quick=True)


def test_placement_plan_every_walker_every_hold_phone_only():
    plan = plan_placement_dataset(subjects=4, duration_s=(20.0, 25.0), seed=3)
    assert len(plan) == 4 * (len(SINGLE_HOLDS) + 1)
    by_subject: dict[str, list] = {}
    for p in plan:
        by_subject.setdefault(p.config.subject.name, []).append(p.config)
        assert p.config.devices == ("phone",) and 20.0 <= p.config.duration_s <= 25.0
    assert sorted(by_subject) == ["u1", "u2", "u3", "u4"]
    for cfgs in by_subject.values():
        assert sorted(c.phone_hold for c in cfgs if c.mode == "STW") == sorted(h for _, h in SINGLE_HOLDS)
        assert [c.placement for c in cfgs if c.mode != "STW"] == ["MP"]
    # a pure function of the seed; another seed, other walks
    assert plan_placement_dataset(4, (20.0, 25.0), 3) == plan
    assert [p.seed for p in plan_placement_dataset(4, (20.0, 25.0), 4)] != [p.seed for p in plan]
    with pytest.raises(ConfigError, match="at least 2 subjects"):
        plan_placement_dataset(subjects=1)


def test_sim_placement_dataset_labels_and_subject_split(sim_quick):
    ds = Dataset.open(sim_quick)
    assert len(ds) == 4 * 6 and set(ds.manifest["devices"]) == {"phone"}
    seen = set()
    for name in ds.names:
        rec = ds.load(name)
        lab = rec.labels[rec.labels["kind"] == "placement"]
        values = set(lab["value"]) - {"transition"}
        seen |= values
        if rec.meta["mode"] == "STW":  # a single hold: the one the walk's name says
            assert values == {name.split("_", 2)[2]}
        else:  # multi-placement: several holds with moves between them
            assert len(values) >= 2 and "transition" in set(lab["value"])
    assert seen <= set(PHONE_HOLDS) and len(seen) >= 5
    assert set(SIM.classes) == set(PHONE_HOLDS)
    tr = set(split_view(ds, SIM.scheme, "train").manifest["subject"])
    te = set(split_view(ds, SIM.scheme, "test").manifest["subject"])
    assert tr == {"u1", "u2", "u3"} and te == {"u4"}


def _results(root: Path) -> dict:
    """(technique, seed) → what a run's config and metrics say, minus timings and paths."""
    out = {}
    for run in sorted(root.glob("*/*")):
        assert runs.is_complete(run), run
        train = yaml.safe_load((run / "config.yaml").read_text())["config"]["train"]
        m = json.loads((run / "metrics.json").read_text())
        t = m.pop("training")
        for k in ("wall_s", "s_per_epoch"):
            t.pop(k)
        out[(run.name.rsplit("-", 1)[0], train["seed"])] = {
            "train": {k: v for k, v in train.items() if k != "data"},
            "metrics": m,
            "training": t,
        }
    return out


def test_jobs_2_gives_the_same_runs_as_one_process(sim_quick, tmp_path):
    """Four runs (2 techniques × 2 seeds) in one process and spread over two: every run folder
    complete, configs equal, and the seeded training gives identical metrics."""
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        shutil.copytree(sim_quick.parent, out / "data")  # the same generated data, not regenerated
    kw = dict(datasets=["sim-placement"], seeds=2, quick=True, techniques=["baseline", "rot_z"], echo=lambda s: None)
    har.run_benchmark(Path("unused"), a, **kw)
    har.run_benchmark(Path("unused"), b, execution=Execution(jobs=2, threads=1), **kw)
    ra, rb = _results(a / "runs"), _results(b / "runs")
    assert sorted(ra) == [("baseline", 0), ("baseline", 1), ("rot_z", 0), ("rot_z", 1)]
    assert ra == rb
    assert ra[("baseline", 0)]["training"]["classes"] == list(SIM.classes)
    assert ra[("rot_z", 0)]["training"]["train_windows_expanded"] == 2 * ra[("rot_z", 0)]["training"]["train_windows"]
    page = (b / "results.md").read_text()
    assert "## sim-placement" in page and "world-frame input" in page
    doc = json.loads((b / "results.json").read_text())
    assert doc["datasets"]["sim-placement"]["baseline"]["seeds"] == 2
    # a second invocation (nothing left to train) adds its wall time to the first's
    first = doc["invocations"]
    assert len(first) == 1 and first[0]["wall_s"] > 0
    har.run_benchmark(Path("unused"), b, execution=Execution(jobs=2, threads=1), **kw)
    doc2 = json.loads((b / "results.json").read_text())
    assert doc2["invocations"][0] == first[0] and len(doc2["invocations"]) == 2
    assert "over 2 invocations" in (b / "results.md").read_text()


def test_steps_budget_sets_each_datasets_epochs(sim_quick, tmp_path):
    """--steps: epochs = round(steps / batches per epoch) of the un-augmented training set, at
    least 1, recorded in each run's config; --epochs and --steps together are refused."""
    from wearnav.train.classify import ClassifyConfig, _windows, sequences

    cfg = ClassifyConfig(
        model=har.BASELINE, data=str(sim_quick), scheme=SIM.scheme, label_kind=SIM.label_kind, classes=SIM.classes
    )
    n = len(_windows(sequences(split_view(Dataset.open(sim_quick), SIM.scheme, "train"), cfg), cfg, SIM.classes))
    batches = -(-n // 64)
    assert batches > 1
    assert har.epochs_for_steps(SIM, sim_quick, 3 * batches) == 3
    assert har.epochs_for_steps(SIM, sim_quick, 3 * batches + batches // 2 - 1) == 3
    assert har.epochs_for_steps(SIM, sim_quick, 1) == 1
    with pytest.raises(ConfigError, match="not both"):
        har.run_benchmark(Path("unused"), tmp_path, datasets=["sim-placement"], quick=True, epochs=2, steps=10)


def test_classify_a_sensor_logger_export_end_to_end(sim_quick, tmp_path, monkeypatch, capsys):
    """Train a tiny placement classifier on the simulated walkers, write a new simulated
    multi-placement walk as a Sensor Logger export (iOS, g units, split gravity), and label it."""
    from wearnav.importers import sensorlogger
    from wearnav.importers.sensorlogger_export import write_export
    from wearnav.simulate.config import WalkConfig, sample_subject
    from wearnav.simulate.walk import simulate_walk
    from wearnav.train.classify import ClassifyConfig, fit, prepare_run

    cfg = ClassifyConfig(
        model=har.BASELINE,
        data=str(sim_quick),
        scheme=SIM.scheme,
        label_kind="placement",
        classes=SIM.classes,
        epochs=1,
        max_train_windows=256,
        model_args={"hidden": 16},
    )
    run = prepare_run(cfg, tmp_path / "run")
    fit(cfg, run, progress=False)

    walker = sample_subject(np.random.default_rng(11), "me")
    rec = simulate_walk(
        WalkConfig(name="mine", subject=walker, mode="PVW", placement="MP", duration_s=40.0, devices=("phone",)), seed=5
    ).recording
    export = write_export(rec, tmp_path / "Mine-2024-05-01_10-00-00", platform="ios")
    imported = next(sensorlogger.read(export))
    code, out, err = run_cli(monkeypatch, capsys, "classify", export, "--model", run, "--out", tmp_path / "lab")
    assert code == 0, err
    csvs = list((tmp_path / "lab").glob("*_intervals.csv"))
    pngs = list((tmp_path / "lab").glob("*_timeline.png"))
    assert len(csvs) == 1 and len(pngs) == 1 and pngs[0].stat().st_size > 1000
    assert csvs[0].name == f"{imported.name}_intervals.csv"
    iv = pd.read_csv(csvs[0])
    assert list(iv.columns) == ["start_s", "end_s", "label", "windows", "mean_confidence"]
    # every window of the 50 Hz aligned recording is labelled once
    from wearnav.preprocess import align

    seq = align(imported, cfg.preprocess_config())
    n_windows = (len(seq) - cfg.window) // (cfg.window // 2) + 1
    assert iv["windows"].sum() == n_windows
    # a window unlike any the model trained on is labelled unknown (issue 35 §3)
    assert set(iv["label"]) <= set(SIM.classes) | {"unknown"}
    assert ((iv["mean_confidence"] > 0) & (iv["mean_confidence"] <= 1)).all()
    # contiguous intervals covering the windows: from the first window's start to the last's end
    assert (iv["end_s"] > iv["start_s"]).all() and np.allclose(iv["start_s"].iloc[1:], iv["end_s"].iloc[:-1])
    assert iv["start_s"].iloc[0] == pytest.approx(seq.t[0], abs=1e-3)
    last_end = seq.t[(n_windows - 1) * (cfg.window // 2) + cfg.window - 1]
    assert iv["end_s"].iloc[-1] == pytest.approx(last_end, abs=1e-3)
    assert seq.t[-1] - last_end < cfg.window / cfg.rate  # less than one window left unlabelled
    assert seq.t[-1] - seq.t[0] == pytest.approx(40.0, abs=1.0)
