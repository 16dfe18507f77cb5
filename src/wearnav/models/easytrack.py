"""EasyTrack's BaseModel (paper 004, §IV-B, eqs. 8–11; sizes from §V-A).

One BaseModel = encoder E (LSTM, 64), decoder D (LSTM 64 + FC 6) and predictor P (LSTM 64 +
FC 10 + FC 2):

* reconstruction ŝ = D(E(s)) (eq. 8), loss L_rec = MSE(s, ŝ) (eq. 9). E(s) is the encoder's last
  hidden state (the latent vector); the decoder LSTM reads it repeated once per time step and its
  FC layer maps each step back to the 6 IMU channels.
* prediction d̂ = P(E(s)) (eq. 10): the predictor LSTM reads the encoder's hidden sequence and its
  last state goes through FC(10) → ReLU → FC(2), the segment's horizontal displacement.
* the dual model's output is the mean of two BaseModels' predictions (eq. 11,
  :class:`DualBaseModel`).

Input: a segment of world-frame acc (with gravity) + gyro (B, L, 6), standardised per channel by
buffers ``mean``/``std`` (set from training data with :meth:`BaseModel.set_normalisation`;
defaults take gravity off z and scale acc by 2 m/s²). Reconstruction is scored in standardised
units so acc and gyro weigh alike.

Registered as ``easytrack-base`` (odometry contract: (B, D, L, 6) + mask → (B, 2), the phone or
first present device), so ``wearnav train --model easytrack-base`` trains it on dense truth too;
the EasyTrack benchmark reads its output as the displacement of a segment.
"""

from __future__ import annotations

from typing import cast

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from wearnav.models.base import OdometryModel, first_present
from wearnav.models.registry import register
from wearnav.recording import STANDARD_GRAVITY


class BaseModel(OdometryModel):
    mean: Tensor  # buffers (register_buffer), typed
    std: Tensor

    default_lr, default_batch = 8e-4, 64  # §V-A (`wearnav train` picks these up)

    def __init__(self, n_devices: int = 1, window: int = 25, hidden: int = 64, channels: int = 6):
        super().__init__()
        self.n_devices, self.window, self.hidden, self.channels = n_devices, window, hidden, channels
        self.encoder = nn.LSTM(channels, hidden, batch_first=True)
        self.decoder = nn.LSTM(hidden, hidden, batch_first=True)
        self.decoder_fc = nn.Linear(hidden, channels)
        self.predictor = nn.LSTM(hidden, hidden, batch_first=True)
        self.fc1 = nn.Linear(hidden, 10)
        self.fc2 = nn.Linear(10, 2)
        mean = torch.zeros(channels)
        mean[2] = STANDARD_GRAVITY
        std = torch.ones(channels)
        std[:3] = 2.0
        self.register_buffer("mean", mean)
        self.register_buffer("std", std)

    def set_normalisation(self, x: Tensor) -> None:
        """Per-channel mean/std from training segments x (N, L, 6)."""
        flat = x.reshape(-1, x.shape[-1]).to(self.mean.dtype)
        self.mean.copy_(flat.mean(0))
        self.std.copy_(flat.std(0).clamp_min(1e-3))

    def normalise(self, s: Tensor) -> Tensor:
        return (s - self.mean) / self.std

    def encode(self, s: Tensor) -> Tensor:
        """Encoder hidden sequence (B, L, H) of a raw segment s (B, L, 6)."""
        h, _ = self.encoder(self.normalise(s))
        return h

    def reconstruction_loss(self, s: Tensor, h: Tensor | None = None) -> Tensor:
        """L_rec = MSE(s, D(E(s))) (eqs. 8–9), in standardised units, mean over the batch."""
        h = self.encode(s) if h is None else h
        z = h[:, -1:].expand(-1, s.shape[1], -1)
        out, _ = self.decoder(z)
        return F.mse_loss(self.decoder_fc(out), self.normalise(s))

    def displacement(self, s: Tensor, h: Tensor | None = None) -> Tensor:
        """d̂ = P(E(s)) (eq. 10), (B, 2)."""
        h = self.encode(s) if h is None else h
        p, _ = self.predictor(h)
        return self.fc2(torch.relu(self.fc1(p[:, -1])))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self.displacement(first_present(x, mask)[0])

    def loss(self, batch: dict[str, Tensor]) -> tuple[Tensor, dict[str, Tensor]]:
        s = first_present(batch["x"], batch["mask"])[0]
        h = self.encode(s)
        mse = F.mse_loss(self.displacement(s, h), batch["vel"])
        rec = self.reconstruction_loss(s, h)
        return mse + rec, {"vel": mse, "rec": rec}


class DualBaseModel(nn.Module):
    """Two BaseModels; inference is the mean of their predictions (eq. 11)."""

    def __init__(self, a: BaseModel, b: BaseModel):
        super().__init__()
        self.models = nn.ModuleList([a, b])

    def displacement(self, s: Tensor) -> Tensor:
        a, b = (cast(BaseModel, m) for m in self.models)  # an nn.ModuleList's items are typed nn.Module
        return 0.5 * (a.displacement(s) + b.displacement(s))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self.displacement(first_present(x, mask)[0])


@register(
    "easytrack-base",
    task="odometry",
    layout="single",
    description="EasyTrack BaseModel: LSTM(64) encoder, LSTM decoder (AE loss), LSTM+FC(10)+FC(2) predictor",
)
def easytrack_base(n_devices: int = 3, window: int = 25, **kw) -> BaseModel:
    return BaseModel(n_devices=n_devices, window=window, **kw)
