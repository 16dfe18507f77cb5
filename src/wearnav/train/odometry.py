"""One LightningModule trains every odometry model (DESIGN.md, "Training and evaluation core").

The module knows nothing about any model beyond the contract in :mod:`wearnav.models.base`: it
calls ``model.loss(batch)`` to train and ``model(x, mask)`` to validate, so Suite-IN++'s eq. (25)
terms and any other auxiliary loss stay inside the model. Checkpoints are selected and early
stopping decided on the validation velocity MSE, the one figure every model shares.

Reproducibility: every random draw of an epoch (shuffling, augmentation, dropout) is seeded
from ``(seed, epoch)``, so a run killed mid-epoch and resumed from ``last.ckpt`` replays that
epoch exactly and ends with the same weights and metrics as an uninterrupted run.

Decisions: docs/decisions/0013-training-recipe-and-one-module.md,
docs/decisions/0025-velocity-losses-polar.md.
"""

from __future__ import annotations

import dataclasses
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import torch

from wearnav import runs, trust
from wearnav.core.textio import read_json
from wearnav.dataset import Dataset, scorable_split, train_val_views
from wearnav.errors import ConfigError, FormatError, ValidationError, check_field_types, check_names
from wearnav.models import registry
from wearnav.models.base import VEL_LOSSES, AlongPointing, OdometryModel, ScaledVelocity, SnapToPointing
from wearnav.models.pdr import PDR, STEP_PER_CADENCE_M_S, PDRSpeed
from wearnav.preprocess import (
    SPARSE_TRUTH_HZ,
    SURVEYED_TRUTH_MAX_GAP_S,
    TRUTH_MAX_GAP_S,
    PreprocessConfig,
    check_speed_warp,
    load_sequences,
    time_warped,
)
from wearnav.preprocess.augment import get as augmentation
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.recording import CANONICAL_DEVICES
from wearnav.train.common import (
    BEST,
    CHECKPOINTS,
    LAST,
    GpuBusy,
    Schedule,
    SeededModule,
    check_run_kind,
    load_weights,
    make_trainer,
)
from wearnav.train.interrupt import stop_between_batches

log = logging.getLogger(__name__)

TRAINING = "training.json"  # what fit() measured; evaluate_run merges it into metrics.json
# What `wearnav adapt` did to a run (wearnav.adapt): its ``velocity_scale`` multiplies the model's
# velocity wherever the run is loaded (:func:`load_model`, the one place it is applied).
ADAPTATION = "adaptation.json"
DEFAULT_LR, DEFAULT_BATCH = 1e-3, 128
# How a run is optimised (TrainConfig.recipe): "fast", the default, Adam at DEFAULT_LR with a one-
# epoch linear warm-up, held for half the epochs, then a cosine decay to 1 % of it at ``epochs``,
# and a model's auxiliary losses (Suite-IN++'s contrastive/orthogonality terms) ramped in over
# that first half — it learns in a short run; "paper", each model's published schedule (its
# ``default_lr``, e.g. Suite-IN++'s 1e-4, constant; auxiliary losses from the start), which needs
# the papers' ~100 epochs. Measured with `wearnav train suitein++ --data <small> --epochs 12`,
# seed 0 (validation velocity MSE; standing still 0.628): with the earlier 526 K Suite-IN++, paper
# 0.624 (test ATE 17.5 m, standing still 15.4 m), lr 1e-3 cosine over all epochs 0.233, lr 3e-3
# cosine 0.025 (test 10.3 m), lr 1e-3 held half then cosine 0.044 (3.6 m); the ~5-epoch plateau
# at the trivial answer is the auxiliary losses' (177 K mixed Suite-IN++: 0.131 with them from
# the start, 0.017 without them, 0.020 ramped in); today's 496.8 K Suite-IN++ with this recipe
# 0.012 (test ATE 2.2 m).
RECIPES = ("fast", "paper")
FAST_HOLD = 0.5  # share of the epochs at the full lr before the cosine decay ("fast")


def _needs_heading_frame(model: str) -> bool:
    """Whether ``model`` only runs on windows in the device's heading frame (a registry flag; an
    unknown name: no, it is refused where it is built)."""
    try:
        return registry.get(model).heading_frame
    except ConfigError:
        return False


@dataclass(frozen=True)
class TrainConfig:
    """Everything that decides a trained odometry model. Saved as YAML in the run folder.

    ``recipe`` (:data:`RECIPES`) decides the learning-rate schedule; ``lr`` of None takes the
    recipe's (``fast``: 1e-3; ``paper``: the model's ``default_lr``, else 1e-3) and ``batch`` of
    None the model's ``default_batch``, else 128. ``max_minutes`` bounds the run's total training time
    over all its attempts (Lightning's Timer is restored on resume; rerun with a larger value to
    give a run more time); it does not enter the run's hash.
    """

    model: str
    data: str
    devices: tuple[str, ...] = ("phone", "watch", "earbuds")
    model_args: dict[str, Any] = field(default_factory=dict)
    train_split: str = "train"
    val_split: str = "val"
    rate: float = 25.0
    window: int = 100
    stride: int = 10
    epochs: int = 100
    patience: int = 10
    lr: float | None = None
    batch: int | None = None
    recipe: str = "fast"
    augment: tuple[str, ...] = ("rotate_yaw",)
    seed: int = 0
    max_minutes: float | None = None
    # preprocessing beyond the Suite-IN++ defaults (wearnav.preprocess.PreprocessConfig)
    # ``frame_align``: the training recordings' frame; ``eval_frame_align``: the validation and test
    # recordings' (used for model selection and scoring) — by default one constant yaw from the
    # truth's first 10 s ("initial", Suite-IN++'s single initial rotation), never the truth's yaw
    # over time; "truth" there is a named diagnostic. Where training uses no truth alignment
    # ("none", "common"), evaluation uses the same as training (see :meth:`eval_config`).
    frame_align: str = "truth"
    eval_frame_align: str = "initial"
    truth_max_gap: float = TRUTH_MAX_GAP_S
    yaw_deg: float = 0.0
    # the loss on the velocity (wearnav.models.base.velocity_loss): "mse", the papers' (which
    # shortens a velocity whose direction is uncertain), or "polar" (log speed + direction apart)
    vel_loss: str = "mse"
    # each window in the carrying device's heading frame (PreprocessConfig.heading_frame); no random
    # yaw then (it would turn away what the frame gives). Left out of configs while False.
    heading_frame: bool = field(default=False, metadata={runs.OMIT_AT_DEFAULT: True})
    # the training sequences also played this many times faster (wearnav.preprocess.time_warped),
    # each factor one more copy; left out of configs while empty
    speed_warp: tuple[float, ...] = field(default=(), metadata={runs.OMIT_AT_DEFAULT: True})

    def __post_init__(self) -> None:
        check_field_types(self)
        if not self.heading_frame and _needs_heading_frame(self.model):  # e.g. pdr-pointing: its input is that frame
            object.__setattr__(self, "heading_frame", True)
            object.__setattr__(self, "augment", tuple(a for a in self.augment if a != "rotate_yaw"))
        if self.heading_frame and "rotate_yaw" in self.augment:
            raise ConfigError("heading_frame keeps the device's heading as the window's frame: drop rotate_yaw")
        if self.vel_loss not in VEL_LOSSES:
            raise ConfigError(f"velocity loss must be one of {', '.join(VEL_LOSSES)}, got {self.vel_loss!r}")
        for name in self.augment:  # every name before any work (a bench builds its configs first)
            augmentation(name)
        check_speed_warp(self.speed_warp)
        if self.epochs < 1:
            raise ConfigError(f"epochs must be ≥ 1, got {self.epochs}")
        if self.seed < 0:
            raise ConfigError(f"seed must be ≥ 0, got {self.seed}")
        if self.max_minutes is not None and not self.max_minutes > 0:
            raise ConfigError(f"max time must be positive minutes, got {self.max_minutes}")
        if not self.devices:
            raise ConfigError("at least one device must be named")
        if self.lr is not None and not self.lr > 0:
            raise ConfigError(f"lr must be positive, got {self.lr}")
        if self.recipe not in RECIPES:
            raise ConfigError(f"recipe must be one of {', '.join(RECIPES)}, got {self.recipe!r}")
        if self.batch is not None and self.batch < 1:
            raise ConfigError(f"batch must be ≥ 1, got {self.batch}")
        self.preprocess_config()  # their own checks (rate, frame alignment, window sizes), here
        PreprocessConfig(frame_align=self.eval_frame_align)
        self.window_config()  # so that a damaged config.yaml is refused when it is read

    @classmethod
    def from_dict(cls, d: dict) -> TrainConfig:
        names = {f.name: f for f in dataclasses.fields(cls)}
        unknown = set(d) - set(names)
        if unknown:
            raise ConfigError(f"unknown training config keys: {sorted(unknown)}")
        kw: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(**kw)

    def preprocess_config(self) -> PreprocessConfig:
        return PreprocessConfig(
            rate=self.rate,
            devices=tuple(self.devices),
            frame_align=self.frame_align,
            truth_max_gap=self.truth_max_gap,
            yaw_deg=self.yaw_deg,
            heading_frame=self.heading_frame,
        )

    def eval_config(self) -> TrainConfig:
        """This config as validation and test recordings are prepared: ``frame_align`` replaced by
        ``eval_frame_align`` where training aligns onto the truth ("truth" or "initial"); a
        training frame without truth ("none", "common") is kept, so a test input never holds more
        ground truth than the training input did."""
        if self.frame_align in ("none", "common"):
            return self
        return dataclasses.replace(self, frame_align=self.eval_frame_align)

    def window_config(self, stride: int | None = None, target: str | None = "velocity") -> WindowConfig:
        return WindowConfig(window=self.window, stride=stride or self.stride, target=target)


HASH_EXCLUDE = ("max_minutes",)


def build_model(cfg: TrainConfig) -> torch.nn.Module:
    model = registry.build(cfg.model, n_devices=len(cfg.devices), window=cfg.window, **cfg.model_args)
    if isinstance(model, OdometryModel):  # read by the model's own loss(); inference does not depend on it
        model.vel_loss = cfg.vel_loss
    return model


def recipe_schedule(recipe: str, epochs: int, steps_per_epoch: int) -> Schedule:
    """The learning-rate schedule of ``recipe`` (:data:`RECIPES`) over ``epochs`` of
    ``steps_per_epoch`` optimizer steps."""
    if recipe == "paper":
        return Schedule()
    total = epochs * steps_per_epoch
    hold = int(FAST_HOLD * total)
    return Schedule(warmup_steps=steps_per_epoch, total_steps=total, decay_from=hold, aux_warmup_steps=hold)


class OdometryModule(SeededModule):
    def validation_step(self, batch, batch_idx):
        vel = self.model(batch["x"], batch["mask"])
        mse = torch.mean((vel - batch["vel"]) ** 2)
        self.log("val/vel_mse", mse, prog_bar=True, batch_size=batch["x"].shape[0], sync_dist=True)


def _check_windows(ds: WindowDataset, what: str, data: str) -> None:
    if len(ds) == 0:
        raise ValidationError(
            f"no {what} windows with truth (is the split empty, or has the data no dense truth?)", data
        )


def fit(
    cfg: TrainConfig,
    run: str | Path,
    progress: bool = True,
    devices: int = 1,
    strategy: str = "auto",
    resident: bool | None = None,
) -> dict:
    """Train ``cfg.model`` into run folder ``run`` (resuming from its last.ckpt if present).

    ``devices``/``strategy``: one training spread over several GPUs or CPU processes (Lightning's
    DDP, :func:`wearnav.train.common.make_trainer`); ``cfg.batch`` stays the global batch, so the
    run (and its folder) is the same on one device or many. With ``strategy="ddp"`` Lightning
    starts the other processes by re-running this command; they end here, after training.
    ``resident``: keep every window on the training device (:meth:`WindowDataset.to`); None: on a
    single GPU, where the host data path would keep it waiting (issue 37). The batches are the same
    bit for bit either way, so it never enters the run's config.

    Returns the training record that :func:`wearnav.evaluate.evaluate_run` merges into
    metrics.json: epochs run, best epoch and validation MSE, wall time, seconds per epoch, what
    stopped the run, whether it beat standing still (``beats_trivial``, ``trivial_val_vel_mse``:
    :func:`zero_velocity_mse`) and the training data's facts (``training_data``:
    :func:`wearnav.trust.data_facts`, for `wearnav track`'s warnings). Models that are not learned (PDR) are not fitted. Holds the run folder's
    lock while it runs (:func:`wearnav.runs.locked`): a second process is refused.
    """
    with runs.locked(run):
        return _fit(cfg, Path(run), progress, devices, strategy, resident)


def finished(run: Path, cfg: TrainConfig) -> dict | None:
    """The training record of ``run`` when its training ended for good: stopped early, or all of
    ``cfg.epochs`` run. A run stopped by its time budget is not finished (a larger ``--max-time``
    resumes it). Resuming a finished run restarts early stopping's patience and trains on (seen: a
    run stopped early after 27 epochs resumed from a last.ckpt at epoch 17 when a second site was
    added to its benchmark), changing a model already scored."""
    f = run / TRAINING
    if not (f.is_file() and (run / CHECKPOINTS / BEST).is_file()):
        return None
    rec = read_json(f)
    if rec.get("stopped_by") == "early stopping" or (rec.get("epochs_run") or 0) >= cfg.epochs:
        return rec
    return None


def _fit(cfg: TrainConfig, run: Path, progress: bool, devices: int, strategy: str, resident: bool | None) -> dict:
    L.seed_everything(cfg.seed, workers=True, verbose=False)  # before the weights are drawn
    model = build_model(cfg)
    spec = registry.get(cfg.model)
    if not spec.learned:
        runs.write_json(Path(run) / TRAINING, {"learned": False})
        return {"learned": False}
    if (done := finished(run, cfg)) is not None:  # a finished run is kept, not resumed (its patience would restart)
        log.info(f"{run.name}: finished earlier ({done['stopped_by']}, {done['epochs_run']} epochs), not resumed")
        return done
    model_lr: float = getattr(model, "default_lr", DEFAULT_LR) if cfg.recipe == "paper" else DEFAULT_LR
    model_batch: int = getattr(model, "default_batch", DEFAULT_BATCH)
    lr, batch = cfg.lr or model_lr, cfg.batch or model_batch
    train_view, val_view, val_note = train_val_views(Dataset.open(cfg.data), cfg.train_split, cfg.val_split)
    train_seqs = load_sequences(train_view, cfg, progress)
    train_seqs += [time_warped(s, k) for k in cfg.speed_warp for s in train_seqs]
    if len(val_view) == 0:
        raise ValidationError(f"split {cfg.val_split!r} is empty; name a validation split with --val-split", cfg.data)
    val_seqs = load_sequences(val_view, cfg.eval_config(), progress)
    train_ds = WindowDataset(train_seqs, cfg.window_config())
    val_ds = WindowDataset(val_seqs, cfg.window_config())
    _check_windows(train_ds, f"training ({cfg.train_split})", cfg.data)
    _check_windows(val_ds, f"validation ({cfg.val_split})", cfg.data)
    # what the model is trained on, for `wearnav track` to compare a recording with (wearnav.trust)
    facts = trust.data_facts(
        [s.recording for s in train_seqs if s.recording is not None], cfg.devices, cfg.window / cfg.rate
    )

    steps = -(-len(train_ds) // batch)  # optimizer steps per epoch (the last batch may be partial)
    module = OdometryModule(model, lr, cfg.augment, cfg.seed, recipe_schedule(cfg.recipe, cfg.epochs, steps))
    ckpt_dir = run / CHECKPOINTS
    trainer, checkpoint, stopper = make_trainer(
        run,
        cfg.epochs,
        cfg.max_minutes,
        progress,
        len(train_ds) // batch,
        monitor="val/vel_mse",
        mode="min",
        patience=cfg.patience,
        devices=devices,
        strategy=strategy,
    )
    device = trainer.strategy.root_device
    if resident is None:
        resident = device.type == "cuda" and trainer.world_size == 1
    if resident:  # every window on the device: one gather per batch (WindowDataset.to)
        train_ds.to(device)
        val_ds.to(device)
    last = ckpt_dir / LAST
    resumed = last.is_file()
    # A resumed run adds to what earlier attempts measured: epochs already done, wall time spent.
    before_epochs = int(torch.load(last, map_location="cpu", weights_only=False)["epoch"]) + 1 if resumed else 0
    earlier = read_json(run / TRAINING) if resumed and (run / TRAINING).is_file() else {}
    if resumed:
        log.info(f"{run.name}: resuming from {last} ({before_epochs} epoch(s) done)")
    t0 = time.perf_counter()
    with stop_between_batches(trainer):  # Ctrl-C / SIGTERM: exit 130 / 143, last.ckpt intact
        trainer.fit(
            module,
            train_ds.loader(batch, cfg.seed, shard=True),
            val_ds.loader(1024, shard=True),
            ckpt_path=str(last) if last.is_file() else None,
        )
    wall = time.perf_counter() - t0
    if trainer.global_rank > 0:  # a DDP worker that re-ran the command: rank 0 records and evaluates
        sys.exit(0)
    epochs = max(int(trainer.current_epoch), before_epochs)  # a resume that stops at once did none
    stopped = (
        "early stopping"
        if stopper.stopped_epoch > 0
        else "max time"
        if cfg.max_minutes and epochs < cfg.epochs
        else "max epochs"
    )
    best = checkpoint.best_model_score
    record = {
        "learned": True,
        "lr": lr,
        "batch": batch,
        "train_windows": len(train_ds),
        "val_windows": len(val_ds),
        "epochs_run": epochs,
        "stopped_by": stopped,
        "best_val_vel_mse": None if best is None else float(best),
        "wall_s": round(wall + earlier.get("wall_s", 0.0), 2),
        # this attempt's own rate; an attempt that ran no epoch keeps the earlier one
        "s_per_epoch": (
            round(wall / (epochs - before_epochs), 2) if epochs > before_epochs else earlier.get("s_per_epoch")
        ),
        "resumed": resumed,
        "attempts": earlier.get("attempts", 1) + 1 if resumed else 1,
        "accelerator": str(trainer.strategy.root_device),
        "data_on_device": bool(resident),  # how it ran (not hashed): WindowDataset.to
        "gpu_busy_pct": next((c.busy_pct for c in trainer.callbacks if isinstance(c, GpuBusy)), None),
        "processes": trainer.world_size,  # how it ran (not hashed): DDP processes
        # did it learn: its best validation MSE against standing still's on the same windows
        **trust.odometry_baseline(None if best is None else float(best), zero_velocity_mse(val_ds)),
        "training_data": facts,
    }
    if val_note:  # the validation part was chosen here (wearnav.dataset.train_val_views)
        record["validation"] = val_note
    runs.write_json(run / TRAINING, record)
    return record


def zero_velocity_mse(ds: WindowDataset) -> float:
    """The validation MSE ((m/s)², over windows and both axes, as ``val/vel_mse``) of standing
    still: predicting zero velocity for every window of ``ds``."""
    L = ds.cfg.window
    sq = []
    for i, seq in enumerate(ds.sequences):
        s = ds.index[ds.index[:, 0] == i, 1]
        if len(s) and seq.pos is not None:
            vel = (seq.pos[s + L - 1] - seq.pos[s]) / (seq.t[s + L - 1] - seq.t[s])[:, None]
            sq.append(vel**2)
    return float(np.mean(np.concatenate(sq))) if sq else float("nan")


# Where a loaded model's speed comes from (:func:`load_model`): the model itself; PDR's step
# counter with the model's direction (wearnav.models.pdr.PDRSpeed, issue 34's hybrid), its steps
# 0.67 m long or ("cadence") as long as the cadence makes them (pdr.STEP_PER_CADENCE_M_S); or the
# model's speed alone, along where the phone points (wearnav.models.base.AlongPointing; a model in
# the heading frame only); or ("snapped") the cadence hybrid with the model's direction turned onto
# where the phone points wherever it is within SNAP_DEG of it (wearnav.models.base.SnapToPointing;
# the heading frame only).
SPEED_SOURCES = ("model", "pdr", "cadence", "pointing", "snapped")
POINTING_SPEEDS = ("pointing", "snapped")  # the sources that read the phone's pointing: heading frame only


def load_model(run: str | Path, which: str = BEST, speed: str = "model") -> tuple[torch.nn.Module, TrainConfig]:
    """The model of a run folder with its ``best`` (or ``last``) weights, in eval mode; where the
    run was adapted with a speed scale (:func:`velocity_scale`), wrapped to apply it. ``speed``
    "pdr": its direction at PDR's speed in the same window (:class:`wearnav.models.pdr.PDRSpeed`);
    "cadence": the same with steps as long as the window's cadence makes them;
    "pointing": its speed along where the phone points (:class:`wearnav.models.base.AlongPointing`),
    for a run trained in the heading frame (:func:`with_speed`); "snapped": "cadence" with its
    direction turned onto the phone's pointing where it is near it
    (:class:`wearnav.models.base.SnapToPointing`), for a run trained in the heading frame."""
    run = Path(run)
    check_run_kind(run, "odometry")  # a classifier's run: say so, not "unknown config keys"
    cfg = runs.read_run_config(run, TrainConfig)
    model = build_model(cfg)
    if registry.get(cfg.model).learned:
        load_weights(model, run / CHECKPOINTS / which)
    scale = velocity_scale(run)
    if scale != 1.0:
        model = ScaledVelocity(model, scale)
    model = with_speed(model, cfg, speed)
    model.eval()
    return model, cfg


def with_speed(model: torch.nn.Module, cfg: TrainConfig, speed: str) -> torch.nn.Module:
    """``model`` (of ``cfg``) with its speed taken from ``speed`` (:data:`SPEED_SOURCES`): itself
    unchanged for "model", else wrapped as :func:`load_model` describes (a learned model only: PDR's
    speed is its own; "pointing" only for one trained in the heading frame)."""
    if speed not in SPEED_SOURCES:
        raise ConfigError(f"speed must come from one of {', '.join(SPEED_SOURCES)}, got {speed!r}")
    if speed == "model":
        return model
    if not registry.get(cfg.model).learned:
        raise ConfigError(f"a speed from {speed!r} needs a learned model: {cfg.model}'s speed is its own")
    if speed in POINTING_SPEEDS and not cfg.heading_frame:
        raise ConfigError(f"{cfg.model}: only a model trained in the heading frame has the phone's pointing as +x")
    if speed == "pointing":
        return AlongPointing(model)
    if speed == "snapped":
        model = SnapToPointing(model)
    cadence = STEP_PER_CADENCE_M_S if speed in ("cadence", "snapped") else None
    return PDRSpeed(model, PDR(len(cfg.devices), cfg.window, rate=cfg.rate, step_per_cadence=cadence))


def velocity_scale(run: str | Path) -> float:
    """The factor `wearnav adapt --method scale` stored in the run's :data:`ADAPTATION` (1.0 where
    the run was not adapted); an unreadable or non-positive one is a FormatError naming the file."""
    path = Path(run) / ADAPTATION
    if not path.is_file():
        return 1.0
    doc = read_json(path)
    scale = doc.get("velocity_scale", 1.0) if isinstance(doc, dict) else None
    if not isinstance(scale, (int, float)) or not np.isfinite(scale) or scale <= 0:
        raise FormatError(f"velocity_scale must be a positive number, got {scale!r}", path)
    return float(scale)


def run_record(cfg: TrainConfig) -> dict:
    """What a run folder's config.yaml holds under ``config`` (and what its hash is taken of)."""
    return {
        "train": runs.to_dict(cfg),
        "preprocess": runs.to_dict(cfg.preprocess_config()),
        "eval_preprocess": runs.to_dict(cfg.eval_config().preprocess_config()),
    }


def run_hash_exclude(record: dict) -> dict:
    train = {k: v for k, v in record["train"].items() if k not in HASH_EXCLUDE}
    if train.get("vel_loss") == "mse":  # every run before the field had it: their folders keep their names
        del train["vel_loss"]
    return {**record, "train": train}


def validation_note(cfg: TrainConfig) -> str | None:
    """How ``cfg``'s validation recordings are chosen when the dataset has no ``cfg.val_split``
    (:func:`wearnav.dataset.train_val_views`), else None; shown before training starts."""
    if not registry.get(cfg.model).learned:
        return None
    return train_val_views(Dataset.open(cfg.data), cfg.train_split, cfg.val_split)[2]


def dataset_defaults(data: str | Path) -> dict[str, tuple[Any, str | None]]:
    """The :class:`TrainConfig` fields that ``data`` decides when the user names none: field →
    (value, a line saying why, or None where it is the usual default). ``devices``, those its recordings have (phone, watch, earbuds first, in
    that order); ``truth_max_gap``, ``SURVEYED_TRUTH_MAX_GAP_S`` where its truth is surveyed points
    (median below ``SPARSE_TRUTH_HZ`` points per second: an imported real building), so that the
    points are joined by straight lines into training targets."""
    m = Dataset.open(data).manifest
    have = {d for s in m["devices"].astype(str) for d in s.split(";") if d}
    devices = tuple(d for d in CANONICAL_DEVICES if d in have) + tuple(sorted(have - set(CANONICAL_DEVICES)))
    fields: dict[str, tuple[Any, str | None]] = {}
    if devices:
        fields["devices"] = (
            devices,
            None
            if devices == CANONICAL_DEVICES
            else f"devices: {', '.join(devices)} (those the dataset's recordings have)",
        )
    with_truth = m[m["truth_points"] >= 2]
    if len(with_truth):
        hz = float((with_truth["truth_points"] / with_truth["duration"].clip(lower=1e-9)).median())
        if hz < SPARSE_TRUTH_HZ:
            fields["truth_max_gap"] = (
                SURVEYED_TRUTH_MAX_GAP_S,
                f"truth: surveyed points ({hz:.2f} per second), joined by straight lines "
                f"across gaps up to {SURVEYED_TRUTH_MAX_GAP_S:g} s into training targets",
            )
    return fields


def configure(
    model: str,
    data: str | Path,
    devices: tuple[str, ...] | None = None,
    eval_splits: tuple[str, ...] = ("test",),
    **fields,
) -> tuple[TrainConfig, tuple[str, ...], list[str]]:
    """`wearnav train`'s config for ``model`` on ``data``: the fields the data decides where the user
    gave none (:func:`dataset_defaults`; ``devices`` None: the dataset's), the ``eval_splits`` the
    data has (:func:`evaluation_splits`), and one line for each choice made for the user (devices,
    truth gaps, the validation part, a missing test split), to show before training starts."""
    defaults = dataset_defaults(data)
    if devices is not None:
        defaults["devices"] = (tuple(devices), None)
    cfg = TrainConfig(model=model, data=str(data), **{k: v for k, (v, _) in defaults.items()}, **fields)
    splits, no_eval = evaluation_splits(cfg, eval_splits) if eval_splits else ((), None)
    notes = [note for _, note in defaults.values()] + [validation_note(cfg), no_eval]
    return cfg, splits, [n for n in notes if n]


def evaluation_splits(cfg: TrainConfig, splits: tuple[str, ...] = ("test",)) -> tuple[tuple[str, ...], str | None]:
    """Of the splits to evaluate after training, those that ``cfg.data`` has, and a note naming the
    ones it lacks and the splits it has (an imported real dataset often has no ``test``)."""
    known = sorted({str(s) for s in Dataset.open(cfg.data).manifest["split"] if str(s)})
    missing = [s for s in splits if s not in known]
    if not missing:
        return splits, None
    return (
        tuple(s for s in splits if s in known),
        f"the dataset has no {' or '.join(repr(s) for s in missing)} split (its splits: {', '.join(known) or 'none'}): "
        "not evaluated after training; evaluate with `wearnav eval RUN --split NAME` (or --data ANOTHER)",
    )


def check_devices(ds, devices: tuple[str, ...]) -> None:
    """Refuse a device layout naming a device that no recording of ``ds`` has (a typo would
    otherwise train on zeros where that device's input belongs)."""
    have = sorted({d for s in ds.manifest["devices"].astype(str) for d in s.split(";") if d})
    check_names(devices, have, "device", ds.root)  # valid: those the dataset's recordings have


def prepare_run(cfg: TrainConfig, run: str | Path, eval_splits: tuple[str, ...] = ()) -> Path:
    """Create (or reuse) run folder ``run`` for ``cfg``: a folder holding another config is refused,
    so a resumed run never mixes two configurations. ``eval_splits``: the splits the run will be
    evaluated on after training, checked now (known, with truth) rather than after the training."""
    run = Path(run)
    spec = registry.get(cfg.model)  # an unknown model is refused before anything is written
    if spec.task != "odometry":
        odometry = ", ".join(s.name for s in registry.available() if s.task == "odometry")
        raise ConfigError(f"{cfg.model!r} is a {spec.task} model; `wearnav train` trains odometry models ({odometry})")
    record = run_record(cfg)
    if (run / runs.CONFIG).is_file():
        old = runs.read_config(run)["config"]
        if run_hash_exclude(old) != run_hash_exclude(record):
            raise ConfigError("holds a run of another configuration; choose another --out", run)
        for split in eval_splits:
            scorable_split(Dataset.open(cfg.data), split)
        return run
    if not runs.is_blank(run):
        raise ConfigError("exists and is not an empty folder or a run folder; choose another --out", run)
    ds = Dataset.open(cfg.data)
    check_devices(ds, cfg.devices)
    if registry.get(cfg.model).learned:
        for split, view in zip(
            (cfg.train_split, cfg.val_split), train_val_views(ds, cfg.train_split, cfg.val_split)[:2]
        ):
            if len(view) == 0:
                raise ValidationError(f"split {split!r} is empty", cfg.data)
            if (view.manifest["truth_points"].astype(float) < 2).all():
                raise ValidationError(
                    f"no training data: the {split!r} recordings have no truth positions "
                    "(odometry training needs truth)",
                    cfg.data,
                )
    for split in eval_splits:
        scorable_split(ds, split)
    run.mkdir(parents=True, exist_ok=True)
    runs.write_config(run, record, {"data_provenance": ds.provenance})
    return run
