"""What every training task shares (odometry in :mod:`.odometry`, classification in
:mod:`.classify`): the seeded LightningModule base, the Trainer with its checkpoints, and
loading a checkpoint's weights.

Reproducibility: every random draw of an epoch (shuffling, augmentation, dropout) is seeded from
``(seed, epoch)``, so a run killed mid-epoch and resumed from ``last.ckpt`` replays that epoch
exactly and ends with the same weights and metrics as an uninterrupted run.

Checkpoints are written through :func:`wearnav.core.fileio.atomic_path` with ``durable=True``
(:class:`AtomicCheckpointIO`): a kill or a power cut during a save leaves the previous
``last.ckpt`` / ``best.ckpt``, never a torn one.

Decisions: docs/decisions/0013-training-recipe-and-one-module.md,
docs/decisions/0003-exact-resume-and-batched-fetch.md.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
import threading
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lightning as L
import numpy as np
import torch
from lightning.pytorch.callbacks import Callback, Timer
from lightning.pytorch.plugins import TorchCheckpointIO

from wearnav import runs
from wearnav.core.fileio import atomic_path
from wearnav.core.progress import eta_line, interval_s, on_terminal
from wearnav.errors import ConfigError, FormatError, MissingFileError
from wearnav.models import registry
from wearnav.preprocess.augment import apply as augment_batch

log = logging.getLogger(__name__)

CHECKPOINTS = "checkpoints"
BEST, LAST = "best.ckpt", "last.ckpt"


class AtomicCheckpointIO(TorchCheckpointIO):
    """Lightning's checkpoint I/O with the save made atomic and durable.

    Lightning's own save (``lightning.fabric.utilities.cloud_io._atomic_save``, 2.6) writes to a
    temporary file in the *system* temp folder and moves it over the checkpoint: a rename when
    that folder is on the same file system, a copy (torn if killed midway) when it is not, and
    never an fsync. Here the temporary file sits beside the checkpoint and is fsynced, then renamed.
    """

    def save_checkpoint(self, checkpoint: dict, path, storage_options=None) -> None:
        if storage_options is not None:
            raise TypeError(f"{type(self).__name__} takes no storage_options")
        with atomic_path(path, durable=True) as tmp:
            torch.save(checkpoint, tmp)


@dataclass(frozen=True)
class Schedule:
    """The learning rate's factor (× the base lr) at each optimizer step: a linear warm-up from
    ``1 / warmup_steps`` to 1 over the first ``warmup_steps`` steps, 1 until ``decay_from``, then a
    cosine from 1 down to ``final`` at ``total_steps`` (held there after). ``total_steps`` 0: constant 1 (no schedule).
    A callable object, so ``LambdaLR`` saves its state in the checkpoint and a resumed run goes on
    from the same step."""

    warmup_steps: int = 0
    total_steps: int = 0
    final: float = 0.01
    decay_from: int = 0  # the cosine starts here (or after the warm-up, whichever is later)
    aux_warmup_steps: int = 0  # auxiliary losses ramp in linearly over these steps (:meth:`aux`)

    def __call__(self, step: int) -> float:
        if self.total_steps <= 0:
            return 1.0
        if step < self.warmup_steps:
            return (step + 1) / self.warmup_steps
        start = max(self.warmup_steps, self.decay_from)
        if step < start:
            return 1.0
        span = max(self.total_steps - start, 1)
        done = min((step - start) / span, 1.0)
        return self.final + (1.0 - self.final) * 0.5 * (1.0 + math.cos(math.pi * done))

    def aux(self, step: int) -> float:
        """The weight (0–1) on a model's auxiliary losses at ``step``: 0 → 1 linearly over
        ``aux_warmup_steps`` (none: 1 throughout)."""
        return 1.0 if self.aux_warmup_steps <= 0 else min(step / self.aux_warmup_steps, 1.0)


class SeededModule(L.LightningModule):
    """Adam on ``model`` at ``lr`` × ``schedule`` (per optimizer step; default constant); batch
    augmentations from :mod:`wearnav.preprocess.augment` drawn from a generator seeded per epoch; the
    training loss is ``model.loss(batch)`` → (loss, named parts)."""

    def __init__(
        self,
        model: torch.nn.Module,
        lr: float,
        augment: tuple[str, ...] = (),
        seed: int = 0,
        schedule: Schedule = Schedule(),
    ):
        super().__init__()
        self.model: Any = model  # an OdometryModel or HARNet: loss(batch), an aux_scale where it has one
        self.lr = lr
        self.augment = tuple(augment)
        self.seed = seed
        self.schedule = schedule
        self._gen = torch.Generator()

    def on_train_epoch_start(self) -> None:
        base = self.seed * 1_000_003 + self.current_epoch
        torch.manual_seed(base)  # dropout and any other draw inside the model
        self._gen.manual_seed(base + 7)

    def training_step(self, batch, batch_idx):
        if hasattr(self.model, "aux_scale"):
            self.model.aux_scale = self.schedule.aux(self.global_step)
        if self.augment:
            batch = augment_batch(self.augment, batch, self._gen)
        loss, parts = self.model.loss(batch)
        n = batch["x"].shape[0]
        # sync_dist: under DDP the logged value is the mean over processes (one process: unchanged)
        self.log("train/loss", loss, prog_bar=True, batch_size=n, sync_dist=True)
        for k, v in parts.items():
            self.log(f"train/{k}", v, batch_size=n, sync_dist=True)
        return loss

    def configure_optimizers(self):
        opt = torch.optim.Adam(self.model.parameters(), lr=self.lr)
        if self.schedule.total_steps <= 0:
            return opt
        return {
            "optimizer": opt,
            "lr_scheduler": {"scheduler": torch.optim.lr_scheduler.LambdaLR(opt, self.schedule), "interval": "step"},
        }


STRATEGIES = ("auto", "ddp", "ddp_spawn")


class LogProgress(Callback):
    """Training progress as log lines (:mod:`wearnav.core.progress`) where no bar can be drawn: at most
    every ``interval_s`` seconds, the epoch and batch, and the time left (the epoch limit's
    estimate, or the time budget's remainder if that is sooner)."""

    def __init__(self, name: str, max_minutes: float | None = None, interval: float | None = None):
        self.name, self.max_minutes = name, max_minutes
        self.interval = interval_s() if interval is None else interval
        self.t0 = self.last = time.monotonic()

    def on_train_start(self, trainer, pl_module) -> None:
        self.t0 = self.last = time.monotonic()
        self.first_epoch = trainer.current_epoch

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        now = time.monotonic()
        if now - self.last < self.interval:
            return
        self.last = now
        n_batches = trainer.num_training_batches if isinstance(trainer.num_training_batches, int) else 0
        epoch = trainer.current_epoch + ((batch_idx + 1) / n_batches if n_batches else 0.0)
        line = eta_line(
            f"train {self.name}", round(epoch, 1), trainer.max_epochs, now - self.t0, "epochs", epoch - self.first_epoch
        )
        timer = next((c for c in trainer.callbacks if isinstance(c, Timer)), None)  # --max-time, over resumes
        budget_s = timer.time_remaining("train") if timer is not None else None
        done_here = epoch - self.first_epoch
        epochs_s = (now - self.t0) * (trainer.max_epochs - epoch) / done_here if done_here > 0 else None
        if budget_s is not None and (epochs_s is None or budget_s < epochs_s):  # the time budget ends it sooner
            line = line.split(", about")[0] + f", about {max(budget_s, 0):.0f} s left (--max-time)"
        log.info(line)


class GpuBusy(Callback):
    """How busy the GPU was while training: NVML's utilisation (``torch.cuda.utilization``: the
    share of the last sample period in which at least one kernel ran; it says nothing of how many
    of the SMs a kernel kept busy), sampled every ``every_s`` seconds through every training epoch
    (validation excluded). :attr:`busy_pct` is the mean, or None where no sample could be read
    (no GPU, or no NVML binding: the ``nvidia-ml-py`` package)."""

    def __init__(self, every_s: float = 0.1):
        self.every_s = every_s
        self.samples: list[float] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _sample(self, device: torch.device) -> None:
        while not self._stop.wait(self.every_s):
            try:
                self.samples.append(float(torch.cuda.utilization(device)))
            except Exception:  # no NVML binding (or a driver without it): nothing to report
                return

    def on_train_epoch_start(self, trainer, pl_module) -> None:
        device = trainer.strategy.root_device
        if device.type != "cuda":
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._sample, args=(device,), daemon=True)
        self._thread.start()

    def on_train_epoch_end(self, trainer, pl_module) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None

    @property
    def busy_pct(self) -> float | None:
        return round(float(np.mean(self.samples)), 1) if self.samples else None


def make_trainer(
    run: Path,
    epochs: int,
    max_minutes: float | None,
    progress: bool,
    steps_per_epoch: int,
    monitor: str | None = None,
    mode: str = "min",
    patience: int = 10,
    devices: int = 1,
    strategy: str = "auto",
):
    """The Trainer every task uses: checkpoints/last.ckpt always (a resume point), best.ckpt and
    early stopping on ``monitor`` when one is given. Returns (trainer, checkpoint, stopper|None).

    ``devices``/``strategy``: Lightning's, for one training on several GPUs (or CPU processes):
    ``devices=4, strategy="ddp"`` runs 4 processes, each on its share of every batch (the loaders
    shard batches themselves: ``WindowDataset.loader(shard=True)``, so Lightning's sampler is
    off). How a run is spread never enters its config or hash; fp32 throughout."""
    if devices < 1:
        raise ConfigError(f"devices must be ≥ 1, got {devices}")
    if strategy not in STRATEGIES:
        raise ConfigError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    from lightning.pytorch.callbacks import EarlyStopping, ModelCheckpoint
    from lightning.pytorch.loggers import CSVLogger

    # Lightning's start-up chatter (accelerator lines, product tips) is not for our users.
    logging.getLogger("lightning.pytorch.utilities.rank_zero").setLevel(logging.WARNING)
    warnings.filterwarnings("ignore", message=r"Checkpoint directory .* exists and is not empty")
    warnings.filterwarnings("ignore", message=r".*isinstance\(treespec, LeafSpec\)")
    checkpoint = ModelCheckpoint(
        dirpath=run / CHECKPOINTS,
        filename="best",
        monitor=monitor,
        mode=mode,
        save_last=True,
        enable_version_counter=False,
        save_top_k=1 if monitor else 0,
    )
    callbacks: list[Callback] = [checkpoint, GpuBusy()]
    if progress and not on_terminal():  # no bar can be drawn: periodic log lines instead
        callbacks.append(LogProgress(run.name, max_minutes))
    stopper = None
    if monitor:
        stopper = EarlyStopping(monitor=monitor, patience=patience, mode=mode)
        callbacks.append(stopper)
    trainer = L.Trainer(
        max_epochs=epochs,
        max_time=dt.timedelta(minutes=max_minutes) if max_minutes else None,
        callbacks=callbacks,
        logger=CSVLogger(run, name="logs"),  # logs/version_N: one per attempt, a resume keeps the old
        enable_progress_bar=progress and on_terminal(),
        enable_model_summary=False,
        num_sanity_val_steps=0,
        accelerator="auto",
        devices=devices,
        strategy=strategy,
        use_distributed_sampler=False,
        default_root_dir=run,
        plugins=[AtomicCheckpointIO()],
        deterministic=False,
        log_every_n_steps=max(1, min(50, steps_per_epoch)),
    )
    return trainer, checkpoint, stopper


def load_weights(model: torch.nn.Module, path: Path) -> None:
    """Load a Lightning checkpoint's ``model.*`` weights; a torn or foreign file is one line."""
    if not path.is_file():
        raise MissingFileError(f"no checkpoint {CHECKPOINTS}/{path.name} (was the run trained?)", path.parent.parent)
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
        state = {k.removeprefix("model."): v for k, v in ckpt["state_dict"].items()}
        model.load_state_dict(state)
    except Exception as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FormatError(f"corrupt or incompatible checkpoint: {msg}", path) from None


# What each kind of run is called, and the command that takes it (for a run given to the wrong one).
RUN_KINDS = {
    "odometry": ("an odometry model", "wearnav track (or wearnav eval)"),
    "classify": ("an activity classifier", "wearnav classify"),
    "noisy": ("an EasyTrack noisy-label run", "wearnav bench easytrack"),
}


def run_kind(run: str | Path) -> tuple[str | None, str | None]:
    """(task, model) of a run folder from its config.yaml: ``task`` is a registry task
    (``odometry``, ``classify``) or ``noisy`` for an EasyTrack run; (None, None) when the config
    says neither (the run's loader then reports what is wrong with it)."""
    config = runs.read_config(run)["config"]
    train, noisy = config.get("train"), config.get("noisy")
    if isinstance(train, dict) and isinstance(train.get("model"), str):
        try:
            return registry.get(train["model"]).task, train["model"]
        except ConfigError:
            return None, train["model"]
    if isinstance(noisy, dict):
        return "noisy", str(noisy.get("method", "easytrack"))
    return None, None


def check_run_kind(run: str | Path, task: str) -> None:
    """Refuse a run folder of another kind than ``task`` with what it is and which command takes it,
    e.g. "RUN is an activity classifier (har-cnn-bilstm); use wearnav classify"."""
    kind, model = run_kind(run)
    if kind is not None and kind != task:
        what, command = RUN_KINDS.get(kind, (f"a {kind} model", "another command"))
        raise ConfigError(f"is {what} ({model}), not {RUN_KINDS[task][0]}; use {command}", Path(run))
