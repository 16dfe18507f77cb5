"""One training spread over two processes (Lightning DDP on CPU, gloo) is the training of one
process: each process takes half of every batch (WindowDataset.loader(shard=True)), DDP averages
the two halves' gradients, which is the whole batch's gradient, so the logged losses and the
weights agree up to float32 summation order.

The run goes through Lightning's real 'ddp' strategy, which starts the second process by re-running
the command: the training is a small script run in a subprocess (a pytest process cannot be
re-run that way). The model has no dropout or batch norm, and training here has no augmentation:
those draw per process, so with them the two trainings are equal in distribution only."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

SCRIPT = textwrap.dedent("""
    import json, sys
    import torch
    from torch import nn
    from wearnav.models.base import OdometryModel
    from wearnav.models.registry import register
    from wearnav.train.odometry import TrainConfig, fit

    @register("ddp-test", task="odometry", layout="concat", description="test model: no dropout, no batch norm")
    class Lin(OdometryModel):
        def __init__(self, n_devices=3, window=100):
            super().__init__()
            self.head = nn.Linear(4 * n_devices, 2)

        def forward(self, x, mask):
            dz = torch.diff(x[..., 2], dim=-1)
            feat = torch.cat([(x[..., 1:, :2] * dz[..., None]).mean(dim=2), x[..., :2].std(dim=2)], -1)
            return self.head((feat * mask[..., None]).flatten(1))

    data, run, devices, strategy = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    torch.set_num_threads(1)
    cfg = TrainConfig(model="ddp-test", data=data, epochs=3, patience=5, batch=64, lr=1e-2, augment=())
    print(json.dumps(fit(cfg, run, progress=False, devices=devices, strategy=strategy)))
""")


@pytest.fixture(scope="module")
def tiny(tiny_dataset, tmp_path_factory) -> Path:
    """Three training recordings (three walking modes), one validation and one test recording of
    the tiny dataset: ~200 training windows, 4 batches of 64 an epoch (every process reads and
    windows the data of its own)."""
    from wearnav.dataset import Dataset, write_dataset

    ds = Dataset.open(tiny_dataset(0))
    m = ds.manifest.set_index("name")
    split = m["split"]
    train = m[split == "train"].drop_duplicates("mode").index[:3].tolist()
    pick = train + [n for n in ds.names if split[n] == "val"][:1] + [n for n in ds.names if split[n] == "test"][:1]
    return write_dataset(tmp_path_factory.mktemp("data") / "small", [(ds.load(n), split[n]) for n in pick]).root


def _train(tmp_path: Path, data: Path, name: str, devices: int, strategy: str) -> tuple[dict, pd.DataFrame, dict]:
    script = tmp_path / "train_ddp.py"
    script.write_text(SCRIPT)
    run = tmp_path / name
    env = {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "PYTHONPATH": os.pathsep.join(
            [str(Path(__file__).resolve().parents[1] / "src"), os.environ.get("PYTHONPATH", "")]
        ),
    }
    p = subprocess.run(
        [sys.executable, str(script), str(data), str(run), str(devices), strategy],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr[-3000:]
    record = json.loads(p.stdout.strip().splitlines()[-1])
    log = pd.read_csv(run / "logs" / "version_0" / "metrics.csv")
    weights = torch.load(run / "checkpoints" / "last.ckpt", map_location="cpu", weights_only=False)["state_dict"]
    return record, log, weights


@pytest.mark.ddp
@pytest.mark.slow
def test_ddp_on_two_processes_trains_as_one_process(tiny, tmp_path):
    one, log1, w1 = _train(tmp_path, tiny, "one", 1, "auto")
    two, log2, w2 = _train(tmp_path, tiny, "two", 2, "ddp")
    assert one["processes"] == 1 and two["processes"] == 2
    assert one["train_windows"] == two["train_windows"] and one["epochs_run"] == two["epochs_run"] == 3
    l1 = log1.dropna(subset=["train/loss"])[["step", "train/loss"]].to_numpy()
    l2 = log2.dropna(subset=["train/loss"])[["step", "train/loss"]].to_numpy()
    assert len(l1) >= 3 and np.array_equal(l1[:, 0], l2[:, 0])
    # the training moved (the comparison is not of a model that learns nothing) ...
    assert abs(l1[-1, 1] - l1[0, 1]) > 1e-3 * l1[0, 1]
    # ... and the two trainings agree to float32 summation order: measured 7e-8 relative on the
    # logged losses of 3 epochs (48 steps of 64, on the whole tiny dataset), 3e-8 absolute on
    # weights of size up to 0.7
    np.testing.assert_allclose(l2[:, 1], l1[:, 1], rtol=1e-5)
    v1 = log1.dropna(subset=["val/vel_mse"])["val/vel_mse"].to_numpy()
    v2 = log2.dropna(subset=["val/vel_mse"])["val/vel_mse"].to_numpy()
    np.testing.assert_allclose(v2, v1, rtol=1e-3)  # halves of a validation batch can differ by one window
    for k in w1:
        np.testing.assert_allclose(w2[k].numpy(), w1[k].numpy(), rtol=1e-5, atol=1e-6)


def test_sharded_batches_split_every_batch_between_processes(monkeypatch):
    """What each process of a DDP training draws: its part of every batch of the one-process order."""
    from wearnav.preprocess.windows import BatchSampler

    one = list(BatchSampler(203, 64, seed=5))
    assert [len(b) for b in one] == [64, 64, 64, 11]
    parts = []
    for rank in range(2):
        s = BatchSampler(203, 64, seed=5, shard=True)
        monkeypatch.setattr(s, "_rank_world", lambda r=rank: (r, 2))
        parts.append(list(s))
        assert len(s) == len(parts[-1]) == 4
    for k, batch in enumerate(one):
        assert sorted(parts[0][k] + parts[1][k]) == sorted(batch)
        assert abs(len(parts[0][k]) - len(parts[1][k])) <= 1
    # not sharded (evaluation, or no process group): the whole batch
    assert list(BatchSampler(203, 64, seed=5, shard=False)) == one
    # a last batch smaller than the number of processes is dropped on every process
    s = BatchSampler(129, 64, seed=5, shard=True)
    monkeypatch.setattr(s, "_rank_world", lambda: (1, 2))
    assert len(s) == len(list(s)) == 2


@pytest.mark.ddp
@pytest.mark.slow
def test_wearnav_train_num_devices_2_ddp_from_the_command_line(tiny, tmp_path):
    """`wearnav train --num-devices 2 --strategy ddp`: Lightning re-runs the command for rank 1,
    which stops after training; rank 0 alone writes the run and prints once. The run's config is
    the one-device run's (how it ran is in training.json only)."""
    from wearnav import runs
    from wearnav.train.odometry import TrainConfig, run_record

    env = {
        **os.environ,
        "OMP_NUM_THREADS": "1",
        "PYTHONPATH": os.pathsep.join(
            [str(Path(__file__).resolve().parents[1] / "src"), os.environ.get("PYTHONPATH", "")]
        ),
    }
    run = tmp_path / "run"
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "wearnav",
            "train",
            "ronin",
            "--data",
            str(tiny),
            "--out",
            str(run),
            "--epochs",
            "1",
            "--batch",
            "64",
            "--num-devices",
            "2",
            "--strategy",
            "ddp",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.count('"training"') == 1 and p.stdout.count('"test"') == 1
    assert json.loads((run / "training.json").read_text())["processes"] == 2 and runs.is_complete(run)
    cfg = TrainConfig(model="ronin", data=str(tiny), epochs=1, batch=64)
    assert runs.read_config(run)["config"] == run_record(cfg)
