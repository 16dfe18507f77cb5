"""Training and evaluating activity / placement classifiers (paper 002), beside
:mod:`wearnav.train.odometry` and sharing its core (:mod:`wearnav.train.common`).

A run is a pure function of :class:`ClassifyConfig`: run folder by config hash
(:mod:`wearnav.runs`), ``training.json`` from :func:`fit` (with the training windows per class and
the training data's rates, placements and gravity directions, :func:`wearnav.trust.data_facts`),
``metrics.json`` from :func:`evaluate_run` (accuracy, macro-F1, confusion matrix on the test
subjects, and ``beats_trivial``: whether the accuracy beats always answering the training
windows' majority class, ``trivial_accuracy``; on the test subjects, as the protocol has no
validation split).

Protocol (as the paper: a train and a test set, a fixed number of epochs): no validation split
and no early stopping; the weights after the last epoch are the model (``last.ckpt``). Splits are
subject-independent (:data:`TEST_SUBJECTS`): every recording of a subject is on one side.

Techniques (paper 002 Sec. II-B, :mod:`wearnav.preprocess.augment`): ``model`` picks the baseline / Head2 /
Head3; ``expand`` adds transformed copies of the training windows (rotation eqs. 9–11,
"all axes", noise eq. 12 with σ from the training windows); ``denoise`` applies the moving
average of eq. 13 to training and test sequences; ``augment`` names batch augmentations
(``rotate_random``); ``frame`` "device" (the paper's sensor frame) or "world".
"""

from __future__ import annotations

import dataclasses
import logging
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import torch

from wearnav import runs, trust
from wearnav.core.textio import read_json
from wearnav.errors import (
    ConfigError,
    FormatError,
    MissingFileError,
    ValidationError,
    check_field_types,
)
from wearnav.models import registry
from wearnav.preprocess import Aligned, PreprocessConfig, load_sequences
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.train.common import CHECKPOINTS, LAST, SeededModule, check_run_kind, load_weights, make_trainer
from wearnav.train.interrupt import stop_between_batches

log = logging.getLogger(__name__)

TRAINING = "training.json"

# Subject-independent test sets, by split scheme. UCI HAR's own split (its test subjects); for
# the others, which define none, every fourth subject (MotionSense: 6 of 24; UJI: 5 of 23) and,
# for Oxford's two users, user 2 (train on one person, test on the other); the simulator's
# placement dataset (wearnav.simulate.presets.plan_placement_dataset): every fourth walker.
TEST_SUBJECTS: dict[str, frozenset[int]] = {
    "uci-hapt": frozenset({2, 4, 9, 10, 12, 13, 18, 20, 24}),
    "motionsense": frozenset({4, 8, 12, 16, 20, 24}),
    "uji": frozenset({4, 8, 12, 16, 20}),
    "oxford": frozenset({2}),
    "sim-placement": frozenset({4, 8, 12, 16}),
}


def subject_number(subject: str) -> int:
    """The number in a manifest's subject id ("user02", "sub04", "s12", "user2")."""
    m = re.search(r"(\d+)$", str(subject))
    if not m:
        raise ValidationError(f"subject id {subject!r} has no number to assign it to a split")
    return int(m.group(1))


def split_of(scheme: str, subject: str) -> str:
    """ "train" or "test" for a subject under ``scheme``; "manifest" is not handled here."""
    if scheme not in TEST_SUBJECTS:
        raise ConfigError(f"unknown split scheme {scheme!r} (expected one of {', '.join(TEST_SUBJECTS)} or manifest)")
    return "test" if subject_number(subject) in TEST_SUBJECTS[scheme] else "train"


def split_view(ds, scheme: str, side: str):
    """The recordings of dataset ``ds`` on ``side`` ("train" / "test") of the split."""
    if scheme == "manifest":
        return ds.split(side)
    subjects = [s for s in ds.manifest["subject"].astype(str).unique() if split_of(scheme, s) == side]
    return ds.filter(subject=subjects) if subjects else ds.filter(subject=["\0none"])


@dataclass(frozen=True)
class ClassifyConfig:
    """Everything that decides a trained classifier. ``classes`` empty: every value of
    ``label_kind`` in the training recordings. ``max_train_windows`` subsamples the training
    windows (quick runs only). ``max_minutes`` does not enter the hash."""

    model: str
    data: str
    scheme: str = "manifest"
    label_kind: str = "activity"
    classes: tuple[str, ...] = ()
    devices: tuple[str, ...] = ("phone",)
    frame: str = "device"
    rate: float = 50.0
    window: int = 128
    stride: int = 64
    epochs: int = 30
    lr: float | None = None
    batch: int | None = None
    augment: tuple[str, ...] = ()
    expand: str | None = None
    noise_fraction: float = 0.1
    denoise: int = 0
    max_train_windows: int | None = None
    model_args: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    max_minutes: float | None = None

    def __post_init__(self) -> None:
        check_field_types(self)
        if self.epochs < 1 or self.seed < 0:
            raise ConfigError(f"epochs must be ≥ 1 and seed ≥ 0, got {self.epochs} and {self.seed}")
        if self.denoise < 0:
            raise ConfigError(f"moving-average window must be ≥ 0 samples, got {self.denoise}")
        if self.expand is not None:
            from wearnav.preprocess.augment import expansion_copies

            expansion_copies(self.expand)
        if not self.devices:
            raise ConfigError("at least one device must be named")
        self.preprocess_config()  # their own checks (rate, frame, window sizes), here so that a
        self.window_config()  # damaged config.yaml is refused when it is read

    @classmethod
    def from_dict(cls, d: dict) -> ClassifyConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise ConfigError(f"unknown classification config keys: {sorted(unknown)}")
        kw: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(**kw)

    def preprocess_config(self) -> PreprocessConfig:
        # frame_align "none": the classifier sees each device in its own frame (or its own world
        # frame); nothing ties devices together but the clock.
        return PreprocessConfig(rate=self.rate, devices=tuple(self.devices), frame=self.frame, frame_align="none")

    def window_config(self, target: str | None = "class") -> WindowConfig:
        return WindowConfig(
            window=self.window, stride=self.stride, target=target, label_kind=self.label_kind if target else None
        )


HASH_EXCLUDE = ("max_minutes",)


def run_record(cfg: ClassifyConfig) -> dict:
    train = {k: v for k, v in runs.to_dict(cfg).items() if k not in HASH_EXCLUDE}
    return {"train": train, "preprocess": runs.to_dict(cfg.preprocess_config())}


def run_folder(root: str | Path, name: str, cfg: ClassifyConfig) -> Path:
    return runs.run_dir(root, name, run_record(cfg))


def prepare_run(cfg: ClassifyConfig, run: str | Path) -> Path:
    """Create (or reuse) run folder ``run`` for ``cfg``; one holding another config is refused."""
    from wearnav.dataset import Dataset

    run = Path(run)
    if registry.get(cfg.model).task != "classify":
        raise ConfigError(f"model {cfg.model!r} is not a classifier")
    record = run_record(cfg)
    if (run / runs.CONFIG).is_file():
        old = runs.read_config(run)["config"]
        old = {**old, "train": {k: v for k, v in old.get("train", {}).items() if k not in HASH_EXCLUDE}}
        if old != record:
            raise ConfigError("holds a run of another configuration; choose another --out", run)
        return run
    if not runs.is_blank(run):
        raise ConfigError("exists and is not an empty folder or a run folder; choose another --out", run)
    ds = Dataset.open(cfg.data)
    for side in ("train", "test"):
        if len(split_view(ds, cfg.scheme, side)) == 0:
            raise ValidationError(f"no {side} recordings under split scheme {cfg.scheme!r}", cfg.data)
    run.mkdir(parents=True, exist_ok=True)
    runs.write_config(run, {**record, "train": runs.to_dict(cfg)}, {"data_provenance": ds.provenance})
    return run


def sequences(view, cfg: ClassifyConfig, progress: bool = False) -> list[Aligned]:
    """Aligned recordings of a view, with eq. 13's moving average when ``cfg.denoise``."""
    from wearnav.preprocess.augment import moving_average

    seqs = load_sequences(view, cfg, progress)
    if cfg.denoise > 1:  # new objects: the aligned cache must stay raw
        seqs = [
            dataclasses.replace(s, imu=moving_average(s.imu, cfg.denoise, axis=1).astype(s.imu.dtype)) for s in seqs
        ]
    return seqs


def _windows(seqs, cfg: ClassifyConfig, classes) -> WindowDataset:
    return WindowDataset(seqs, cfg.window_config(), classes=list(classes) if classes else None)


def _subsample(wds: WindowDataset, n: int | None, seed: int) -> WindowDataset:
    if n is not None and len(wds) > n:
        keep = np.sort(np.random.default_rng(seed).choice(len(wds), n, replace=False))
        wds.index = wds.index[keep]
    return wds


def _sample_x(wds: WindowDataset, n: int = 4096) -> torch.Tensor:
    """Up to n training windows, evenly spaced (σ of eq. 12 is estimated on these)."""
    idx = np.unique(np.linspace(0, len(wds) - 1, min(n, len(wds))).astype(int))
    return wds[idx.tolist()]["x"]


def fit(cfg: ClassifyConfig, run: str | Path, progress: bool = True) -> dict:
    """Train into ``run`` (resuming from its last.ckpt). Returns and writes training.json. Holds
    the run folder's lock while it runs (:func:`wearnav.runs.locked`)."""
    with runs.locked(run):
        return _fit(cfg, Path(run), progress)


def _fit(cfg: ClassifyConfig, run: Path, progress: bool) -> dict:
    from wearnav.dataset import Dataset
    from wearnav.preprocess.augment import ExpandedWindows, expansion_copies, noise_sigma

    ds = Dataset.open(cfg.data)
    train_seqs = sequences(split_view(ds, cfg.scheme, "train"), cfg, progress)
    train_ds = _subsample(_windows(train_seqs, cfg, cfg.classes), cfg.max_train_windows, cfg.seed)
    if len(train_ds) == 0:
        raise ValidationError(f"no labelled training windows of kind {cfg.label_kind!r}", cfg.data)
    classes = list(train_ds.classes)
    L.seed_everything(cfg.seed, workers=True, verbose=False)  # before the weights are drawn
    model = registry.build(
        cfg.model, n_devices=len(cfg.devices), window=cfg.window, n_classes=len(classes), **cfg.model_args
    )
    model_lr: float = getattr(model, "default_lr", 1e-3)
    model_batch: int = getattr(model, "default_batch", 64)
    lr, batch = cfg.lr or model_lr, cfg.batch or model_batch
    sigma = None
    data: WindowDataset | ExpandedWindows = train_ds
    if cfg.expand:
        copies = expansion_copies(cfg.expand)
        if "noise" in copies:
            sigma = noise_sigma(_sample_x(train_ds), cfg.noise_fraction)
        data = ExpandedWindows(train_ds, copies, sigma or (0.0, 0.0), cfg.seed)
    module = SeededModule(model, lr, cfg.augment, cfg.seed)
    trainer, _, _ = make_trainer(run, cfg.epochs, cfg.max_minutes, progress, len(data) // batch)
    last = run / CHECKPOINTS / LAST
    resumed = last.is_file()
    if resumed:
        log.info(f"{run.name}: resuming from {last}")
    t0 = time.perf_counter()
    with stop_between_batches(trainer):  # Ctrl-C / SIGTERM: exit 130 / 143, last.ckpt intact
        trainer.fit(module, data.loader(batch, cfg.seed), ckpt_path=str(last) if resumed else None)
    wall = time.perf_counter() - t0
    epochs = int(trainer.current_epoch)
    record = {
        "classes": classes,
        "lr": lr,
        "batch": batch,
        "train_windows": len(train_ds),
        "train_windows_expanded": len(data),
        "noise_sigma": sigma,
        "epochs_run": epochs,
        "stopped_by": "max time" if cfg.max_minutes and epochs < cfg.epochs else "max epochs",
        "wall_s": round(wall, 2),
        "s_per_epoch": round(wall / max(epochs, 1), 2),
        "resumed": resumed,
        "accelerator": str(trainer.strategy.root_device),
    }
    # the training windows' labels (the majority class is the trivial baseline) and the data's
    # facts (rates, placements, gravity directions), for evaluate_run and `wearnav classify`
    labels = window_labels(train_ds)
    record["class_windows"] = {c: int(np.sum(labels == i)) for i, c in enumerate(classes)}
    record["training_data"] = trust.data_facts(
        [s.recording for s in train_seqs if s.recording is not None], cfg.devices, cfg.window / cfg.rate
    )
    runs.write_json(run / TRAINING, record)
    return record


def window_labels(wds: WindowDataset, chunk: int = 4096) -> np.ndarray:
    """The class index of every window of ``wds`` (−1: unlabelled), fetched ``chunk`` at a time."""
    n = len(wds)
    parts = [wds[list(range(a, min(a + chunk, n)))]["label"].numpy() for a in range(0, n, chunk)]
    return np.concatenate(parts) if parts else np.empty(0, np.int64)


def load_model(run: str | Path) -> tuple[torch.nn.Module, ClassifyConfig, list[str]]:
    """The run's model with its last-epoch weights (eval mode), its config and class names."""
    run = Path(run)
    check_run_kind(run, "classify")  # an odometry run: say so, not "unknown config keys"
    cfg = runs.read_run_config(run, ClassifyConfig)
    path = run / TRAINING
    if not path.is_file():
        raise MissingFileError("run has no training.json (was it trained?)", run)
    classes = read_json(path).get("classes")
    if not isinstance(classes, list) or not classes or not all(isinstance(c, str) for c in classes):
        raise FormatError("no 'classes' list of class names", path)
    model = registry.build(
        cfg.model, n_devices=len(cfg.devices), window=cfg.window, n_classes=len(classes), **cfg.model_args
    )
    load_weights(model, run / CHECKPOINTS / LAST)
    model.eval()
    record = read_json(path)
    thr = record.get("unknown_threshold")
    if thr is not None and not (isinstance(thr, int | float) and 0.0 <= thr <= 1.0):
        raise FormatError(f"'unknown_threshold' must be a probability, got {thr!r}", path)
    model.unknown_threshold = thr  # type: ignore[assignment]  # a plain attribute labelling.window_classes reads (issue 35 §3)
    still = record.get(STILL_RULE)
    model.still_rule = None if still is None else StillRule.from_record(still, classes, path)  # type: ignore[assignment]  # ditto (issue 56 §3)
    k = record.get("context_windows", 1)
    if not (isinstance(k, int) and k >= 1 and k % 2 == 1):
        raise FormatError(f"'context_windows' must be an odd count of windows, got {k!r}", path)
    model.context_windows = k  # type: ignore[assignment]  # read by labelling.window_classes (context_probs)
    model.training_gravity = (
        ((record.get("training_data") or {}).get("devices") or {}).get(cfg.devices[0], {}).get("gravity_directions")
    )
    return model, cfg, classes


@torch.no_grad()
def window_probs(model, x: torch.Tensor, mask: torch.Tensor, batch: int = 512) -> np.ndarray:
    """Softmax probabilities (N, classes) of windows ``x`` (N, D, L, 6) with ``mask`` (N, D), in
    chunks of ``batch`` (the live receiver passes several sessions' windows at once)."""
    out = [torch.softmax(model(x[k : k + batch], mask[k : k + batch]), dim=1).numpy() for k in range(0, len(x), batch)]
    return np.concatenate(out) if out else np.empty((0, 0), np.float32)


def predict_probs(model, wds: WindowDataset, batch: int = 512) -> np.ndarray:
    """Softmax probabilities (N, classes) of every window of ``wds``."""
    out = [window_probs(model, b["x"], b["mask"], batch) for b in wds.loader(batch)]
    return np.concatenate(out) if out else np.empty((0, 0), np.float32)


def predict(model, wds: WindowDataset, batch: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Predicted class index and softmax confidence per window of ``wds``."""
    p = predict_probs(model, wds, batch)
    return (p.argmax(1), p.max(1)) if len(p) else (np.empty(0, int), np.empty(0))


def context_probs(prob: np.ndarray, k: int) -> np.ndarray:
    """Each window's class probabilities decided over its context (issue 35): the normalised
    geometric mean of the probabilities (N, C) of the windows at most (k − 1) / 2 away from it in a
    run of consecutive windows (at the ends, those that exist), softmax of their mean log
    probability. It multiplies the neighbours' evidence, tempered by their count, so a stray window
    in a walk is outvoted by its neighbours while a bout as long as the context keeps its label.
    ``k`` = 1: the window alone."""
    if k < 1 or k % 2 == 0:
        raise ValueError(f"the context is an odd number of windows, got {k}")
    prob = np.asarray(prob, np.float64)
    if k == 1 or len(prob) == 0:
        return prob / np.maximum(prob.sum(axis=1, keepdims=True), 1e-300)
    h = k // 2
    c = np.vstack([np.zeros((1, prob.shape[1])), np.cumsum(np.log(np.clip(prob, 1e-12, 1.0)), axis=0)])
    i = np.arange(len(prob))
    lo, hi = np.maximum(i - h, 0), np.minimum(i + h + 1, len(prob))
    mean = (c[hi] - c[lo]) / (hi - lo)[:, None]
    e = np.exp(mean - mean.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


STILL_RULE = "still_rule"  # training.json's record of the model's StillRule (issue 56 §3)


@dataclass(frozen=True)
class StillRule:
    """How a window whose top class is standing or sitting is decided (issue 56 §3). Turned to
    gravity, a still phone shows neither posture: the shipped model splits a still phone in the hand
    about 0.45 / 0.55 between them, and one top-probability threshold for every class (0.66) called
    a user's pauses ``unknown``; on a source it did not train on it calls nearly every standing
    window sitting (its standing share of the two, about 0.04, the same for both postures). So the
    two are decided as a group: the window is still when their summed probability reaches
    ``threshold`` (else ``unknown``); it is standing when the phone turns at least
    ``gyro_rad_s`` on average over the window's context (a standing body sways, a seated one rests;
    :func:`context_mean` of :func:`gyro_rad_s`), else sitting; a window without a gyroscope (all
    zeros), or a rule without ``gyro_rad_s``, is standing when standing's share of the two reaches
    ``standing_share``. All are calibrated on the leave-one-dataset-out held-out windows
    (:func:`wearnav.bench.har_lodo.calibrate_still`); ``standing`` and ``sitting`` are the classes'
    indices in the model's class list. Decision: docs/decisions/0043-standing-sitting-still-rule.md."""

    threshold: float  # standing + sitting probability under which the window is unknown
    standing_share: float  # p(standing) / (p(standing) + p(sitting)) from which it is standing
    gyro_rad_s: float | None = None  # mean angular rate (rad/s) from which a still window is standing
    standing: int = 0
    sitting: int = 1

    def record(self) -> dict:
        """Its training.json form (classes by name: indices differ between runs)."""
        out = {"threshold": self.threshold, "standing_share": self.standing_share}
        return out if self.gyro_rad_s is None else {**out, "gyro_rad_s": self.gyro_rad_s}

    @classmethod
    def from_record(cls, d, classes: list[str], path: Path | None = None) -> StillRule:
        """The rule of a training.json record for a model of ``classes``; a malformed one ends in
        a :class:`FormatError` naming ``path``."""
        keys = {"threshold", "standing_share"}
        ok = isinstance(d, dict) and keys <= set(d) <= keys | {"gyro_rad_s"}
        if not ok or not all(isinstance(d[k], int | float) and 0.0 <= d[k] <= 1.0 for k in d):
            raise FormatError(
                f"'{STILL_RULE}' must hold threshold and standing_share (probabilities) and gyro_rad_s "
                f"(0–1 rad/s), got {d!r}",
                path,
            )
        if "standing" not in classes or "sitting" not in classes:
            raise FormatError(f"'{STILL_RULE}' needs classes standing and sitting, the model has {classes}", path)
        gyro = d.get("gyro_rad_s")
        return cls(
            float(d["threshold"]),
            float(d["standing_share"]),
            None if gyro is None else float(gyro),
            classes.index("standing"),
            classes.index("sitting"),
        )


def gyro_rad_s(x: np.ndarray) -> np.ndarray:
    """Each window's mean angular rate (rad/s): the mean norm of the gyroscope channels (3:6) of
    windows ``x`` (N, L, 6), in any frame (a norm does not depend on how the device is held)."""
    return np.linalg.norm(np.asarray(x, np.float64)[..., 3:6], axis=-1).mean(axis=-1)


def context_mean(v: np.ndarray, k: int) -> np.ndarray:
    """Each window's value ``v`` (N,) averaged over the windows at most (k − 1) / 2 away in a run of
    consecutive windows (at the ends, those that exist): the context :func:`context_probs` decides
    over."""
    v = np.asarray(v, np.float64)
    if k <= 1 or len(v) == 0:
        return v
    c = np.concatenate([[0.0], np.cumsum(v)])
    i = np.arange(len(v))
    lo, hi = np.maximum(i - k // 2, 0), np.minimum(i + k // 2 + 1, len(v))
    return (c[hi] - c[lo]) / (hi - lo)


def decide(
    prob: np.ndarray,
    unknown_threshold: float | None = None,
    still: StillRule | None = None,
    gyro: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Each window's class index (−1: unknown) and confidence from its probabilities ``prob``
    (N, C), as ``classify``, the live page and the leave-one-dataset-out scores decide it: the top
    class, unknown where its probability is under ``unknown_threshold`` (issue 35 §3); a window
    whose top class is standing or sitting is decided by ``still`` instead (:class:`StillRule`, with
    ``gyro`` (N,) the windows' mean angular rate over their context, rad/s), its confidence then the
    two classes' summed probability. Windows of any other top class are decided as without ``still``."""
    prob = np.asarray(prob, np.float64)
    cls, conf = prob.argmax(1), prob.max(1)
    sure = np.ones(len(cls), bool) if unknown_threshold is None else conf >= unknown_threshold
    if still is not None and len(prob):
        a, b = still.standing, still.sitting
        group = (cls == a) | (cls == b)
        q = prob[:, a] + prob[:, b]
        standing = prob[:, a] / np.maximum(q, 1e-300) >= still.standing_share
        if still.gyro_rad_s is not None and gyro is not None:
            g = np.asarray(gyro, np.float64)
            standing = np.where(g > 0, g >= still.gyro_rad_s, standing)
        cls = np.where(group, np.where(standing, a, b), cls)
        conf = np.where(group, q, conf)
        sure = np.where(group, q >= still.threshold, sure)
    return np.where(sure, cls, -1), conf


def evaluate_run(run: str | Path, training: dict | None = None, progress: bool = False) -> dict:
    """Accuracy, macro-F1 and the confusion matrix on the test subjects → metrics.json."""
    from wearnav.dataset import Dataset
    from wearnav.metrics import accuracy, confusion_matrix, macro_f1

    run = Path(run)
    model, cfg, classes = load_model(run)
    ds = Dataset.open(cfg.data)
    test_ds = _windows(sequences(split_view(ds, cfg.scheme, "test"), cfg, progress), cfg, classes)
    if len(test_ds) == 0:
        raise ValidationError("no labelled test windows", cfg.data)
    pred, _ = predict(model, test_ds)
    true = window_labels(test_ds)
    k = len(classes)
    if training is None and (run / TRAINING).is_file():
        training = read_json(run / TRAINING)
    metrics = {
        "model": cfg.model,
        "classes": classes,
        "test_windows": int(len(true)),
        "test_subjects": sorted(split_view(ds, cfg.scheme, "test").manifest["subject"].astype(str).unique()),
        "accuracy": accuracy(true, pred, k),
        "macro_f1": macro_f1(true, pred, k),
        "confusion": confusion_matrix(true, pred, k).tolist(),
        "training": training if training is not None else {},
    }
    counts = (training or {}).get("class_windows")
    if isinstance(counts, dict) and counts:  # did it learn: against always answering the majority class
        majority = classes.index(max(counts, key=lambda c: counts[c]))
        metrics.update(trust.classify_baseline(metrics["accuracy"], true, majority, classes))
    runs.write_metrics(run, metrics)
    return metrics
