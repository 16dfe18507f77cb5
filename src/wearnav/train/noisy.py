"""Learning odometry from noisy phone labels: EasyTrack (paper 004, §IV) and its baselines.

Methods (one :class:`NoisyConfig` each; ``method``):

* ``easytrack``   dual BaseModels + CNAL (eqs. 12–13) + CoAdapt (eqs. 14–18), total loss eq. 19.
* ``easytrack-amended``  the same, CoAdapt amended: no length bias, δ from the data (:mod:`wearnav.train.coadapt`).
* ``nocnal``      EasyTrack without CNAL (labels uncorrected).
* ``nocoadapt``   EasyTrack without CoAdapt (each model trains on all instances with weight 1).
* ``coteaching``  the same dual BaseModels, no CNAL; each model keeps its R(T) small-loss share to
                  train its peer with a fixed forget-rate schedule R(T) = 1 − ε·min(T / T_k, 1)
                  (Han et al. 2018), weights 1.
* ``aux``         the same dual BaseModels with a noise-adaptation layer and no small-loss
                  selection: one free correction vector per *segment* (labels d̃_i + c_i,
                  regulariser γ_aux‖c_i‖², :func:`aux_loss`), i.e. label noise assumed
                  independent, unlike CNAL's chain.
* ``basemodel``   one BaseModel on the noisy labels (MSE + reconstruction); ``basemodel-gt`` the
                  same on the true displacements.
* ``ionet`` / ``ronin``  the registry's models trained on the noisy labels (MSE).

Why a plain loop and not Lightning: one step updates two models from each other's per-instance
selections, a third parameter set (CNAL) with its own learning rate, and moving-average state
(R_δ); with Lightning's manual optimisation all of that would live in hooks anyway. The loop
follows the project's seeding rule instead (every draw of an epoch comes from a generator seeded
by (seed, epoch)) and saves its whole state after every epoch (``state.pt``, atomic), so a killed
run resumes at the next epoch with the same result.

The models' losses are per instance (:func:`wearnav.models.base.instance_velocity_loss` on the
displacements): the MSE over the two components (m², the paper's) or, with ``loss="polar"``, the
log-length error plus the length-weighted direction error (issue 34: the MSE shortens a
displacement whose direction is uncertain; the log floor is then 0.1 m on a ~1-s segment). Sums over instances
(eq. 18) are divided by the batch size (a constant factor, i.e. a learning-rate scale). CNAL's
loss (eq. 13) is taken against the ensemble prediction with the models detached, so CNAL learns
the corrections from every instance while the models learn only from their peer's selection.
The joint phase's learning rate follows a cosine from 8e-4 to the minimum 8e-5 (the paper gives
the two ends, not the curve).

Units: displacements are in metres; the paper reports every length in cm. Two of its
hyper-parameters carry a unit:

* γ = 1 (eq. 13) is γ = 0.01 in metres (the paper's lengths are cm).
* δ = 0.24 (eq. 14) is compared with the per-instance displacement error ‖d̂ − d̃‖₂ in metres
  (:func:`instance_error`), not with the MSE in m². Why, with the numbers: Decision: docs/decisions/0009-easytrack-training-loop-and-units.md.

Decision: docs/decisions/0037-easytrack-polar-loss.md.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn
from torch.nn import functional as F

from wearnav import runs
from wearnav.core.fileio import atomic_path, save_npy_atomic, write_text_atomic
from wearnav.core.progress import Progress
from wearnav.core.rotations import rotate_about_vertical
from wearnav.errors import ConfigError
from wearnav.fixlabels import Segments
from wearnav.models.base import VEL_LOSSES, instance_velocity_loss
from wearnav.models.easytrack import BaseModel
from wearnav.models.registry import build
from wearnav.models.ronin import MIN_WINDOW
from wearnav.train import coadapt

log = logging.getLogger(__name__)

METHODS = (
    "easytrack",
    "easytrack-amended",
    "nocnal",
    "nocoadapt",
    "coteaching",
    "aux",
    "basemodel",
    "basemodel-gt",
    "ionet",
    "ronin",
)
DUAL = ("easytrack", "easytrack-amended", "nocnal", "nocoadapt", "coteaching", "aux")
COADAPT = ("easytrack", "easytrack-amended", "nocnal")  # the methods that select with CoAdapt
CNAL = ("easytrack", "easytrack-amended", "nocoadapt")
AMENDED_FIELDS = ("strata", "delta_mad", "rel_floor")  # NoisyConfig fields only the amended method reads
# per joint epoch, the mean over batches of each of issue 59's diagnostics (wearnav.train.coadapt)
DIAGNOSTICS = ("length_bias", "weighting_length_bias", "delta_scale", "ensemble_shrinkage")
STATE = "state.pt"


@dataclass(frozen=True)
class NoisyConfig:
    method: str = "easytrack"
    seed: int = 0
    ae_epochs: int = 5
    pre_epochs: int = 5
    joint_epochs: int = 190
    batch: int = 64
    lr: float = 8e-4
    lr_min: float = 8e-5
    lr_cnal: float = 2e-4
    betas: tuple[float, float] = (0.5, 0.999)
    tau: float = 0.8  # eq. 15
    eta: float = 1.0  # eq. 15
    beta: float = 0.02  # eq. 14
    delta: float = 0.24  # l_δ in metres of displacement error ‖d̂ − d̃‖₂ (eq. 14; module docstring)
    gamma: float = 0.01  # eq. 13 in metres: the paper's γ = 1 with displacements in cm (module docstring)
    gamma_aux: float = 1.0  # AUX's weight-decay prior γ_aux‖c_i‖² (m², like the MSE; :func:`aux_loss`)
    lambda_r: float = 1.0  # eq. 19
    lambda_c: float = 1.0  # eq. 19
    low_share: float = 0.2  # the last 20 % of the selected ...
    low_weight: float = 0.1  # ... get this weight
    coteach_forget: float = 0.2  # Co-teaching's ε
    coteach_tk: float = 0.1  # T_k as a share of the joint epochs
    # the models' loss on the displacements (wearnav.models.base.instance_velocity_loss): "mse" as the
    # paper, or "polar" (log length and direction apart: issue 34's fix, which a direction the input
    # leaves uncertain cannot shorten); CoAdapt ranks instances by it, CNAL and AUX keep their MSE
    loss: str = "mse"
    yaw_augment: bool = True  # turn each segment's input by a random yaw, its prediction back (not in the
    # paper; RoNIN trains so). Its effect on BaseModel-GT: `wearnav bench easytrack-base`, docs/results.md
    # easytrack-amended only (wearnav.train.coadapt): label-length strata of the selection; p_δ's outlier
    # bound median + delta_mad·MAD on relative errors ‖d̂ − d̃‖ / max(‖d̃‖, rel_floor m)
    strata: int = 8
    delta_mad: float = 3.0
    rel_floor: float = coadapt.REL_FLOOR_M

    def __post_init__(self):
        if self.method not in METHODS:
            raise ConfigError(f"unknown method {self.method!r} (expected one of {', '.join(METHODS)})")
        if self.loss not in VEL_LOSSES:
            raise ConfigError(f"unknown loss {self.loss!r} (expected one of {', '.join(VEL_LOSSES)})")
        if min(self.ae_epochs, self.pre_epochs, self.joint_epochs) < 0 or self.batch < 2:
            raise ConfigError("epochs must be ≥ 0 and batch ≥ 2")
        if self.strata < 1 or not self.delta_mad > 0 or not self.rel_floor > 0:
            raise ConfigError("strata must be ≥ 1, delta_mad and rel_floor > 0")

    def record(self) -> dict:
        """The config as a run folder's record: the amended method's fields only where it reads them,
        so the other methods' run folders keep the names (config hashes) they had before it."""
        d = dataclasses.asdict(self)
        return d if self.method == "easytrack-amended" else {k: v for k, v in d.items() if k not in AMENDED_FIELDS}


# ---- schedules and losses (each a pure function; tests use hand-made tensors) -------------------


def r_tau(T: int, T_max: int, tau: float = 0.8, eta: float = 1.0) -> float:
    """R_τ^T = 1 − τ·g(η, T), g = log(η(T−1)+1) / log(η·T_max + 1), T ∈ [1, T_max] (eq. 15)."""
    if T_max < 1:
        return 1.0
    T = min(max(T, 1), T_max)
    return 1.0 - tau * math.log(eta * (T - 1) + 1) / math.log(eta * T_max + 1)


def r_delta_update(r_prev: float, pred: Tensor, target: Tensor, delta: float, beta: float = 0.02) -> float:
    """R_δ^{T,B} = (1 − β) R_δ^{T,B−1} + β p_δ^{T,B} (eq. 14), p_δ the share of instances whose
    displacement error ‖pred − target‖₂ (m) is below δ (m; module docstring on units)."""
    err = instance_error(pred, target)
    p = float((err < delta).float().mean()) if err.numel() else 0.0
    return (1 - beta) * r_prev + beta * p


def r_select(r_t: float, r_d: float) -> float:
    """R_s = max(R_τ, R_δ) (eq. 16)."""
    return max(r_t, r_d)


def select_small_loss(
    losses: Tensor, ratio: float, low_share: float = 0.2, low_weight: float = 0.1
) -> tuple[Tensor, Tensor]:
    """Indices of the ⌈ratio·B⌉ smallest losses (ascending) and their weights: 1, except the last
    ``low_share`` of the selected (the largest losses among them), which get ``low_weight``
    (§IV-D2)."""
    B = losses.numel()
    k = min(B, max(1, int(math.ceil(ratio * B - 1e-9))))
    idx = torch.argsort(losses.detach())[:k]
    w = torch.ones(k, dtype=losses.dtype, device=losses.device)
    n_low = int(math.floor(low_share * k + 1e-9))
    if n_low:
        w[k - n_low :] = low_weight
    return idx, w


def instance_error(pred: Tensor, target: Tensor) -> Tensor:
    """Per-instance displacement error ‖pred − target‖₂ (B,), in metres: what δ is compared with."""
    return (pred - target).norm(dim=1)


def cnal_labels(label: Tensor, corr: Tensor, node0: Tensor, node1: Tensor) -> Tensor:
    """Corrected labels d̃ + (c_e − c_s) (eq. 12) for segments with node indices node0 → node1."""
    return label + corr[node1] - corr[node0]


def cnal_loss(label: Tensor, corr: Tensor, node0: Tensor, node1: Tensor, pred: Tensor, gamma: float = 0.01) -> Tensor:
    """L_cnal = MSE(d̃ + (c_e − c_s), d̂) + γ‖c_e − c_s‖₂ (eq. 13), means over the batch.

    Displacements in metres; the default γ = 0.01 (a length: MSE in m² against ‖Δc‖ in m) is the
    paper's γ = 1 with displacements in centimetres (module docstring). Per segment the L1 term
    pulls Δc back with a force of γ against the MSE's pull (the residual error in m), so residuals
    below ~γ are left uncorrected: 1 cm here, 1 m with γ = 1 in metres."""
    dc = corr[node1] - corr[node0]
    return F.mse_loss(label + dc, pred) + gamma * dc.norm(dim=1).mean()


def aux_loss(label: Tensor, corr: Tensor, pred: Tensor, gamma_aux: float = 1.0) -> Tensor:
    """AUX's loss: MSE(d̃_i + c_i, d̂) + γ_aux·mean_i ‖c_i‖², one free correction ``corr`` (B, 2)
    per segment of the batch.

    Both terms in m², so γ_aux has no unit (a weight-decay prior, no dead zone as an L1 norm would
    have). The MSE averages the two components, so its gradient on c_i is (d̃_i + c_i − d̂_i)/B and
    the prior's 2γ_aux·c_i/B: the optimum is c_i* = (d̂_i − d̃_i)/(1 + 2γ_aux), a third of the
    residual for γ_aux = 1."""
    return F.mse_loss(label + corr, pred) + gamma_aux * (corr**2).sum(dim=1).mean()


def coadapt_losses(
    l1: Tensor, l2: Tensor, ratio: float, low_share: float = 0.2, low_weight: float = 0.1
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """(L_pre1, L_pre2, D_s1, D_s2) of eq. 18: model 1 learns on its peer's selection D_s2 with its
    peer's weights and vice versa; sums divided by the batch size."""
    B = l1.numel()
    s1, w1 = select_small_loss(l1, ratio, low_share, low_weight)
    s2, w2 = select_small_loss(l2, ratio, low_share, low_weight)
    return (w2 * l1[s2]).sum() / B, (w1 * l2[s1]).sum() / B, s1, s2


def turn(v: Tensor, angle: Tensor) -> Tensor:
    """Segments (B, L, 6) (acc and gyro turned) or displacements (B, 2) turned about the vertical
    by ``angle`` (B,) rad, counter-clockwise seen from above."""
    if v.dim() == 2:
        return rotate_about_vertical(torch.cat([v, torch.zeros_like(v[:, :1])], 1), angle)[:, :2]
    return rotate_about_vertical(v.reshape(*v.shape[:-1], 2, 3), angle.view(-1, 1, 1)).reshape(v.shape)


# ---- models ---------------------------------------------------------------------------------------


class Resampled(nn.Module):
    """Run a registry model that needs longer windows (RoNIN ≥ 32 samples) on a segment
    linearly resampled to ``length`` samples."""

    def __init__(self, model: nn.Module, length: int):
        super().__init__()
        self.model, self.length = model, length

    def displacement(self, s: Tensor) -> Tensor:
        if s.shape[1] != self.length:
            s = F.interpolate(s.transpose(1, 2), size=self.length, mode="linear", align_corners=True).transpose(1, 2)
        return self.model(s[:, None], torch.ones(s.shape[0], 1, device=s.device))


class Registry(nn.Module):
    def __init__(self, model: nn.Module):
        super().__init__()
        self.model = model

    def displacement(self, s: Tensor) -> Tensor:
        return self.model(s[:, None], torch.ones(s.shape[0], 1, device=s.device))


def build_models(cfg: NoisyConfig, window: int) -> list[nn.Module]:

    torch.manual_seed(cfg.seed * 7919 + 11)
    if cfg.method == "ionet":
        return [Registry(build("ionet", n_devices=1, window=window))]
    if cfg.method == "ronin":
        return [Resampled(build("ronin", n_devices=1, window=max(window, MIN_WINDOW)), max(window, MIN_WINDOW))]
    n = 2 if cfg.method in DUAL else 1
    models: list[nn.Module] = []
    for k in range(n):
        torch.manual_seed(cfg.seed * 7919 + 101 * (k + 1))  # dual models: different seeds
        models.append(BaseModel(n_devices=1, window=window))
    return models


# ---- training -------------------------------------------------------------------------------------


def _adam(params, lr, cfg):
    return torch.optim.Adam(params, lr=lr, betas=tuple(cfg.betas))


def _batches(n: int, batch: int, gen: torch.Generator) -> list[Tensor]:
    perm = torch.randperm(n, generator=gen)
    return [perm[i : i + batch] for i in range(0, n, batch)]


def _epoch_gen(cfg: NoisyConfig, epoch: int) -> torch.Generator:
    torch.manual_seed(cfg.seed * 1_000_003 + epoch)
    return torch.Generator().manual_seed(cfg.seed * 1_000_003 + epoch + 7)


def _save(run: Path, state: dict) -> None:
    with atomic_path(run / STATE, durable=True) as tmp:  # the resume point: old or new, never torn
        torch.save(state, tmp)


def fit_noisy(
    cfg: NoisyConfig,
    train: Segments,
    run: str | Path,
    progress: bool = False,
    echo=None,
    stop_after: int | None = None,
    monitor=None,
    device: str | None = None,
) -> dict:
    """Train ``cfg.method`` on ``train`` (phone labels; ``basemodel-gt`` uses the truth) in run folder
    ``run``; resumes from ``state.pt``. ``stop_after``: return after that many epochs of this call (an
    interruption, for tests). ``monitor``: a function of the ensemble's displacement function
    (segments (N, L, 6) → (N, 2)) whose dict is added to each epoch's history (held-out ADE over the
    epochs, a diagnostic that never steers training). Returns the training record. Holds the run
    folder's lock while it runs (:func:`wearnav.runs.locked`): a second process is refused.
    ``device``: where to train (default: the GPU where there is one, else the CPU); the state file is
    the same either way, so a run may resume on the other."""
    dev = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
    with runs.locked(run):
        return _fit_noisy(cfg, train, Path(run), progress, echo, stop_after, monitor, dev)


def _fit_noisy(
    cfg: NoisyConfig,
    train: Segments,
    run: Path,
    progress: bool,
    echo,
    stop_after: int | None,
    monitor,
    dev: torch.device,
) -> dict:
    x = torch.as_tensor(train.x, dtype=torch.float32, device=dev)
    use_truth = cfg.method == "basemodel-gt"
    y_np = train.truth if use_truth else train.label
    if not np.isfinite(y_np).all():
        raise ConfigError(f"{cfg.method}: training labels have NaN (basemodel-gt needs dense truth)")
    y = torch.as_tensor(y_np, dtype=torch.float32, device=dev)
    truth = torch.as_tensor(train.truth, dtype=torch.float32, device=dev)  # bookkeeping only (Fig. 6), may be NaN
    node0 = torch.as_tensor(train.node0, dtype=torch.long, device=dev)
    node1 = torch.as_tensor(train.node1, dtype=torch.long, device=dev)
    n = len(train)
    # duck-typed: BaseModels (encode, reconstruction_loss, displacement(s, h)) where ``base``,
    # else wrappers with displacement(s) only; the loop branches on ``base``
    models: list[Any] = [m.to(dev) for m in build_models(cfg, train.x.shape[1])]
    for m in models:
        if isinstance(m, BaseModel):
            m.set_normalisation(x)
    base = all(isinstance(m, BaseModel) for m in models)
    dual = len(models) == 2
    cnal = cfg.method in CNAL
    aux = cfg.method == "aux"
    corr = nn.Parameter(torch.zeros(train.n_nodes if cnal else (n if aux else 0), 2, device=dev))
    zero = torch.zeros((), device=dev)
    truth_known = bool(np.isfinite(train.truth).all())  # selected-noise bookkeeping (Fig. 6) needs the truth
    opts = [_adam(m.parameters(), cfg.lr, cfg) for m in models]
    opt_c = _adam([corr], cfg.lr_cnal, cfg) if (cnal or aux) else None
    ae_epochs = cfg.ae_epochs if base else 0
    total = ae_epochs + cfg.pre_epochs + cfg.joint_epochs
    state: dict[str, Any] = {"epoch": 0, "r_delta": 0.0, "history": [], "wall_s": 0.0}
    if (run / STATE).is_file():
        st = torch.load(run / STATE, map_location="cpu", weights_only=False)
        for m, sd in zip(models, st["models"]):
            m.load_state_dict(sd)
        for o, sd in zip(opts, st["opts"]):
            o.load_state_dict(sd)
        if opt_c is not None:
            corr.data.copy_(st["corr"])
            opt_c.load_state_dict(st["opt_c"])
        state = {k: st[k] for k in ("epoch", "r_delta", "history", "wall_s")}
        log.info(f"{run.name}: resuming from {run / STATE} ({state['epoch']} epoch(s) done)")
    # disjoint halves for the dual models' AE pre-training (§IV-E), by trajectory
    half = torch.as_tensor(train.traj % 2 == 0)
    if half.all() or not half.any():
        half = torch.arange(n) % 2 == 0
    halves = [torch.nonzero(half).ravel(), torch.nonzero(~half).ravel()] if dual else [torch.arange(n)]
    halves = [h.to(dev) for h in halves]
    r_delta = state["r_delta"]

    bar = Progress(total=total, initial=state["epoch"], desc=cfg.method, unit="epoch", enabled=progress, leave=False)
    done_here = 0
    while state["epoch"] < total and (stop_after is None or done_here < stop_after):
        done_here += 1
        ep = state["epoch"]
        t0 = time.perf_counter()
        gen = _epoch_gen(cfg, ep)
        phase = "ae" if ep < ae_epochs else ("pre" if ep < ae_epochs + cfg.pre_epochs else "joint")
        T = ep - ae_epochs - cfg.pre_epochs + 1  # joint epoch, 1-based
        if phase == "joint":
            lr = cfg.lr_min + 0.5 * (cfg.lr - cfg.lr_min) * (1 + math.cos(math.pi * (T - 1) / max(cfg.joint_epochs, 1)))
        else:
            lr = cfg.lr
        for o in opts:
            for g in o.param_groups:
                g["lr"] = lr
        for m in models:
            m.train()
        # running sums stay on the device (no host sync per batch); read once at the epoch's end
        sums: dict[str, Any] = {
            "loss": zero.clone(),
            "rec": zero.clone(),
            "r_s": 0.0,
            "sel_noise_cm": zero.clone(),
            "sel_noise_corr_cm": zero.clone(),
            "all_noise_cm": zero.clone(),
            "sel_disp_cm": zero.clone(),
            "all_disp_cm": zero.clone(),
            "n_sel": 0,
            "n_b": 0,
        }
        sel_noise_last = []
        diag: dict[str, list[float]] = {k: [] for k in DIAGNOSTICS}
        if phase == "ae":
            for k, m in enumerate(models):
                for b in _batches(halves[k].numel(), cfg.batch, gen):
                    idx = halves[k][b.to(dev)]
                    loss = m.reconstruction_loss(x[idx])
                    opts[k].zero_grad()
                    loss.backward()
                    opts[k].step()
                    sums["rec"] += loss.detach()
                    sums["n_b"] += 1
        else:
            r_t = r_tau(T, cfg.joint_epochs, cfg.tau, cfg.eta) if phase == "joint" else 1.0
            for b in _batches(n, cfg.batch, gen):
                b = b.to(dev)
                xb, yb = x[b], y[b]
                angle = (torch.rand(xb.shape[0], generator=gen) * (2 * math.pi)).to(dev) if cfg.yaw_augment else None
                xin = xb if angle is None else turn(xb, angle)
                hs = [m.encode(xin) for m in models] if base else [None] * len(models)
                preds = [m.displacement(xin, h) if base else m.displacement(xin) for m, h in zip(models, hs)]
                if angle is not None:  # back to the labels' frame, so every loss below is unchanged
                    preds = [turn(p, -angle) for p in preds]
                if cnal:
                    target = cnal_labels(yb, corr, node0[b], node1[b])
                elif aux:
                    target = yb + corr[b]
                else:
                    target = yb
                tgt_models = target if phase == "joint" else yb
                losses = [instance_velocity_loss(p, tgt_models, cfg.loss) for p in preds]
                total_loss = torch.zeros((), device=dev)
                if dual and phase == "joint":
                    diag["ensemble_shrinkage"].append(coadapt.ensemble_shrinkage(preds[0].detach(), preds[1].detach()))
                if dual and phase == "joint" and cfg.method in (*COADAPT, "coteaching"):
                    pooled = torch.cat([preds[0].detach(), preds[1].detach()])
                    tgt2 = tgt_models.detach().repeat(2, 1)
                    length = tgt_models.detach().norm(dim=1)  # the label's length, what the rule may see
                    if cfg.method == "coteaching":
                        ratio = 1.0 - cfg.coteach_forget * min(T / max(1.0, cfg.coteach_tk * cfg.joint_epochs), 1.0)
                        lp1, lp2, s1, s2 = coadapt_losses(losses[0], losses[1], ratio, 0.0, 1.0)
                        w1, w2 = torch.ones_like(s1, dtype=yb.dtype), torch.ones_like(s2, dtype=yb.dtype)
                    elif cfg.method == "easytrack-amended":
                        r_delta = coadapt.r_delta_amended(r_delta, pooled, tgt2, cfg.delta_mad, cfg.rel_floor, cfg.beta)
                        ratio = r_select(r_t, r_delta)
                        lp1, lp2, s1, s2, w1, w2 = coadapt.coadapt_losses_stratified(
                            losses[0], losses[1], length, ratio, cfg.strata, cfg.low_share, cfg.low_weight
                        )
                    else:
                        r_delta = r_delta_update(r_delta, pooled, tgt2, cfg.delta, cfg.beta)
                        ratio = r_select(r_t, r_delta)
                        lp1, lp2, s1, s2 = coadapt_losses(losses[0], losses[1], ratio, cfg.low_share, cfg.low_weight)
                        w1 = select_small_loss(losses[0], ratio, cfg.low_share, cfg.low_weight)[1]
                        w2 = select_small_loss(losses[1], ratio, cfg.low_share, cfg.low_weight)[1]
                    total_loss = total_loss + lp1 + lp2
                    sums["r_s"] += ratio
                    # issue 59's diagnostics (wearnav.train.coadapt), from what the rule sees (no truth)
                    diag["length_bias"].append(coadapt.length_bias(torch.cat([s1, s2]), length))
                    diag["weighting_length_bias"].append(
                        0.5
                        * (
                            coadapt.weighting_length_bias(s1, w1, length)
                            + coadapt.weighting_length_bias(s2, w2, length)
                        )
                    )
                    diag["delta_scale"].append(coadapt.delta_scale(instance_error(pooled, tgt2), cfg.delta))
                    sel = torch.cat([s1, s2])
                    tb = truth[b]
                    e_raw = (tb[sel] - yb[sel]).norm(dim=1)
                    e_cor = (tb[sel] - target[sel].detach()).norm(dim=1)
                    if truth_known:
                        sums["sel_noise_cm"] += 100 * e_raw.sum()
                        sums["sel_noise_corr_cm"] += 100 * e_cor.sum()
                        sums["n_sel"] += int(sel.numel())
                        if ep == total - 1:
                            sel_noise_last.append(e_cor.cpu().numpy())
                        sums["all_noise_cm"] += 100 * (tb - yb).norm(dim=1).mean()
                        # are the small-loss instances the clean ones, or the easy (short) ones?
                        sums["sel_disp_cm"] += 100 * tb[sel].norm(dim=1).sum()
                        sums["all_disp_cm"] += 100 * tb.norm(dim=1).mean()
                else:
                    for l in losses:
                        total_loss = total_loss + l.mean()
                    sums["r_s"] += 1.0
                if base:
                    rec_loss = sum(m.reconstruction_loss(xin, h) for m, h in zip(models, hs))
                    total_loss = total_loss + cfg.lambda_r * rec_loss
                    sums["rec"] += rec_loss.detach()
                if (cnal or aux) and phase == "joint":
                    ens = torch.stack(preds).mean(0).detach()
                    if cnal:
                        lc = cnal_loss(yb, corr, node0[b], node1[b], ens, cfg.gamma)
                    else:
                        lc = aux_loss(yb, corr[b], ens, cfg.gamma_aux)
                    total_loss = total_loss + cfg.lambda_c * lc
                for o in opts:
                    o.zero_grad()
                if opt_c is not None:
                    opt_c.zero_grad()
                total_loss.backward()
                for o in opts:
                    o.step()
                if opt_c is not None and phase == "joint":
                    opt_c.step()
                sums["loss"] += total_loss.detach()
                sums["n_b"] += 1
        sums = {k: float(v) if isinstance(v, Tensor) else v for k, v in sums.items()}
        nb = max(sums["n_b"], 1)
        rec = {
            "epoch": ep + 1,
            "phase": phase,
            "lr": lr,
            "loss": sums["loss"] / nb,
            "rec": sums["rec"] / nb,
            "r_tau": r_tau(T, cfg.joint_epochs, cfg.tau, cfg.eta) if phase == "joint" else None,
            "r_delta": r_delta if phase == "joint" else None,
            "r_s": sums["r_s"] / nb if phase != "ae" else None,
            "selected_noise_cm": sums["sel_noise_cm"] / sums["n_sel"] if sums["n_sel"] else None,
            "selected_noise_corrected_cm": sums["sel_noise_corr_cm"] / sums["n_sel"] if sums["n_sel"] else None,
            "batch_noise_cm": sums["all_noise_cm"] / nb if sums["n_sel"] else None,
            "selected_displacement_cm": sums["sel_disp_cm"] / sums["n_sel"] if sums["n_sel"] else None,
            "batch_displacement_cm": sums["all_disp_cm"] / nb if sums["n_sel"] else None,
            "s": time.perf_counter() - t0,
            **{k: float(np.nanmean(v)) if v else None for k, v in diag.items()},
        }
        if opt_c is not None and cnal and np.isfinite(train.truth).all():
            rec["corrected_label_noise_median_cm"] = 100 * float(
                np.median(
                    np.linalg.norm(train.truth - cnal_labels(y, corr.detach(), node0, node1).cpu().numpy(), axis=1)
                )
            )
        if monitor is not None:
            for m in models:
                m.eval()
            with torch.no_grad():
                rec.update(
                    monitor(
                        lambda xs: (
                            torch.stack(
                                [m.displacement(torch.as_tensor(xs, dtype=torch.float32, device=dev)) for m in models]
                            )
                            .mean(0)
                            .cpu()
                            .numpy()
                        )
                    )
                )
        state["history"].append(rec)
        state["epoch"] = ep + 1
        state["r_delta"] = r_delta
        state["wall_s"] += rec["s"]
        if sel_noise_last:
            save_npy_atomic(run / "selected_noise_last_epoch.npy", np.concatenate(sel_noise_last))
        _save(
            run,
            {
                **state,
                "models": [m.state_dict() for m in models],
                "opts": [o.state_dict() for o in opts],
                "corr": corr.detach().clone(),
                "opt_c": opt_c.state_dict() if opt_c is not None else None,
                "config": dataclasses.asdict(cfg),
            },
        )
        bar.update(1)
        if echo:
            echo(f"{cfg.method} epoch {ep + 1}/{total} {phase} loss {rec['loss']:.4f} ({rec['s']:.1f} s)")
    bar.close()
    hist = state["history"]
    timed = [h["s"] for h in hist if h["phase"] != "ae"] or [h["s"] for h in hist]
    return {
        "epochs": total,
        "ae_epochs": ae_epochs,
        "pre_epochs": cfg.pre_epochs,
        "joint_epochs": cfg.joint_epochs,
        "wall_s": state["wall_s"],
        "s_per_epoch": float(np.mean(timed)) if timed else None,
        "device": str(dev) + (f" ({torch.cuda.get_device_name(dev)})" if dev.type == "cuda" else ""),
        "history": hist,
    }


def load_predictor(cfg: NoisyConfig, run: str | Path, window: int):
    """The trained model(s) of a run: a function segments (N, L, 6) → displacements (N, 2) (the
    dual methods average their two models, eq. 11)."""
    models: list[Any] = build_models(cfg, window)  # each has displacement(s) (build_models)
    st = torch.load(Path(run) / STATE, map_location="cpu", weights_only=False)
    for m, sd in zip(models, st["models"]):
        m.load_state_dict(sd)
        m.eval()

    @torch.no_grad()
    def predict(x: np.ndarray, batch: int = 1024) -> np.ndarray:
        out = []
        for i in range(0, len(x), batch):
            xb = torch.as_tensor(x[i : i + batch], dtype=torch.float32)
            out.append(torch.stack([m.displacement(xb) for m in models]).mean(0).numpy())
        return np.concatenate(out) if out else np.empty((0, 2))

    return predict


def corrections(run: str | Path) -> np.ndarray:
    """The learned CNAL / AUX correction vectors of a run."""
    return torch.load(Path(run) / STATE, map_location="cpu", weights_only=False)["corr"].numpy()


def write_history(run: str | Path, record: dict) -> None:
    write_text_atomic(json.dumps(record["history"], indent=1, default=float), Path(run) / "history.json", durable=True)
