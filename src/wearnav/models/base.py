"""The model contract (DESIGN.md, "Training and evaluation core").

An odometry model maps world-frame IMU windows of a fixed device layout to a mean horizontal
velocity; every auxiliary loss lives in the model's own :meth:`OdometryModel.loss`, so one
LightningModule trains every odometry model.
"""

from __future__ import annotations

from typing import cast

import torch
from torch import Tensor, nn
from torch.nn import functional as F


class OdometryModel(nn.Module):
    """Base class. ``forward(x, mask)``: x (B, D, L, 6) world-frame acc+gyro, mask (B, D) with 1.0
    where a device is present → velocity (B, 2) m/s. Models that are not learned (PDR) set
    ``learned = False`` and may have no parameters."""

    learned: bool = True
    # Weight (0–1) on the model's auxiliary losses (Suite-IN++'s contrastive and orthogonality
    # terms), set per step by the trainer's recipe (wearnav.train.common.Schedule.aux): the "fast"
    # recipe ramps them in while the velocity is learned first.
    aux_scale: float = 1.0

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:  # pragma: no cover - abstract
        raise NotImplementedError

    def loss(self, batch: dict[str, Tensor]) -> tuple[Tensor, dict[str, Tensor]]:
        """Total loss and its named parts. Default: MSE of the mean window velocity."""
        vel = self(batch["x"], batch["mask"])
        mse = F.mse_loss(vel, batch["vel"])
        return mse, {"vel": mse}

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
