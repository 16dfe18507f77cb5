"""The activity classifier trained on every labelled source at once (issue 35), and its
leave-one-dataset-out measurement.

**Windows** (:mod:`wearnav.train.activity_data`): every source's recordings cut into windows as
inference cuts them, each labelled in the one label set (unlabelled: −1), cached per source.

**Balance** (:func:`sample_weights`): at most ``max_per_class`` windows of one class from one
source (drawn at random), then each window is drawn with probability ∝ m_c / (S_c · n_{c,s}): class
c weighs m_c ∝ n_c^``class_power`` (n_c its windows after the cap), and within a class each of the
S_c sources that have it weighs the same, so MotionSense's pocket walks do not outweigh the
hand-held ones.

**Rare classes**: a class that fewer than ``rare_sources`` (3) training sources have (stairs,
running) has its prior multiplied by ``rare_factor`` after training (log ``rare_factor`` added to
its logit bias in the checkpoint, so ``classify`` needs nothing else): the model says stairs or
running only on strong evidence.

**Motion amplitude** (``amp_jitter``, :mod:`wearnav.models.har`): each training window's horizontal
and vertical motion is scaled by its own random factor within 1 ± ``amp_jitter``, so the model reads
the walk's shape rather than its strength.

**Training** (:func:`train_run`): Adam, ``epochs`` × ``steps`` batches of 64 drawn with those
weights, one torch thread; the run folder is one ``classify`` reads (config.yaml with a
:class:`ClassifyConfig`, ``training.json`` with the classes, ``checkpoints/last.ckpt``).

**Context** (``context_windows``, :data:`CONTEXT_WINDOWS`): ``classify``, the live page and the
scores here decide each window's label over its neighbours as well
(:func:`wearnav.train.classify.context_probs`: the normalised geometric mean of the probabilities
of 5 consecutive windows, 7.7 s), written into training.json. Unlabelled windows are kept, with
label −1, as the neighbours of the labelled windows; they are neither trained on nor scored.

**Leave one dataset out** (:mod:`wearnav.bench.har_lodo`): a run trains on every source but
``held_out`` and is scored on all of ``held_out``'s windows; the ``in-dataset`` run trains on
every source's training subjects and is scored on each source's test subjects.

Decision (each constant, what it was chosen on and what it measured):
docs/decisions/0030-activity-context-ensembles-amplitude.md.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from wearnav import activity_labels as al
from wearnav import runs
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, ValidationError
from wearnav.metrics import accuracy, confusion_matrix, macro_f1
from wearnav.models import registry
from wearnav.models.har import AMP_JITTER, HAREnsemble, HARNet
from wearnav.train.activity_data import (
    MODEL,
    SOURCES,
    WINDOW,
    Windows,
    classify_config,
    merge_facts,
    source_windows,
)
from wearnav.train.classify import (
    STILL_RULE,
    TRAINING,
    context_probs,
    load_model,
)
from wearnav.train.common import CHECKPOINTS, LAST

BATCH = 64  # paper 002's batch size
CONTEXT_WINDOWS = 5  # a window's label is decided over 5 windows, 7.7 s (wearnav.train.classify.context_probs)


def cap_per_class(w: Windows, max_per_class: int | None, seed: int) -> Windows:
    """At most ``max_per_class`` windows of one (source, class), drawn at random."""
    if max_per_class is None:
        return w
    rng = np.random.default_rng(seed)
    keep = []
    for s in np.unique(w.source):
        for c in np.unique(w.y[w.source == s]):
            idx = np.flatnonzero((w.source == s) & (w.y == c))
            keep.append(idx if len(idx) <= max_per_class else rng.choice(idx, max_per_class, replace=False))
    return w.take(np.sort(np.concatenate(keep))) if keep else w


def sample_weights(y: np.ndarray, source: np.ndarray, class_power: float = 0.0) -> np.ndarray:
    """Drawing probability ∝ n_c^class_power / (S_c · n_{c,s}) (module docstring); sums to 1."""
    wts = np.zeros(len(y))
    for c in np.unique(y):
        srcs = np.unique(source[y == c])
        mass = float(np.sum(y == c)) ** class_power
        for s in srcs:
            m = (y == c) & (source == s)
            wts[m] = mass / (len(srcs) * m.sum())
    return wts / wts.sum()


@dataclass(frozen=True)
class ActivityRun:
    """One training of the multi-source activity model: ``sources`` trained on (all their
    windows, or with ``in_dataset`` their training side only); ``held_out``: the source scored
    (all its windows), or with ``in_dataset`` every source's test side."""

    device: str
    sources: tuple[str, ...]
    data: dict[str, str]  # source → imported folder
    held_out: str | None = None
    in_dataset: bool = False
    epochs: int = 6
    steps: int = 150
    max_per_class: int | None = 1500
    class_power: float = 1.0
    rare_sources: int = 3
    rare_factor: float = 0.03
    # har-gravity's training-time augmentation (wearnav.models.har): random motion amplitude, gyro dropout
    amp_jitter: float = AMP_JITTER
    gyro_dropout: float = 0.1
    seed: int = 0
    lr: float = 1e-3
    unknown_threshold: float | None = None  # written into training.json for classify (shipped model)
    still_rule: dict | None = None  # ditto: how standing and sitting are decided (classify.StillRule.record)
    context_windows: int = CONTEXT_WINDOWS  # ditto: classify decides a window's label over this many
    members: int = 1  # networks in the model, each from its own seed (wearnav.models.har.HAREnsemble)
    cache: str | None = None

    def __post_init__(self) -> None:
        if self.held_out is not None and self.held_out not in self.data:
            raise ConfigError(f"held-out source {self.held_out!r} has no data folder")
        unknown = [s for s in self.sources if s not in SOURCES]
        if unknown:
            raise ConfigError(f"unknown activity sources: {', '.join(unknown)}")
        if self.members < 1:
            raise ConfigError(f"members must be ≥ 1, got {self.members}")
        if self.context_windows < 1 or self.context_windows % 2 == 0:
            raise ConfigError(f"context_windows must be an odd count, got {self.context_windows}")

    @property
    def train_sources(self) -> tuple[str, ...]:
        return tuple(s for s in self.sources if s != self.held_out or self.in_dataset)

    def record(self) -> dict:
        """What decides the run (its folder's hash): everything but the cache folder."""
        d = dataclasses.asdict(self)
        d.pop("cache")
        if self.members == 1:  # left out at its default: runs from before it keep their folders
            d.pop("members")
        if self.still_rule is None:  # ditto
            d.pop("still_rule")
        return d


def _windows_of(run: ActivityRun, sources) -> tuple[Windows, list[dict]]:
    cache = Path(run.cache) if run.cache else None
    parts, facts = [], []
    for s in sources:
        w, f = source_windows(s, Path(run.data[s]), cache)
        parts.append(w)
        facts.append(f)
    return Windows.concat(parts), facts


def train_run(run: ActivityRun, folder: Path, echo=None) -> dict:
    """Train ``run`` into ``folder`` (config.yaml, training.json, checkpoints/last.ckpt), score it
    (metrics.json, ``heldout.npz``: per scored window its source, true and predicted class (LABELS
    indices), top probability and every class's, ``prob``, in the order of training.json's classes,
    all decided over the context (:func:`score_run`), and ``pred_window`` / ``conf_window`` decided
    alone) and return the metrics."""
    folder = Path(folder)
    torch.set_num_threads(1)
    train, facts = _windows_of(run, run.train_sources)
    if run.in_dataset:
        train = train.take(~train.test)
    train = train.take(train.y >= 0)
    if len(train) == 0:
        raise ValidationError("no labelled training windows")
    present = sorted(set(train.y.tolist()))  # every (source, class) keeps windows under the cap
    classes = [al.LABELS[i] for i in present]
    remap = np.full(len(al.LABELS), -1, np.int64)
    remap[present] = np.arange(len(present))
    cfg = classify_config(run.device, str(run.data[run.train_sources[0]]), classes, run.epochs, run.seed, run.members)
    folder.mkdir(parents=True, exist_ok=True)
    runs.write_config(
        folder,
        {"train": runs.to_dict(cfg), "preprocess": runs.to_dict(cfg.preprocess_config())},
        {"activity_run": run.record()},
    )
    nets, losses, t0 = [], [], time.perf_counter()
    uncapped = train
    for k in range(run.members):  # member k: seed + k for its weights, its windows and its batches
        seed = run.seed + k
        train = cap_per_class(uncapped, run.max_per_class, seed)
        y = remap[train.y]
        torch.manual_seed(seed)
        net = registry.build(
            MODEL,
            n_devices=1,
            window=WINDOW,
            n_classes=len(classes),
            amp_jitter=run.amp_jitter,
            gyro_dropout=run.gyro_dropout,
        )
        if not isinstance(net, HARNet):
            raise ConfigError(f"{MODEL} is not a HARNet")
        losses.append(
            _fit(net, train, y, run, seed, folder.name + (f" member {k + 1}" if run.members > 1 else ""), echo)
        )
        nets.append(net)
        if k == 0:
            first = train, y  # the first member's windows, for the record
    wall = time.perf_counter() - t0
    train, y = first
    sources_of = {c: len(set(train.source[y == i].tolist())) for i, c in enumerate(classes)}
    rare = [c for c in classes if sources_of[c] < run.rare_sources]
    with torch.no_grad():  # the prior of a class few sources have, times rare_factor (module docstring)
        for net in nets:
            for c in rare:
                net.classifier.bias[classes.index(c)] += float(np.log(run.rare_factor))
    model = nets[0] if run.members == 1 else HAREnsemble(nets)
    (folder / CHECKPOINTS).mkdir(exist_ok=True)
    torch.save({"state_dict": {f"model.{k}": v for k, v in model.state_dict().items()}}, folder / CHECKPOINTS / LAST)
    record = {
        "classes": classes,
        "lr": run.lr,
        "batch": BATCH,
        "epochs_run": run.epochs,
        "steps_per_epoch": run.steps,
        "loss_per_epoch": losses[0] if run.members == 1 else losses,
        "wall_s": round(wall, 2),
        "s_per_epoch": round(wall / run.epochs, 2),
        "train_windows": int(len(y)),
        "class_windows": {c: int(np.sum(y == i)) for i, c in enumerate(classes)},
        "source_windows": {s: int(np.sum(train.source == s)) for s in run.train_sources},
        "training_data": merge_facts(facts, run.device),
        "sources": list(run.train_sources),
        "class_sources": sources_of,
        "rare_classes": rare,
        "rare_factor": run.rare_factor,
        "context_windows": run.context_windows,
        "members": run.members,
    }
    if run.unknown_threshold is not None:
        record["unknown_threshold"] = run.unknown_threshold
    if run.still_rule is not None:
        record[STILL_RULE] = run.still_rule
    runs.write_json(folder / TRAINING, record)
    metrics = score_run(run, folder, record)
    runs.write_metrics(folder, metrics)
    return metrics


def _fit(net: HARNet, train: Windows, y: np.ndarray, run: ActivityRun, seed: int, name: str, echo=None) -> list[float]:
    """Train one network: Adam, ``run.epochs`` × ``run.steps`` batches drawn with
    :func:`sample_weights` from a generator seeded ``seed``; returns the mean loss per epoch."""
    opt = torch.optim.Adam(net.parameters(), lr=run.lr)
    p = sample_weights(y, train.source, run.class_power)
    rng = np.random.default_rng(seed)
    x_all, y_all = torch.from_numpy(train.x), torch.from_numpy(y)
    mask = torch.ones(BATCH, 1)
    losses = []
    net.train()
    for epoch in range(run.epochs):
        total = 0.0
        for _ in range(run.steps):
            idx = torch.from_numpy(rng.choice(len(y), BATCH, p=p))
            loss, _ = net.loss({"x": x_all[idx][:, None], "mask": mask, "label": y_all[idx]})
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach())
        losses.append(round(total / run.steps, 4))
        if echo:
            echo(f"{name}: epoch {epoch + 1}/{run.epochs} loss {losses[-1]:.3f}")
    return losses


def score(true: np.ndarray, pred: np.ndarray, n: int) -> dict:
    """Accuracy, macro-F1 (:func:`wearnav.metrics.macro_f1`) and walking recall of LABELS indices."""
    walk = al.LABELS.index(al.WALKING)
    has_walk = np.any(true == walk)
    return {
        "windows": int(len(true)),
        "accuracy": accuracy(true, pred, n),
        "macro_f1": macro_f1(true, pred, n),
        "walking_recall": float(np.mean(pred[true == walk] == walk)) if has_walk else None,
        "walking_windows": int(np.sum(true == walk)),
    }


@torch.no_grad()
def predict_windows(model, x: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """Softmax probabilities (N, classes) of windows x (N, L, 6)."""
    model.eval()
    out = [
        torch.softmax(model(torch.from_numpy(x[a : a + chunk])[:, None], torch.ones(min(chunk, len(x) - a), 1)), 1)
        for a in range(0, len(x), chunk)
    ]
    return torch.cat(out).numpy() if out else np.empty((0, 0))


def score_run(run: ActivityRun, folder: Path, record: dict) -> dict:
    """Score the trained model on the run's held-out windows (see :class:`ActivityRun`) as
    ``classify`` labels them: every window of a recording predicted, each decided over its
    ``context_windows`` (:func:`wearnav.train.classify.context_probs`), the labelled ones scored;
    ``per_window`` in each source's metrics: the same windows decided alone."""
    model, _, classes = load_model(folder)
    n = len(al.LABELS)
    if run.in_dataset:
        test, _ = _windows_of(run, run.sources)
        test = test.take(test.test)
    elif run.held_out is not None:
        test, _ = _windows_of(run, (run.held_out,))
    else:
        return {"per_source": {}, "training": record, "measured_by": "the leave-one-dataset-out suite"}
    if not np.any(test.y >= 0):  # e.g. a slice without test subjects: nothing to score
        return {"per_source": {}, "labels": list(al.LABELS), "classes": classes, "training": record}
    alone = predict_windows(model, test.x)
    prob = np.empty_like(alone)
    for idx in test.runs():
        prob[idx] = context_probs(alone[idx], run.context_windows)
    to_label = np.asarray([al.LABELS.index(c) for c in classes])
    keep = test.y >= 0
    test, prob, alone = test.take(keep), prob[keep], alone[keep]
    pred, pred_alone = to_label[prob.argmax(1)], to_label[alone.argmax(1)]
    np.savez(
        folder / "heldout.npz",
        source=test.source,
        true=test.y,
        pred=pred,
        conf=prob.max(1),
        prob=prob.astype(np.float32),
        pred_window=pred_alone,
        conf_window=alone.max(1),
    )
    per = {}
    for s in np.unique(test.source):
        m = test.source == s
        per[s] = score(test.y[m], pred[m], n)
        per[s]["confusion"] = confusion_matrix(test.y[m], pred[m], n).tolist()
        per[s]["per_window"] = score(test.y[m], pred_alone[m], n)
    return {"per_source": per, "labels": list(al.LABELS), "classes": classes, "training": record}


def unknown_threshold(conf: np.ndarray, correct: np.ndarray, keep: float = 0.95) -> float:
    """The largest top-probability threshold that keeps ≥ ``keep`` of the correct windows (the
    (1 − keep) quantile of the correct windows' top probability, lower interpolation)."""
    c = np.sort(np.asarray(conf)[np.asarray(correct, bool)])
    if c.size == 0:
        raise ValidationError("no correctly classified held-out window to calibrate the threshold on")
    return float(c[int(np.floor((1.0 - keep) * c.size))])


def read_heldout(folder: Path) -> dict:
    z = np.load(Path(folder) / "heldout.npz", allow_pickle=False)
    return {k: z[k] for k in z.files}


def training_record(folder: Path) -> dict:
    return read_json(Path(folder) / TRAINING)
