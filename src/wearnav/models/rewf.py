"""ReWF (ReWF1, Suite-IN++'s multi-node baseline [36], paper 000 Sec. V-B): a ResNet inertial
encoder per node and an LSTM sensor-weight extractor whose Gumbel-softmax weights fuse the nodes.
Its code is not public (Suite-IN++ re-implemented it too); this is our reading:

- encoder, per device (own weights): RoNIN's ResNet-18-1D backbone (input block, groups of two
  BasicBlocks 64-128-256-512, 1×1 transition to 128) with the input block's stride and max-pool
  off (``input_stride`` 1), so the 100-sample window keeps 13 steps after the three stride-2
  groups → features F_j (128, 13);
- weight extractor, shared: an LSTM (``lstm_hidden`` 256) over each device's feature sequence, its
  last hidden state → linear → one logit per device; weights = Gumbel-softmax (temperature
  ``tau``) over the PRESENT devices while training, its noise-free softmax at inference; an
  absent device gets weight 0 and its encoder reads zeros, so its input changes nothing;
- Σ_j w_j F_j flattened → RoNIN's FC head, ``fc_dim`` 768 wide (768 → 768 → 2, dropout 0.5).

Table VI lists 14,049.1 K parameters and 0.223 G multiply-accumulates; this reading gives
14,002 K and 0.229 G. The three ResNet encoders at full temporal resolution are the compute
(and 11.6 M of the parameters); the LSTM width 256 and head width 768 are our fit to the rest.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel
from wearnav.models.deepit import masked_softmax
from wearnav.models.registry import register
from wearnav.models.ronin import resnet_layers


class ResNetEncoder(nn.Module):
    """RoNIN's ResNet-18-1D without its FC head: (B, 6, L) → (B, trans_planes, L')."""

    def __init__(
        self, in_channels: int = 6, blocks=(2, 2, 2, 2), base: int = 64, trans_planes: int = 128, input_stride: int = 1
    ):
        super().__init__()
        self.input_block, self.groups, self.transition, self.halvings = resnet_layers(
            in_channels, blocks, base, trans_planes, input_stride
        )

    def length(self, window: int) -> int:
        return -(-window // 2**self.halvings)

    def forward(self, x: Tensor) -> Tensor:
        return self.transition(self.groups(self.input_block(x)))


class ReWF(OdometryModel):
    def __init__(
        self,
        n_devices: int = 3,
        window: int = 100,
        lstm_hidden: int = 256,
        tau: float = 1.0,
        fc_dim: int = 768,
        dropout: float = 0.5,
        input_stride: int = 1,
        trans_planes: int = 128,
    ):
        super().__init__()
        self.n_devices, self.tau = n_devices, tau
        encoders = [ResNetEncoder(trans_planes=trans_planes, input_stride=input_stride) for _ in range(n_devices)]
        self.encoders = nn.ModuleList(encoders)
        length = encoders[0].length(window)
        if length < 1 or window < 8:
            raise ConfigError(f"rewf: window {window} is too short")
        self.weight_lstm = nn.LSTM(trans_planes, lstm_hidden, batch_first=True)
        self.weight_out = nn.Linear(lstm_hidden, 1)
        self.fc = nn.Sequential(
            nn.Linear(trans_planes * length, fc_dim),
            nn.ReLU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, fc_dim),
            nn.ReLU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, 2),
        )

    def weights(self, x: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        """Per-device features (B, D, C, L') and fusion weights (B, D), 0 where absent."""
        if x.shape[1] != self.n_devices:
            raise ConfigError(f"rewf: model built for {self.n_devices} devices, got {x.shape[1]}")
        # An absent device's encoder sees zeros, so in training its data cannot reach the batch
        # statistics (its weight below is 0 in any case).
        x = x * (mask > 0).to(x.dtype)[:, :, None, None]
        feats = torch.stack([enc(x[:, j].transpose(1, 2)) for j, enc in enumerate(self.encoders)], 1)
        B, D, C, L = feats.shape
        h, _ = self.weight_lstm(feats.reshape(B * D, C, L).transpose(1, 2))
        logits = self.weight_out(h[:, -1]).view(B, D)
        if self.training:  # Gumbel-softmax: logits + Gumbel noise, softened by tau
            u = torch.rand_like(logits).clamp(1e-10, 1.0 - 1e-7)
            logits = logits - torch.log(-torch.log(u))
        return feats, masked_softmax(logits / self.tau, mask)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        feats, w = self.weights(x, mask)
        return self.fc(torch.einsum("bdcl,bd->bcl", feats, w).flatten(1))


@register(
    "rewf",
    task="odometry",
    layout="multi",
    description="ReWF: ResNet encoder per device, LSTM sensor weights (Gumbel-softmax) fusing the present devices",
)
def rewf(n_devices: int = 3, window: int = 100, **kw) -> ReWF:
    return ReWF(n_devices, window, **kw)
