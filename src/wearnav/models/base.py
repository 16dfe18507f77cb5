"""The model contract (DESIGN.md, "Training and evaluation core").

An odometry model maps world-frame IMU windows of a fixed device layout to a mean horizontal
velocity; every auxiliary loss lives in the model's own :meth:`OdometryModel.loss`, so one
LightningModule trains every odometry model.

Decisions: docs/decisions/0025-velocity-losses-polar.md, docs/decisions/0031-pdr-pointing-and-hybrids.md,
docs/decisions/0040-snapped-pointing.md.
"""

from __future__ import annotations

import math
from typing import cast

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from wearnav.errors import ConfigError

# The velocity losses a model may train with (:func:`velocity_loss`; TrainConfig.vel_loss).
VEL_LOSSES = ("mse", "polar")
# The polar loss's floor under a speed before its log (m/s): a window standing still (0 m/s) and
# one creeping at a few cm/s count alike, and the log stays finite. 0.1 m/s is a tenth of a
# walker's speed (IPIN's walkers 0.92 m/s, ILC2's 1.12: issue 34).
LOG_SPEED_FLOOR_M_S = 0.1
_TINY = 1e-9


def instance_velocity_loss(pred: Tensor, target: Tensor, kind: str = "mse") -> Tensor:
    """Each instance's part of :func:`velocity_loss` (B,): its mean over the batch is that loss.

    ``"mse"``: the squared error averaged over the two components. ``"polar"``: the log-speed error
    plus ``|v|·(1 − cos∠(v̂, v)) / mean(|v|)`` (the batch's mean true speed as the denominator, so
    the mean is the speed-weighted direction term). Methods that rank instances by their loss
    (EasyTrack's small-loss selection, :mod:`wearnav.train.noisy`) take this."""
    if kind == "mse":
        return ((pred - target) ** 2).mean(dim=-1)
    if kind != "polar":
        raise ConfigError(f"unknown velocity loss {kind!r}; one of {', '.join(VEL_LOSSES)}")
    speed_hat = torch.sqrt((pred**2).sum(-1) + _TINY)  # (B,) m/s, finite gradient at 0
    speed = target.norm(dim=-1)
    log_err = torch.log(speed_hat + LOG_SPEED_FLOOR_M_S) - torch.log(speed + LOG_SPEED_FLOOR_M_S)
    cos = (pred * target).sum(-1) / (speed_hat * speed + _TINY)
    return log_err.abs() + speed * (1 - cos) / (speed.mean() + _TINY)


def velocity_loss(pred: Tensor, target: Tensor, kind: str = "mse") -> Tensor:
    """The loss between predicted and true window velocities, (B, 2) m/s each.

    ``"mse"``: the mean squared error of the vector (Suite-IN++ eqs. 7, 22, 23). Its minimiser is
    the conditional mean of the velocity, which is *shorter* than any of the velocities averaged
    wherever the input leaves their direction uncertain: a walker at 1.2 m/s whose heading is
    known only to ±60° is predicted at 0.99 m/s (``tests/test_velocity_loss.py``).

    ``"polar"``: speed and direction apart, so uncertainty in one cannot shorten the other:
    ``|log(|v̂| + f) − log(|v| + f)|`` (L1 on log speed, f = :data:`LOG_SPEED_FLOOR_M_S`: a
    median in ratio, which no direction uncertainty moves) plus ``Σ|v|·(1 − cos∠(v̂, v)) / Σ|v|``
    (the direction error weighted by the true speed, so a window standing still has none). Both
    terms are dimensionless; their gradients are radial and tangential to v̂ respectively.
    Per instance: :func:`instance_velocity_loss`.
    """
    if kind == "mse":
        return F.mse_loss(pred, target)
    return instance_velocity_loss(pred, target, kind).mean()


class OdometryModel(nn.Module):
    """Base class. ``forward(x, mask)``: x (B, D, L, 6) world-frame acc+gyro, mask (B, D) with 1.0
    where a device is present → velocity (B, 2) m/s. Models that are not learned (PDR) set
    ``learned = False`` and may have no parameters."""

    learned: bool = True
    # Weight (0–1) on the model's auxiliary losses (Suite-IN++'s contrastive and orthogonality
    # terms), set per step by the trainer's recipe (wearnav.train.common.Schedule.aux): the "fast"
    # recipe ramps them in while the velocity is learned first.
    aux_scale: float = 1.0
    # The loss on its velocity outputs (:func:`velocity_loss`), set by the trainer from
    # TrainConfig.vel_loss; inference does not depend on it.
    vel_loss: str = "mse"

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def loss(self, batch: dict[str, Tensor]) -> tuple[Tensor, dict[str, Tensor]]:
        """Total loss and its named parts. Default: :func:`velocity_loss` of the mean window velocity."""
        vel = self(batch["x"], batch["mask"])
        loss = velocity_loss(vel, batch["vel"], self.vel_loss)
        return loss, {"vel": loss}

    @torch.no_grad()
    def predict(self, x: Tensor, mask: Tensor) -> Tensor:
        """Velocity (B, 2) for inference; the same as ``forward`` unless a model says otherwise."""
        return self(x, mask)

    def for_export(self) -> nn.Module:
        """The module that :mod:`wearnav.export` traces into TorchScript or ONNX: the same
        arithmetic as ``forward`` in eval mode, without CPU-only fused kernels or Python control
        flow that depends on the batch size. Default: the model itself."""
        return self.eval()


def first_present(x: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
    """The single-device models' input: for each sample, the first device of the layout with
    mask > 0 (the phone where present, else the next present device in layout order).

    Returns its data (B, L, 6), zeros for a sample with no device present, and its index (B,)."""
    present = mask > 0
    idx = present.to(torch.int8).argmax(dim=1)  # argmax returns the first maximal index
    sel = x[torch.arange(x.shape[0], device=x.device), idx]
    return sel * present.any(dim=1).to(x.dtype)[:, None, None], idx


def concat_devices(x: Tensor, mask: Tensor) -> Tensor:
    """The starred baselines' input: the devices' channels side by side in layout order, zeros
    where a device is absent. x (B, D, L, 6), mask (B, D) → (B, D·6, L), channel d·6 + k = axis k
    of device d."""
    B, D, L, C = x.shape
    x = x * (mask > 0).to(x.dtype)[:, :, None, None]
    return x.permute(0, 1, 3, 2).reshape(B, D * C, L)


class ScaledVelocity(OdometryModel):
    """``inner``'s velocity times one factor: a user's speed calibration from their own location
    fixes (:mod:`wearnav.adapt`), applied wherever the run's model is loaded
    (:func:`wearnav.train.odometry.load_model` reads it from the run's ``adaptation.json``).
    Heading is untouched: models are yaw-equivariant, so only their speed scale can be calibrated."""

    scale: Tensor  # buffers (register_buffer), typed

    def __init__(self, inner: nn.Module, scale: float):
        super().__init__()
        self.inner = inner
        self.learned = bool(getattr(inner, "learned", True))
        self.register_buffer("scale", torch.tensor(float(scale)))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self.inner(x, mask) * self.scale

    @torch.no_grad()
    def predict(self, x: Tensor, mask: Tensor) -> Tensor:
        return cast(OdometryModel, self.inner).predict(x, mask) * self.scale  # the wrapped model is one


class AlongPointing(OdometryModel):
    """``inner``'s speed along where the phone points (issue 34 §2, "Hybrids"): for a model whose
    windows are in the device's heading frame (:attr:`wearnav.preprocess.PreprocessConfig.heading_frame`),
    whose +x is the horizontal direction of the phone's y − z axis, the velocity (|v̂|, 0) there.
    The learned model keeps the distance walked, the phone supplies the direction: on the held-out
    ILC2 and IPIN walks the heading-frame Suite-IN++'s direction was no closer to the truth than the
    phone's pointing (10.7–21.0° against 9.1° median in ILC2, 9.1–9.9° against 9.9° in IPIN)."""

    def __init__(self, inner: nn.Module):
        super().__init__()
        self.inner = inner
        self.learned = bool(getattr(inner, "learned", True))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        speed = self.inner(x, mask).norm(dim=1)
        return torch.stack([speed, torch.zeros_like(speed)], dim=1)

    @torch.no_grad()
    def predict(self, x: Tensor, mask: Tensor) -> Tensor:
        speed = cast(OdometryModel, self.inner).predict(x, mask).norm(dim=1)
        return torch.stack([speed, torch.zeros_like(speed)], dim=1)


# Within this angle (degrees) of where the phone points, SnapToPointing takes the pointing.
SNAP_DEG = 30.0


class SnapToPointing(OdometryModel):
    """``inner``'s velocity turned onto where the phone points wherever it is within ``snap_deg`` of it
    (issue 34 §2, "Hybrids"), else as it is; for a model whose windows are in the device's heading
    frame (+x: the horizontal direction of the phone's y − z axis, as :class:`AlongPointing`). A phone
    held ahead points the way of walking, which the phone measures better than the model reads it from
    the gait (its direction erred 10.7–21.0° against the pointing's 9.1° median in ILC2); a phone in a
    pocket or bag points elsewhere, where the model's own direction stays. The model decides which,
    window by window, so no placement is assumed. Turning within ``snap_deg`` errs by at most that
    angle where the phone's pointing is off the walk by less; on the simulator's pocket and bag walks
    it cost nothing (docs/decisions/0040-snapped-pointing.md)."""

    def __init__(self, inner: nn.Module, snap_deg: float = SNAP_DEG):
        super().__init__()
        self.inner = inner
        self.learned = bool(getattr(inner, "learned", True))
        self.cos_snap = math.cos(math.radians(snap_deg))

    def _snap(self, v: Tensor) -> Tensor:
        speed = v.norm(dim=1)
        near = v[:, 0] > self.cos_snap * speed  # within snap_deg of +x (and not standing still)
        along = torch.stack([speed, torch.zeros_like(speed)], dim=1)
        return torch.where(near[:, None], along, v)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self._snap(self.inner(x, mask))

    @torch.no_grad()
    def predict(self, x: Tensor, mask: Tensor) -> Tensor:
        return self._snap(cast(OdometryModel, self.inner).predict(x, mask))
