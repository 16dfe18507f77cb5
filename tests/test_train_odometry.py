"""The odometry training/evaluation core on the tiny simulator preset with a tiny model."""

import json

import numpy as np
import pytest
import torch
from torch import nn

from wearnav import runs
from wearnav.errors import ConfigError, FormatError, ValidationError
from wearnav.evaluate import evaluate_run
from wearnav.models.base import OdometryModel
from wearnav.models.registry import register
from wearnav.train.odometry import TrainConfig, fit, load_model, prepare_run


@register("test-mlp", task="odometry", layout="concat", description="tiny gait-phase model used by the core's tests")
class TinyGait(OdometryModel):
    """A deliberately small but physically meaningful model: in walking, the forward acceleration
    leads the vertical one by about 90°, so mean(a_h · da_z/dt) over a window points along the
    walking direction. A learned 2×2 map per device (and a dropout, so seeding matters) turns that
    vector into a velocity."""

    default_lr = 2e-3  # its "paper" value, for the recipe test

    def __init__(self, n_devices=3, window=100, hidden=16):
        super().__init__()
        self.maps = nn.Parameter(torch.zeros(n_devices, 2, 2))
        self.drop = nn.Dropout(0.1)

    def forward(self, x, mask):
        dz = torch.diff(x[..., 2], dim=-1)
        feat = (x[..., 1:, :2] * dz[..., None]).mean(dim=2)  # (B, D, 2)
        feat = self.drop(feat) * mask[..., None]
        return torch.einsum("bdj,dij->bi", feat, self.maps)


@pytest.fixture(scope="module")
def tiny(tiny_dataset):
    return tiny_dataset(0)


def _cfg(tiny, **kw):
    base = dict(model="test-mlp", data=str(tiny), epochs=3, patience=5, batch=64, lr=3e-3, augment=())
    base.update(kw)
    return TrainConfig(**base)


def test_train_evaluate_writes_a_complete_run(tiny, tmp_path):
    cfg = _cfg(tiny)
    run = prepare_run(cfg, tmp_path / "run")
    training = fit(cfg, run, progress=False)
    assert training["epochs_run"] == 3 and training["train_windows"] > 500
    assert (run / "checkpoints" / "best.ckpt").is_file() and (run / "checkpoints" / "last.ckpt").is_file()
    m = evaluate_run(run, splits=("test",), progress=False, training=training)
    assert runs.is_complete(run)
    s = m["splits"]["test"]["summary"]
    assert s["sequences"] == 5 and s["skipped"] == 0
    # each sequence's ATE equals the RMS of its stored per-timestamp errors
    for row in m["splits"]["test"]["sequences"]:
        traj = np.loadtxt(run / "trajectories" / "test" / f"{row['name']}.csv", delimiter=",", skiprows=1)
        assert row["ate"] == pytest.approx(np.sqrt(np.mean(traj[:, 5] ** 2)), rel=1e-3)
        assert traj[0, 1] == pytest.approx(traj[0, 3]) and traj[0, 2] == pytest.approx(traj[0, 4])
    assert set(m["splits"]["test"]["by_mode"]) == {"STW", "PVW", "MVW", "DRW", "DLW"}
    for png in ("test_trajectories.png", "test_error_cdf.png", "test_ate_box.png"):
        assert (run / "plots" / png).stat().st_size > 5000
    doc = runs.read_config(run)
    assert doc["config"]["train"]["model"] == "test-mlp" and doc["provenance"]["wearnav"]
    assert json.loads((run / "metrics.json").read_text())["training"]["epochs_run"] == 3


def test_learning_beats_a_zero_velocity_guess(tiny, tmp_path):
    """Trained through the core (frames aligned to truth, rotate_yaw augmentation), the tiny gait
    model must find the walking direction on held-out test walks. Measured on the calibrated
    simulator: velocity MSE 0.75 against 1.15 for standing still, direction error median 23°
    (an untrained model: ratio 1, median 90°)."""
    cfg = _cfg(tiny, epochs=8, augment=("rotate_yaw",))
    run = prepare_run(cfg, tmp_path / "run")
    fit(cfg, run, progress=False)
    model, _ = load_model(run)
    from wearnav.dataset import Dataset
    from wearnav.preprocess import load_sequences
    from wearnav.preprocess.windows import WindowDataset

    wds = WindowDataset(load_sequences(Dataset.open(tiny).split("test"), cfg), cfg.window_config())
    b = wds[list(range(len(wds)))]
    with torch.no_grad():
        p = model(b["x"], b["mask"])
    v = b["vel"]
    assert ((p - v) ** 2).sum(1).mean() < 0.8 * (v**2).sum(1).mean()
    ang = torch.atan2(p[:, 1], p[:, 0]) - torch.atan2(v[:, 1], v[:, 0])
    ang = torch.rad2deg(torch.remainder(ang + np.pi, 2 * np.pi) - np.pi).abs()
    assert ang.median() < 35.0


class _Kill(Exception):
    pass


def test_interrupted_and_resumed_run_ends_like_an_uninterrupted_one(tiny, tmp_path, monkeypatch):
    import lightning as L

    cfg = _cfg(tiny, epochs=3)
    ref = prepare_run(cfg, tmp_path / "ref")
    fit(cfg, ref, progress=False)
    ref_m = evaluate_run(ref, progress=False)

    # kill the second run in the middle of its second epoch
    class Killer(L.Callback):
        def on_train_batch_end(self, trainer, module, outputs, batch, batch_idx):
            if trainer.current_epoch == 1 and batch_idx == 3:
                raise _Kill()

    orig = L.Trainer.__init__

    def patched(self, *a, callbacks=(), **kw):
        orig(self, *a, callbacks=[*callbacks, Killer()], **kw)

    run = prepare_run(cfg, tmp_path / "resumed")
    monkeypatch.setattr(L.Trainer, "__init__", patched)
    with pytest.raises(_Kill):
        fit(cfg, run, progress=False)
    monkeypatch.setattr(L.Trainer, "__init__", orig)
    assert (run / "checkpoints" / "last.ckpt").is_file()
    training = fit(cfg, run, progress=False)
    assert training["resumed"]
    m = evaluate_run(run, progress=False)
    for a, b in zip(ref_m["splits"]["test"]["sequences"], m["splits"]["test"]["sequences"]):
        assert a["ate"] == pytest.approx(b["ate"], rel=1e-6)
        assert a["rte"] == pytest.approx(b["rte"], rel=1e-6)


def test_a_finished_run_is_kept_not_resumed(tiny, tmp_path):
    """Fitting a run whose training ended for good (all its epochs, or stopped early) again trains
    nothing and returns its record (the checkpoint is untouched); one stopped by its time budget
    would resume."""
    cfg = _cfg(tiny, epochs=2)
    run = prepare_run(cfg, tmp_path / "r")
    first = fit(cfg, run, progress=False)
    best = run / "checkpoints" / "best.ckpt"
    stamp = best.stat().st_mtime_ns
    again = fit(cfg, run, progress=False)
    assert again == first and not again["resumed"] and best.stat().st_mtime_ns == stamp
    rec = json.loads((run / "training.json").read_text())
    (run / "training.json").write_text(json.dumps({**rec, "epochs_run": 1, "stopped_by": "early stopping"}))
    assert fit(cfg, run, progress=False)["stopped_by"] == "early stopping" and best.stat().st_mtime_ns == stamp
    (run / "training.json").write_text(json.dumps({**rec, "epochs_run": 1, "stopped_by": "max time"}))
    assert fit(cfg, run, progress=False)["resumed"]


def test_bad_configurations_are_one_line_errors(tiny, tmp_path):
    with pytest.raises(ConfigError, match="unknown model"):
        fit(_cfg(tiny, model="nope"), tmp_path / "r", progress=False)
    with pytest.raises(ConfigError):
        _cfg(tiny, epochs=0)
    run = prepare_run(_cfg(tiny), tmp_path / "r2")
    with pytest.raises(ConfigError, match="another configuration"):
        prepare_run(_cfg(tiny, seed=1), run)
    with pytest.raises(ValidationError, match="unknown split"):
        fit(_cfg(tiny, val_split="nosuch"), tmp_path / "r3", progress=False)
    (run / "checkpoints").mkdir(exist_ok=True)
    (run / "checkpoints" / "best.ckpt").write_bytes(b"not a checkpoint")
    with pytest.raises(FormatError, match="corrupt"):
        load_model(run)


class _Constant(OdometryModel):
    def __init__(self, vel):
        super().__init__()
        self.vel = torch.tensor(vel, dtype=torch.float32)

    def forward(self, x, mask):
        return self.vel.expand(x.shape[0], 2)


def test_sparse_truth_is_scored_at_its_points_only():
    """Waypoint truth (real indoor data): the estimate starts at the trace's first waypoint (the
    first window's velocity holds before its centre) and is scored at the later waypoints only;
    dense metrics are not claimed."""
    from conftest import make_stream
    from wearnav.evaluate import evaluate_sequence
    from wearnav.preprocess import Aligned
    from wearnav.recording import Recording, Trajectory

    t = np.arange(0, 60.0, 1 / 25)
    wp_t = np.arange(0.0, 61.0, 10.0)
    rec = Recording(
        name="wp",
        devices={"phone": make_stream(6000, 100.0)},
        truth=Trajectory(wp_t, np.stack([wp_t * 1.0, np.zeros_like(wp_t)], 1)),
    )
    seq = Aligned(
        "wp",
        t,
        ("phone",),
        np.zeros((1, t.size, 6), np.float32),
        np.ones((1, t.size), bool),
        np.full((t.size, 2), np.nan),
        {"mode": "STW"},
        rec,
    )
    row, traj = evaluate_sequence(_Constant([1.0, 0.0]), seq, window=100, stride=10)
    assert row["truth"] == "sparse" and "ate" not in row
    assert row["points"] >= 4 and row["mean_error"] == pytest.approx(0.0, abs=1e-6)
    row, _ = evaluate_sequence(_Constant([0.0, 0.0]), seq, window=100, stride=10)
    # standing still at the first waypoint (t = 0 s): the errors are the distances walked since
    later = wp_t[(wp_t > 0) & (wp_t <= t[-1])]
    assert row["points"] == later.size == 5
    assert row["mean_error"] == pytest.approx(np.mean(later), rel=1e-6)
    assert row["point_errors"] == pytest.approx(later, rel=1e-6)


def test_sequence_cache_is_bounded_and_drops_the_least_recently_used(tiny, monkeypatch):
    """load_sequences keeps at most MAX_CACHED_SEQUENCES aligned sequences per process (a long
    benchmark over many datasets and preprocessing variants must not grow without bound): with
    room for 2, aligning 3 recordings keeps the last 2; asking again for those aligns nothing,
    asking for the first aligns it again."""
    import importlib

    from wearnav.dataset import Dataset
    from wearnav.preprocess import MAX_CACHED_SEQUENCES, BoundedCache, load_sequences

    module = importlib.import_module(load_sequences.__module__)
    assert module._CACHE.maxsize == MAX_CACHED_SEQUENCES
    cache = BoundedCache(2)
    monkeypatch.setattr(module, "_CACHE", cache)
    calls = []
    real_align = module.align
    monkeypatch.setattr(module, "align", lambda rec, pcfg: calls.append(rec.name) or real_align(rec, pcfg))
    view = Dataset.open(tiny)
    names = view.names[:3]
    cfg = _cfg(tiny)
    load_sequences(_View(view, names), cfg)
    assert calls == names and len(cache) == 2
    load_sequences(_View(view, names[1:]), cfg)
    assert calls == names  # both still cached
    load_sequences(_View(view, names[:1]), cfg)
    assert calls == names + names[:1] and len(cache) == 2


def test_bounded_cache_keeps_the_most_recently_used():
    from wearnav.preprocess import BoundedCache

    c = BoundedCache(2)
    c["a"], c["b"] = 1, 2
    assert c["a"] == 1  # a read refreshes "a"
    c["c"] = 3
    assert list(c) == ["a", "c"] and "b" not in c


class _View:
    """A Dataset view restricted to some names (load_sequences needs names, path and load)."""

    def __init__(self, ds, names):
        self.ds, self.names = ds, list(names)

    def path(self, name):
        return self.ds.path(name)

    def load(self, name):
        return self.ds.load(name)


def test_test_input_gets_one_constant_yaw_never_the_truth_over_time(tiny, tmp_path):
    """Issue 16 §1: training may align onto the truth over time; validation and test recordings get
    the common frame plus one yaw from the truth's first 10 s. The old frame is a named diagnostic
    that scores differently."""
    cfg = _cfg(tiny, epochs=1)
    assert cfg.frame_align == "truth" and cfg.eval_config().frame_align == "initial"
    assert _cfg(tiny, frame_align="common").eval_config().frame_align == "common"  # never more truth
    assert _cfg(tiny, frame_align="none", eval_frame_align="truth").eval_config().frame_align == "none"
    with pytest.raises(ConfigError, match="frame_align"):
        _cfg(tiny, eval_frame_align="bogus")
    run = prepare_run(cfg, tmp_path / "run")
    fit(cfg, run, progress=False)
    assert runs.read_config(run)["config"]["eval_preprocess"]["frame_align"] == "initial"
    honest = evaluate_run(run, progress=False)
    diag = evaluate_run(run, progress=False, preprocess={"eval_frame_align": "truth"}, out_dir=tmp_path / "diag")
    assert honest["test_frame"] == "initial" and diag["test_frame"] == "truth"
    a = [r["ate"] for r in honest["splits"]["test"]["sequences"]]
    b = [r["ate"] for r in diag["splits"]["test"]["sequences"]]
    assert a != pytest.approx(b, rel=1e-4)
    assert runs.read_metrics(run)["test_frame"] == "initial"  # the run's own metrics stay honest


def test_recipes_fast_by_default_and_paper_one_option_away(tiny, tmp_path):
    from wearnav.train.odometry import recipe_schedule

    assert TrainConfig(model="test-mlp", data=str(tiny)).recipe == "fast"
    s = recipe_schedule("fast", epochs=10, steps_per_epoch=20)
    assert s.warmup_steps == 20 and s.total_steps == 200 and s.decay_from == 100
    assert s.aux_warmup_steps == 100  # Suite-IN++'s contrastive terms ramp in over the first half
    assert recipe_schedule("paper", 10, 20).total_steps == 0  # constant at the model's paper lr
    with pytest.raises(ConfigError, match="recipe"):
        _cfg(tiny, recipe="slow")
    # the paper recipe takes the model's published lr, constant; fast takes 1e-3 with its schedule
    for recipe, lr in (("paper", TinyGait.default_lr), ("fast", 1e-3)):
        cfg = _cfg(tiny, epochs=1, lr=None, recipe=recipe)
        record = fit(cfg, prepare_run(cfg, tmp_path / recipe), progress=False)
        assert record["lr"] == lr
