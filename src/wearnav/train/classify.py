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

Techniques (paper 002 Sec. II-B, :mod:`wearnav.augment`): ``model`` picks the baseline / Head2 /
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
from wearnav.errors import (
    ConfigError,
    FormatError,
    MissingFileError,
    ValidationError,
    WearnavWarning,
    check_field_types,
)
from wearnav.export.header import is_exported, read_header
from wearnav.fileio import write_text_atomic
from wearnav.models import registry
from wearnav.preprocess import Aligned, PreprocessConfig, align, load_sequences
from wearnav.textio import read_json
from wearnav.train.common import CHECKPOINTS, LAST, SeededModule, check_run_kind, load_weights, make_trainer
from wearnav.train.interrupt import stop_between_batches
from wearnav.windows import WindowConfig, WindowDataset

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
            from wearnav.augment import expansion_copies

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
    from wearnav.augment import moving_average

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
    from wearnav.augment import ExpandedWindows, expansion_copies, noise_sigma
    from wearnav.dataset import Dataset

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
    model.unknown_threshold = thr  # type: ignore[assignment]  # a plain attribute window_classes reads (issue 35 §3)
    k = record.get("context_windows", 1)
    if not (isinstance(k, int) and k >= 1 and k % 2 == 1):
        raise FormatError(f"'context_windows' must be an odd count of windows, got {k!r}", path)
    model.context_windows = k  # type: ignore[assignment]  # read by window_classes (context_probs)
    model.training_gravity = (
        ((record.get("training_data") or {}).get("devices") or {}).get(cfg.devices[0], {}).get("gravity_directions")
    )
    return model, cfg, classes


@torch.no_grad()
def predict_probs(model, wds: WindowDataset, batch: int = 512) -> np.ndarray:
    """Softmax probabilities (N, classes) of every window of ``wds``."""
    out = [torch.softmax(model(b["x"], b["mask"]), dim=1).numpy() for b in wds.loader(batch)]
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


UNKNOWN = "unknown"  # the label of a window the model is unsure of (issue 35 §3)
UNKNOWN_INDEX = -1  # its class index in window_classes' output


def class_name(classes, i: int) -> str:
    """The name of class index ``i`` (:data:`UNKNOWN_INDEX`: :data:`UNKNOWN`)."""
    return UNKNOWN if int(i) == UNKNOWN_INDEX else classes[int(i)]


def unsure_windows(model, seq: Aligned, t: np.ndarray, conf: np.ndarray) -> np.ndarray:
    """Which windows are labelled :data:`UNKNOWN` (issue 35 §3): the top probability is under the
    model's calibrated ``unknown_threshold`` (training.json; the shipped activity model's comes from
    its leave-one-dataset-out runs, :mod:`wearnav.bench.har_lodo`), or, for a model that takes the
    device's own frame (not turned to gravity, ``gravity_align``), the window's gravity direction
    lies further than :data:`wearnav.trust.GRAVITY_MATCH_DEG` from every training window's (the
    trust check of :func:`trust.gravity_outside`, per window). A model without either record: none."""
    out = np.zeros(len(conf), bool)
    thr = getattr(model, "unknown_threshold", None)
    if thr is not None:
        out |= conf < thr
    dirs = getattr(model, "training_gravity", None)
    if dirs and not getattr(model, "gravity_align", False):
        d = int(np.argmax(seq.mask.any(axis=1)))
        i0 = np.clip(np.searchsorted(seq.t, t[:, 0]), 0, len(seq.t) - 1)
        i1 = np.clip(np.searchsorted(seq.t, t[:, 1]), 1, len(seq.t))
        g = np.stack([seq.imu[d, a:b, :3].mean(axis=0) for a, b in zip(i0, np.maximum(i1, i0 + 1))])
        g /= np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-9)
        out |= trust.angles_deg(g, np.asarray(dirs, float)).min(axis=1) > trust.GRAVITY_MATCH_DEG
    return out


def unknown_note(model, k: int, n: int) -> str:
    """The sentence saying that ``k`` of ``n`` windows are :data:`UNKNOWN`, and why."""
    thr = getattr(model, "unknown_threshold", None)
    why = [f"the model's top probability is under {thr:.2f}"] if thr is not None else []
    if getattr(model, "training_gravity", None) and not getattr(model, "gravity_align", False):
        why.append("the device is held unlike any training window")
    return (
        f"{k} of {n} windows ({100 * k / n:.0f} %) labelled {UNKNOWN}: {' or '.join(why)}; "
        "the model is not sure what the wearer did there"
    )


def intervals(t0: np.ndarray, t1: np.ndarray, cls: np.ndarray, conf: np.ndarray, classes) -> list[dict]:
    """Consecutive windows of one class merged into intervals. Windows overlap, so a boundary is
    put midway between the last window of one class and the first of the next."""
    out: list[dict] = []
    mid = (t0 + t1) / 2
    for i in range(len(cls)):
        if out and out[-1]["label"] == class_name(classes, cls[i]):
            r = out[-1]
            r["end_s"], r["windows"], r["_c"] = float(t1[i]), r["windows"] + 1, r["_c"] + float(conf[i])
            continue
        start = float(t0[i]) if not out else float((mid[i - 1] + mid[i]) / 2)
        if out:
            out[-1]["end_s"] = start
        out.append(
            {
                "start_s": start,
                "end_s": float(t1[i]),
                "label": class_name(classes, cls[i]),
                "windows": 1,
                "_c": float(conf[i]),
            }
        )
    for r in out:
        r["mean_confidence"] = round(r.pop("_c") / r["windows"], 4)
    return out


CLASSIFY_JSON = "classify.json"  # the marker of a `wearnav classify` output folder (wearnav.outputs)


def label_recordings(recordings, run: str | Path, out: str | Path, classifier=None) -> dict:
    """Classify every window of each recording with the run's model; write ``<name>_intervals.csv``
    (start_s, end_s, label, windows, mean_confidence) and ``<name>_timeline.png`` (|acc| of the
    first present device with the labels as coloured bands) into ``out``, and ``classify.json``
    (the run, the model's label set ``classes``, the recordings, the files and ``warnings``: one
    line per reason not to trust the labels, :func:`trust_warnings`, also raised as
    :class:`WearnavWarning`). All or nothing: a recording that fails leaves ``out`` as it was
    (:func:`wearnav.outputs.staged_output`). ``classifier``: the run's (model, config, classes) when
    already loaded (:func:`wearnav.train.resolve.resolve_model`). Returns ``files`` (paths), ``classes``,
    ``warnings``."""
    import json
    import warnings

    from wearnav.outputs import check_out_folder, staged_output

    check_out_folder(out, (), CLASSIFY_JSON, "classify")
    model, cfg, classes = classifier or load_model(run)
    found: list[str] = []
    with staged_output(out, CLASSIFY_JSON, "classify", replace=False) as stage:
        names = _label_into(recordings, model, cfg, classes, stage, found, Path(run))
        files = [f for n in names for f in (f"{n}_intervals.csv", f"{n}_timeline.png")] + [CLASSIFY_JSON]
        write_text_atomic(
            json.dumps(
                {
                    "run": str(run),
                    "model": cfg.model,
                    "classes": classes,
                    "recordings": names,
                    "files": files,
                    "warnings": found,
                },
                indent=2,
            ),
            stage / CLASSIFY_JSON,
        )
    for w in found:
        warnings.warn(WearnavWarning(w), stacklevel=2)
    return {"files": [Path(out) / f for f in files[:-1]], "classes": classes, "warnings": found}


def gravity_aligned(cfg: ClassifyConfig) -> bool:
    """Whether the model turns every window to gravity (``har-gravity``, :mod:`wearnav.models.har`):
    then the device's gravity direction, the trust check of how it is held, says nothing about it."""
    return cfg.model == "har-gravity" or bool(cfg.model_args.get("gravity_align"))


def trust_warnings(run: Path, cfg: ClassifyConfig, rec) -> list[str]:
    """Reasons not to trust a recording's labels (:mod:`wearnav.trust`), each with what to do:
    devices it lacks, a placement, rate or gravity direction unlike the training data's, a model
    that did not beat always answering the majority class. ``run``: the run folder, or the model file
    of ``wearnav export`` whose header holds the run's records."""
    out = []
    if (m := trust.missing_devices(cfg.devices, rec.devices)) is not None:
        out.append(f"{m}: {trust.CLASSIFY_DOMAIN_ADVICE}")
    if is_exported(run):  # a `wearnav export` file carries both records in its header
        header = read_header(run)
        record, metrics = header.get("training") or {}, header.get("metrics") or {}
    else:
        record = read_json(run / TRAINING) if (run / TRAINING).is_file() else {}
        metrics = runs.read_metrics(run) if runs.is_complete(run) else {}
    facts = trust.recording_facts(rec, cfg.devices, cfg.window / cfg.rate)
    training = record.get("training_data")
    if training and gravity_aligned(cfg):  # how the device is held is not this model's input
        devices = {d: {**v, "gravity_directions": []} for d, v in (training.get("devices") or {}).items()}
        training = {**training, "devices": devices}
    out += [f"{f}: {trust.CLASSIFY_DOMAIN_ADVICE}" for f in trust.domain_findings(facts, training, cfg.rate)]
    if (m := trust.did_not_learn(metrics)) is not None:
        out.append(f"{m}: {trust.CLASSIFY_LEARN_ADVICE}")
    return [f"{rec.name}: {w}" for w in out]


def window_classes(model, cfg: ClassifyConfig, rec) -> tuple[Aligned, np.ndarray, np.ndarray, np.ndarray]:
    """How ``classify`` labels a recording (and the live receiver its latest seconds, and
    ``track``'s trajectory.html its path): ``rec`` aligned by the run's preprocessing (with eq. 13's
    moving average when ``cfg.denoise``), cut into windows of the run's length at half-window
    strides; returns the aligned input, each window's start and end time (N, 2) s, its class index
    (:data:`UNKNOWN_INDEX` where :func:`unsure_windows`) and softmax confidence (N,) (N = 0 when
    shorter than one window), both decided over the model's ``context_windows`` (training.json;
    :func:`context_probs`; 1 where it has none)."""
    from wearnav.augment import moving_average

    seq = align(rec, cfg.preprocess_config())
    if cfg.denoise > 1:
        seq = dataclasses.replace(seq, imu=moving_average(seq.imu, cfg.denoise, axis=1).astype(seq.imu.dtype))
    wds = WindowDataset([seq], WindowConfig(window=cfg.window, stride=max(1, cfg.window // 2), target=None))
    if len(wds) == 0:
        return seq, np.empty((0, 2)), np.empty(0, np.int64), np.empty(0)
    prob = context_probs(predict_probs(model, wds), getattr(model, "context_windows", 1))
    cls, conf = prob.argmax(1), prob.max(1)
    t = wds[np.arange(len(wds)).tolist()]["t"].numpy()
    cls = np.where(unsure_windows(model, seq, t, conf), UNKNOWN_INDEX, cls)
    return seq, t, cls, conf


def _label_into(recordings, model, cfg, classes: list[str], out: Path, found: list[str], run: Path) -> list[str]:
    """Write each recording's intervals CSV and timeline PNG into ``out``; returns the names and
    adds each recording's :func:`trust_warnings` to ``found``."""
    import pandas as pd
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    written = []
    colours = {c: f"C{i % 10}" for i, c in enumerate(classes)} | {UNKNOWN: "0.6"}
    for rec in recordings:
        found += trust_warnings(run, cfg, rec)
        seq, t, cls, conf = window_classes(model, cfg, rec)
        if len(cls) == 0:
            raise ValidationError(f"shorter than one window ({cfg.window / cfg.rate:g} s)", rec.name)
        if (k := int(np.sum(cls == UNKNOWN_INDEX))) > 0:
            found.append(f"{rec.name}: {unknown_note(model, k, len(cls))}")
        rows = intervals(t[:, 0], t[:, 1], cls, conf, classes)
        df = pd.DataFrame(rows, columns=["start_s", "end_s", "label", "windows", "mean_confidence"])
        if rec.name in written:
            raise ValidationError("two recordings of this name; their files would collide", rec.name)
        written.append(rec.name)
        write_text_atomic(df.to_csv(index=False, float_format="%.3f"), out / f"{rec.name}_intervals.csv")
        d = int(np.argmax(seq.mask.any(axis=1)))
        fig = Figure(figsize=(10, 3))
        ax = fig.add_subplot()
        for r in rows:
            ax.axvspan(r["start_s"] - seq.t[0], r["end_s"] - seq.t[0], color=colours[r["label"]], alpha=0.3, lw=0)
        ax.plot(seq.t - seq.t[0], np.linalg.norm(seq.imu[d, :, :3], axis=1), color="k", lw=0.5)
        from matplotlib.patches import Patch

        ax.legend(
            handles=[Patch(color=colours[c], alpha=0.3, label=c) for c in [*classes, UNKNOWN] if c in set(df["label"])],
            fontsize=7,
            loc="upper right",
            ncol=3,
        )
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"|acc| {seq.devices[d]} (m/s²)")
        ax.set_title(f"{rec.name}: {cfg.label_kind} by {cfg.model}", fontsize=9)
        fig.tight_layout()
        save(fig, out / f"{rec.name}_timeline.png")
    if not written:
        raise ValidationError("no recording to classify")
    return written
