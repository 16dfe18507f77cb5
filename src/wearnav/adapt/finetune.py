"""Fine-tuning an odometry model on a user's fix-labelled segments (issue 18 §3, method
``finetune``; EasyTrack's idea, paper 004 §III, kept simple: no label-noise model).

Loss per segment i of duration T_i, on its mean velocity: Huber(A_i · v / T_i, y_i / T_i), with
A_i · v the model's window velocities integrated over the segment
(:func:`wearnav.adapt.segments.integration_weights`) and the target y_i fixed for the run (so it
does not chase the model), from the fixes' displacement d̃_i and the *un-adapted* model's d_i:

``loss="length"`` (default)  y_i = |d̃_i| · d_i / |d_i|: the fixes' length in the un-adapted
    model's direction, what the ``scale`` method reads from the fixes;
``loss="vector"``            y_i = R(−ψ_i) d̃_i: the fixes' displacement turned into the phone's
    world frame by the yaw fitted against the un-adapted model
    (:func:`wearnav.adapt.segments.segment_yaw`). Least squares on it learns the mean target,
    which shrinks by the cosine of every heading disagreement between fixes and odometry (why
    :func:`wearnav.adapt.segments.compare` uses lengths): with a first development model on
    IPIN's training trials the adapted paths came out 0.77 of the truth's length, the fixes'
    own being 0.90. A loss on lengths alone (|A_i · v| against |d̃_i|) leaves the heading free:
    the same model's known-start error at the training trials' POSI points went from 5.4 to 15.4 m.

Huber, because a fix jump the jump filter lets
through (~5 m over 10 s, 0.5 m/s) must not dominate the mean. Each walk's windows (and vector
labels) of a batch are turned by one random yaw, as training's ``rotate_yaw`` does, so the model
stays yaw-equivariant. A heading-frame model (``PreprocessConfig.heading_frame``) gets no random
yaw (its windows carry none); its window velocities are turned back by each window's heading
before they are integrated, as :func:`wearnav.evaluate.predict_sequence` does.

The network stays in eval mode while its weights move (batch-norm statistics frozen, no
dropout): a few hundred noisy segments are not enough to re-estimate them, and a low learning
rate only nudges the weights. Early stopping on the held-out segments' loss, measured before
the first epoch too; the best weights are kept (the un-adapted ones when no epoch beats them).
"""

from __future__ import annotations

import copy
import logging
import math
from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional as F

from wearnav.adapt.segments import (
    WalkSegments,
    integration_weights,
    odometry_displacements,
    rotate,
    segment_yaw,
    window_centres,
)
from wearnav.errors import ConfigError
from wearnav.preprocess.augment import rotate_batch
from wearnav.preprocess.windows import WindowConfig, WindowDataset

log = logging.getLogger(__name__)

LOSSES = ("length", "vector")


@dataclass(frozen=True)
class FinetuneConfig:
    """How the weights are fine-tuned (module docstring)."""

    epochs: int = 5
    lr: float = 1e-4
    patience: int = 2
    batch: int = 16  # segments per step
    stride_s: float = 1.0  # window spacing while fine-tuning (prediction keeps the run's stride)
    huber_m_s: float = 0.5
    loss: str = "length"  # "length" or "vector" (module docstring)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.loss not in LOSSES:
            raise ConfigError(f"fine-tuning loss must be one of {', '.join(LOSSES)}, got {self.loss!r}")
        if self.epochs < 1 or self.batch < 1 or self.patience < 1 or not (self.lr > 0 and self.stride_s > 0):
            raise ConfigError(f"fine-tuning needs epochs, batch, patience ≥ 1 and a positive lr and stride, got {self}")


@dataclass
class _Walk:
    """A walk's tensors: windows ``x`` (K, D, L, 6), ``mask`` (K, D), ``A`` (n, K), the labels
    (n, 2) in the phone's world frame, the segments' durations (n,) and, in the heading frame, each
    window's heading ``yaw`` (K,)."""

    x: torch.Tensor
    mask: torch.Tensor
    A: torch.Tensor
    label: torch.Tensor
    duration: torch.Tensor
    yaw: torch.Tensor | None = None


def _prepare(model, seg: WalkSegments, window: int, stride: int, loss: str) -> _Walk | None:
    wds = WindowDataset([seg.seq], WindowConfig(window=window, stride=stride, target=None))
    if len(wds) == 0:
        return None
    b = wds[np.arange(len(wds))]
    c = window_centres(seg.seq, window, stride)
    d_odo = odometry_displacements(model, seg, window, stride)
    if loss == "vector":
        label = rotate(seg.d_fix, -segment_yaw(d_odo, seg.d_fix, 0.5 * (seg.t0 + seg.t1)))
    else:
        length = np.linalg.norm(d_odo, axis=1, keepdims=True)
        label = np.where(length > 1e-6, d_odo / np.maximum(length, 1e-6), 0.0) * np.linalg.norm(
            seg.d_fix, axis=1, keepdims=True
        )
    f32 = lambda a: torch.as_tensor(np.asarray(a), dtype=torch.float32)
    A = f32(integration_weights(c, seg.t0, seg.t1))
    return _Walk(b["x"], b["mask"], A, f32(label), f32(seg.t1 - seg.t0), b["yaw"].double() if "yaw" in b else None)


def _turned(v: torch.Tensor, psi: torch.Tensor) -> torch.Tensor:
    """Velocities (N, 2) turned counter-clockwise by ``psi`` (N,) rad (:func:`wearnav.preprocess.windows.turn`)."""
    c, s = torch.cos(psi).to(v.dtype), torch.sin(psi).to(v.dtype)
    return torch.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], dim=1)


def _loss(
    model, walks: list[_Walk], batch: list[tuple[int, np.ndarray]], delta: float, gen: torch.Generator | None
) -> torch.Tensor:
    """Mean Huber loss over the segments ``batch`` ((walk, segment indices) pairs); ``gen``: draw
    one random yaw per walk (training), None: no rotation."""
    xs, masks, yaws, parts = [], [], [], []
    for w, idx in batch:
        walk = walks[w]
        A = walk.A[idx]
        cols = torch.nonzero(A.abs().sum(dim=0) > 0).flatten()
        x, label = walk.x[cols], walk.label[idx]
        if walk.yaw is not None:
            yaws.append(walk.yaw[cols])
        elif gen is not None:
            angle = float(torch.rand(1, generator=gen)) * 2 * math.pi
            x = rotate_batch({"x": x}, torch.full((x.shape[0],), angle))["x"]
            c, s = math.cos(angle), math.sin(angle)
            label = torch.stack([c * label[:, 0] - s * label[:, 1], s * label[:, 0] + c * label[:, 1]], dim=1)
        xs.append(x)
        masks.append(walk.mask[cols])
        parts.append((A[:, cols], label, walk.duration[idx], x.shape[0]))
    vel = model(torch.cat(xs), torch.cat(masks))
    if yaws:  # heading-frame windows: every walk has them (one model, one preprocessing)
        vel = _turned(vel, torch.cat(yaws))
    pred, target, k = [], [], 0
    for A, label, T, n in parts:
        pred.append((A @ vel[k : k + n]) / T[:, None])
        target.append(label / T[:, None])
        k += n
    return F.huber_loss(torch.cat(pred), torch.cat(target), delta=delta)


def _batches(walks: list[_Walk], size: int, rng: np.random.Generator | None) -> list[list[tuple[int, np.ndarray]]]:
    pairs = np.array([(w, i) for w, walk in enumerate(walks) for i in range(walk.A.shape[0])], np.int64).reshape(-1, 2)
    if rng is not None:
        pairs = pairs[rng.permutation(len(pairs))]
    out = []
    for s in range(0, len(pairs), size):
        chunk = pairs[s : s + size]
        out.append([(int(w), chunk[chunk[:, 0] == w, 1]) for w in np.unique(chunk[:, 0])])
    return out


def held_out_loss(model, walks: list[_Walk], cfg: FinetuneConfig) -> float:
    """The mean loss over every held-out segment (no rotation, no gradient)."""
    with torch.no_grad():
        total, n = 0.0, 0
        for b in _batches(walks, 4 * cfg.batch, None):
            m = sum(len(idx) for _, idx in b)
            total += float(_loss(model, walks, b, cfg.huber_m_s, None)) * m
            n += m
    return total / max(n, 1)


def finetune(
    model: torch.nn.Module,
    train: list[WalkSegments],
    held: list[WalkSegments],
    window: int,
    rate: float,
    cfg: FinetuneConfig = FinetuneConfig(),
) -> tuple[torch.nn.Module, list[dict]]:
    """A fine-tuned copy of ``model`` (module docstring) and one record per epoch (epoch 0: before)."""
    model = copy.deepcopy(model).eval()
    stride = max(1, int(round(cfg.stride_s * rate)))
    walks = [w for w in (_prepare(model, s, window, stride, cfg.loss) for s in train) if w is not None]
    held_walks = [w for w in (_prepare(model, s, window, stride, cfg.loss) for s in held) if w is not None]
    torch.manual_seed(cfg.seed)
    gen = torch.Generator().manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    opt = torch.optim.Adam([p for p in model.parameters() if p.requires_grad], lr=cfg.lr)
    best = held_out_loss(model, held_walks, cfg)
    best_state, best_epoch = copy.deepcopy(model.state_dict()), 0
    history = [{"epoch": 0, "held_out_loss": round(best, 6)}]
    for epoch in range(1, cfg.epochs + 1):
        losses = []
        for b in _batches(walks, cfg.batch, rng):
            loss = _loss(model, walks, b, cfg.huber_m_s, gen)
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
        held_loss = held_out_loss(model, held_walks, cfg)
        history.append(
            {"epoch": epoch, "train_loss": round(float(np.mean(losses)), 6), "held_out_loss": round(held_loss, 6)}
        )
        log.info("fine-tune epoch %d: train %.4f, held-out %.4f", epoch, history[-1]["train_loss"], held_loss)
        if held_loss < best:
            best, best_state, best_epoch = held_loss, copy.deepcopy(model.state_dict()), epoch
        elif epoch - best_epoch >= cfg.patience:
            break
    model.load_state_dict(best_state)
    history.append({"best_epoch": best_epoch})
    return model.eval(), history


__all__ = ["FinetuneConfig", "LOSSES", "finetune", "held_out_loss"]
