"""`wearnav train / eval / bench odometry / results` end to end on the tiny preset, and their errors."""

import json
from dataclasses import replace

import pytest

from conftest import run_cli
from test_train_odometry import TinyGait  # noqa: F401  (registers "test-mlp")
from wearnav import runs
from wearnav.dataset import Dataset, DatasetWriter

run = run_cli


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """Part of the tiny preset (seed 1): the first walk of each split and phone placement, so every
    split and placement the suite's tables read (in `test` and `cross_subject` one walk in hand, HD,
    and one multi-placement, MP; in `test_unseen` the pocket and the bag), simulated as
    ``simulate_dataset("tiny", seed=1)`` simulates them: 10 walks instead of 32, as evaluating and
    plotting cost per walk."""
    from wearnav.simulate import simulate_dataset

    def first_of_each(plan):
        seen, kept = set(), []
        for w in plan:
            if (w.split, w.config.placement) not in seen:
                seen.add((w.split, w.config.placement))
                kept.append(w)
        return kept

    root = tmp_path_factory.mktemp("tiny-part") / "tiny"
    simulate_dataset("tiny", root, seed=1, progress=False, select=first_of_each)
    return root


@pytest.mark.slow
def test_train_then_eval(tiny, tmp_path, monkeypatch, capsys):
    code, out, err = run(
        monkeypatch,
        capsys,
        "train",
        "test-mlp",
        "--data",
        tiny,
        "--out",
        tmp_path / "run",
        "--epochs",
        "2",
        "--batch",
        "64",
    )
    assert code == 0, err
    assert (tmp_path / "run" / "metrics.json").is_file()
    code, out, err = run(monkeypatch, capsys, "eval", tmp_path / "run", "--split", "test,cross_subject")
    assert code == 0, err
    summary = json.loads(out[: out.rindex("}") + 1])
    assert summary["test"]["sequences"] == 2 and summary["cross_subject"]["sequences"] == 2  # each: HD, MP
    assert summary["test"]["ate_mean"] > 0
    # the same command again resumes nothing and keeps the run's config
    code, _, err = run(
        monkeypatch,
        capsys,
        "train",
        "test-mlp",
        "--data",
        tiny,
        "--out",
        tmp_path / "run",
        "--epochs",
        "3",
        "--batch",
        "64",
    )
    assert code == 2 and "another configuration" in err and err.count("\n") == 1


@pytest.mark.slow
def test_bench_suite_resumes_and_results_page(tiny, tmp_path, monkeypatch, capsys):
    args = (
        "bench",
        "odometry",
        "--data",
        tiny,
        "--out",
        tmp_path / "odometry",
        "--models",
        "test-mlp",
        "--epochs",
        "1",
        "--seeds",
        "0,1",
    )
    code, out, err = run(monkeypatch, capsys, *args)
    assert code == 0, err
    assert out.count(": done in ") == 2 and "skipped" not in out  # one run per seed
    assert len(list((tmp_path / "odometry").glob("test-mlp-*/metrics.json"))) == 2
    code, out, err = run(monkeypatch, capsys, *args)
    assert code == 0 and out.count("complete, skipped") == 2
    page = (tmp_path / "odometry" / "results.md").read_text()
    assert "## Table III: split `cross_subject`" in page and "| test-mlp |" in page and "Table VI" in page
    metrics = json.loads(next((tmp_path / "odometry").glob("test-mlp-*/metrics.json")).read_text())
    assert set(metrics["splits"]["test"]["by_placement"]) == {"HD", "MP"}  # Table IV's placements
    assert set(metrics["splits"]["test_unseen"]["by_placement"]) == {"PK", "BG"}
    # issue 16 §1: scored in the honest frame, and once more in the old frame as a diagnostic
    run_dir = next((tmp_path / "odometry").glob("test-mlp-*/metrics.json")).parent
    assert metrics["test_frame"] == "initial"
    assert json.loads((run_dir / "diagnostic-truth-frame" / "metrics.json").read_text())["test_frame"] == "truth"
    assert "## What the honest test frame costs" in page
    # a third seed asked for but not run: the page says so
    code, out, err = run(monkeypatch, capsys, *args[:-1], "0,1,2", "--report-only")
    assert code == 0, err
    assert "| 2 of 3 " in (tmp_path / "odometry" / "results.md").read_text()
    assert not list((tmp_path / "odometry").glob("test-mlp-*/training.json"))[2:]  # nothing trained
    # the folder answers a registered question (bench.questions.QUESTIONS: the simulator's tables)
    code, out, err = run(
        monkeypatch, capsys, "results", tmp_path / "odometry", "--out", tmp_path / "docs" / "results.md"
    )
    assert code == 0, err
    doc = (tmp_path / "docs" / "results.md").read_text()
    assert (
        "how does Suite-IN++ compare with its baselines" in doc
        and "Odometry comparison" in doc
        and "Table III: split `test`" in doc
        and "| 2 of 3 " in doc
    )


def test_one_line_errors(tiny, tmp_path, monkeypatch, capsys):
    code, _, err = run(monkeypatch, capsys, "train", "no-such-model", "--data", tiny, "--out", tmp_path / "a")
    assert code == 2 and "unknown model" in err and err.count("\n") == 1
    assert not (tmp_path / "a").exists()
    # a dataset without truth cannot train an odometry model
    ds = Dataset.open(tiny)
    with DatasetWriter(tmp_path / "notruth") as w:
        for name in ds.names[:8]:
            rec = ds.load(name)
            w.add(replace(rec, truth=None), split=ds.manifest.set_index("name").loc[name, "split"])
    code, _, err = run(
        monkeypatch, capsys, "train", "test-mlp", "--data", tmp_path / "notruth", "--out", tmp_path / "b"
    )
    assert code == 2 and "no training data" in err and err.count("\n") == 1
    assert not (tmp_path / "b").exists()
    code, _, err = run(monkeypatch, capsys, "eval", tmp_path / "nowhere")
    assert code == 2 and "not a run folder" in err


@pytest.mark.slow
def test_bench_devices_set_every_runs_layout_and_whose_heading_frame(tiny, tmp_path, monkeypatch, capsys):
    """`bench odometry --devices`: every run's layout in that order, so with --heading-frame the first
    device present gives the frame (the earbuds here); the page says whose; an unknown device is one
    line before any run."""
    base = ("bench", "odometry", "--data", tiny, "--models", "test-mlp", "--epochs", "1", "--heading-frame")
    code, _, err = run(monkeypatch, capsys, *base, "--out", tmp_path / "bad", "--devices", "earbuds,phne")
    assert code == 2 and "unknown device(s) ['phne']" in err and err.count("\n") == 1
    assert not (tmp_path / "bad").exists()
    code, _, err = run(monkeypatch, capsys, *base, "--out", tmp_path / "bad", "--augment", "drop_devics")
    assert code == 2 and "unknown augmentation 'drop_devics'" in err and err.count("\n") == 1
    assert not (tmp_path / "bad").exists()
    layout = ("--devices", "earbuds,phone,watch", "--augment", "rotate_yaw,drop_devices")
    code, _, err = run(monkeypatch, capsys, *base, "--out", tmp_path / "s", *layout)
    assert code == 0, err
    cfg = runs.read_config(next((tmp_path / "s").glob("test-mlp-*")))["config"]
    assert cfg["preprocess"]["devices"] == ["earbuds", "phone", "watch"] and cfg["preprocess"]["heading_frame"]
    assert cfg["train"]["augment"] == ["drop_devices"]  # the heading frame leaves random yaw out
    page = (tmp_path / "s" / "results.md").read_text()
    assert "heading frame of the earbuds (else the next device present)" in page
    assert "augmented with `drop_devices`" in page.splitlines()[0]
