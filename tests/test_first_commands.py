"""The commands a newcomer tries first (issue 22 §2), run as a user runs them: ``python -m wearnav``
in a subprocess (in-process where only the words or the results are checked: a process costs
seconds of imports); each test checks the exit code and the words the user reads."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from wearnav import runs
from wearnav.dataset import Dataset, DatasetWriter, train_val_views
from wearnav.importers.sensorlogger_export import SIMULATED_DEVICE_NAME
from wearnav.recording import Trajectory
from wearnav.simulate import WalkConfig, simulate_recording

SRC = Path(__file__).resolve().parents[1] / "src"


def wearnav(*args, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, "-m", "wearnav", *map(str, args)],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture(scope="module")
def real_like(tmp_path_factory) -> Path:
    """What `wearnav import` makes of a real building: phone only, surveyed points every 10 s as
    truth, every recording in split ``train`` (no val, no test)."""
    root = tmp_path_factory.mktemp("real_like") / "ds"
    with DatasetWriter(root, {"made_by": "test_first_commands"}) as w:
        for i in range(5):
            rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=40), seed=i)
            keep = np.searchsorted(rec.truth.t, np.arange(rec.truth.t[0], rec.truth.t[-1], 10.0))
            w.add(
                dataclasses.replace(
                    rec,
                    name=f"walk{i}",
                    devices={"phone": rec.devices["phone"]},
                    truth=Trajectory(rec.truth.t[keep], rec.truth.pos[keep]),
                ),
                split="train",
            )
    return root


@pytest.mark.slow
def test_simulated_sensorlogger_export_imports_and_tracks_with_pdr_by_name(tmp_path, monkeypatch, capsys):
    p = wearnav("simulate", "--format", "sensorlogger", "--out", tmp_path / "walk")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["simulated"] is True
    assert SIMULATED_DEVICE_NAME in (tmp_path / "walk" / "Metadata.csv").read_text()
    p = wearnav("import", "sensorlogger", tmp_path / "walk", "--out", tmp_path / "ds")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["devices"] == {"phone": 1, "watch": 1, "earbuds": 1}
    p = wearnav("track", tmp_path / "walk", "--model", "pdr", "--out", tmp_path / "t")
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("model: pdr on the phone;")  # PDR reads one device (issue 58 §7)
    summary = json.loads((tmp_path / "t" / "track.json").read_text())
    assert (
        summary["model"] == "pdr" and summary["path"]["length_m"] > 50 and "heading_offset_deg" in summary["anchoring"]
    )
    assert (tmp_path / "t" / "trajectory.geojson").is_file()  # lat/lon made it there and back
    # the same steps along where the phone points (its heading frame): another path, the same length
    # (in-process: what is checked is the path, and a process costs seconds of imports)
    code, _, err = run_cli(
        monkeypatch, capsys, "track", tmp_path / "walk", "--model", "pdr-pointing", "--out", tmp_path / "p"
    )
    assert code == 0, err
    assert json.loads((tmp_path / "p" / "track.json").read_text())["model"] == "pdr-pointing"
    odometry = [pd.read_csv(tmp_path / d / "trajectory.csv")[["x", "y"]].to_numpy() for d in ("t", "p")]
    lengths = [np.linalg.norm(np.diff(xy, axis=0), axis=1).sum() for xy in odometry]  # before any anchoring
    # (rel: the velocity is interpolated between windows, and the two turn differently between them)
    assert lengths[1] == pytest.approx(lengths[0], rel=0.02) and np.abs(odometry[1] - odometry[0]).max() > 1.0


def test_model_names_that_are_not_untrained_baselines_are_refused_with_what_works(tmp_path):
    p = wearnav("track", "x.h5", "--model", "ronin", "--out", tmp_path / "t")
    assert p.returncode == 2
    assert p.stderr == (
        "error: ronin: is a model that must be trained first (wearnav train ronin --data DATA "
        "--out RUN, then --model RUN); shipped models: phone, phone-watch-earbuds; untrained baselines "
        "usable by name: pdr, pdr-cadence, pdr-pointing, pdr-pointing-cadence\n"
    )
    p = wearnav("track", "x.h5", "--model", "pdx", "--out", tmp_path / "t")
    assert p.returncode == 2 and "nor a model name (shipped models: phone, phone-watch-earbuds; untrained" in p.stderr
    assert "did you mean 'pdr'?" in p.stderr


@pytest.mark.parametrize(
    "command, model, words",
    [
        (
            "track",
            "har-cnn-bilstm",
            "is an activity classifier (har-cnn-bilstm), not an odometry model; use wearnav classify",
        ),
        (
            "classify",
            "ronin",
            "is an odometry model (ronin), not an activity classifier; use wearnav track (or wearnav eval)",
        ),
    ],
)
@pytest.mark.slow
def test_a_run_of_the_wrong_kind_says_what_it_is_and_which_command_takes_it(
    tmp_path, monkeypatch, capsys, command, model, words
):
    run = tmp_path / "run"
    run.mkdir()
    runs.write_config(run, {"train": {"model": model, "data": "somewhere"}})
    (tmp_path / "x.h5").touch()  # an input that exists: the model is refused before it is read
    args = (command, tmp_path / "x.h5", "--model", run, "--out", tmp_path / "o")
    if command == "track":  # a real process: exit 2 and its whole stderr the one line
        p = wearnav(*args)
        code, err = p.returncode, p.stderr
    else:  # the same refusal in-process (a process costs seconds: it imports torch before refusing)
        code, _, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2
    assert err == f"error: {run}: {words}\n"


@pytest.mark.slow
def test_training_on_a_dataset_without_val_or_test_uses_its_defaults_and_says_so(
    real_like, tmp_path, monkeypatch, capsys
):
    # in-process: what is checked is the words (a process costs seconds of imports)
    code, _, err = run_cli(
        monkeypatch, capsys, "train", "ionet", "--data", real_like, "--out", tmp_path / "run", "--epochs", "1"
    )
    assert code == 0, err
    train, val, note = train_val_views(Dataset.open(real_like), "train", "val")
    lines = err.splitlines()
    assert lines[:2] == [
        "devices: phone (those the dataset's recordings have)",
        "truth: surveyed points (0.10 per second), joined by straight lines across gaps up to 60 s "
        "into training targets",
    ]
    assert note in lines and note.startswith(f"no 'val' split in the dataset: validating on {len(val)} of its 5")
    assert any(n.startswith("the dataset has no 'test' split (its splits: train): not evaluated") for n in lines)
    training = json.loads((tmp_path / "run" / "training.json").read_text())
    assert training["validation"] == note and training["epochs_run"] == 1
    assert sorted(train.names + val.names) == [f"walk{i}" for i in range(5)] and len(val) >= 1


@pytest.mark.parametrize(
    "args, words",
    [
        (("train", "pdr", "--devices", "phone,watc"), "unknown device(s) ['watc']; valid: phone"),
        (("bench", "odometry", "--models", "ronin,ronn"), "unknown odometry model(s) ['ronn']; valid: "),
        (("bench", "real-odometry", "--models", "ronn"), "unknown odometry model(s) ['ronn']; valid: "),
        (("bench", "har", "--techniques", "baselin", "--quick"), "unknown technique(s) ['baselin']; valid: baseline,"),
    ],
)
def test_names_are_checked_before_any_work_with_the_valid_ones(real_like, monkeypatch, capsys, tmp_path, args, words):
    data = () if args[1] == "har" else ("--data", real_like)
    # in-process: a subprocess costs seconds (a real process's one-line stderr is checked by
    # test_a_run_of_the_wrong_kind_says_what_it_is_and_which_command_takes_it)
    code, out, err = run_cli(monkeypatch, capsys, *args, *data, "--out", tmp_path / "o")
    assert code == 2, err
    assert words in err and err.count("\n") == 1 and out == ""
    assert not (tmp_path / "o").exists()  # refused before anything was written


@pytest.mark.parametrize(
    "args, words",
    [  # the same check
        (("bench", "efficiency", "--models", "pdr,ronn"), "unknown model(s) ['ronn']; valid: "),
        (("demo", "--models", "ronn"), "unknown odometry model(s) ['ronn']; valid: "),
        (
            ("bench", "easytrack", "--quick", "--methods", "easytrak"),
            "unknown method(s) ['easytrak']; valid: easytrack,",
        ),
    ],
)
def test_more_names_are_checked_first(monkeypatch, capsys, tmp_path, args, words):
    code, out, err = run_cli(monkeypatch, capsys, *args, "--out", tmp_path / "o")
    assert code == 2 and words in err and out == ""
    assert not (tmp_path / "o").exists()
