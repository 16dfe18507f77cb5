"""DeepIT* (Suite-IN++'s multi-node baseline [37], paper 000 Sec. V-B): deep inertial tracking
that fuses devices with an LSTM per device and a reliability ("primal") weighting, extended from
phone + earphone to every device of the layout, regressing the window's mean horizontal velocity
instead of distance and heading (as Suite-IN++ adapts it).

Per device j (own weights): the standardised IMU window (gravity off z, acc / 2 m/s²) through a
one-layer LSTM (``hidden``), its hidden states averaged over ``pooled`` equal time segments and
flattened, then ReLU(FC) → an embedding z_j (``embed``). A shared reliability network (FC 32 →
ReLU → FC 1) scores each embedding; the weights are a softmax over the PRESENT devices (an
absent device gets weight 0 and its input changes nothing); Σ_j w_j z_j → FC 64 → ReLU → FC 2.

Sizes are our fit to Table VI (317.3 K parameters, 0.005 G multiply-accumulates), whose paper
does not give them: the recurrent part is what costs compute (about 16 K MACs per step and
device at hidden 60), the per-device FC is what holds the parameters.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel
from wearnav.models.registry import register
from wearnav.recording import STANDARD_GRAVITY


def masked_softmax(logits: Tensor, mask: Tensor) -> Tensor:
    """Softmax over dim 1 of (B, D) logits among entries with mask > 0; absent entries are exactly
    0, and a row without any present entry is all 0."""
    present = mask > 0
    w = torch.softmax(logits.masked_fill(~present, torch.finfo(logits.dtype).min), dim=1)
    return w * present.to(w.dtype)


class DeepIT(OdometryModel):
    shift: Tensor  # buffers (register_buffer), typed
    scale: Tensor

    def __init__(
        self,
        n_devices: int = 3,
        window: int = 100,
        hidden: int = 60,
        pooled: int = 10,
        embed: int = 140,
        score_hidden: int = 32,
        head_hidden: int = 64,
    ):
        super().__init__()
        if window < pooled:
            raise ConfigError(f"deepit: window {window} is shorter than its {pooled} pooled segments")
        self.n_devices, self.pooled = n_devices, pooled
        self.lstms = nn.ModuleList(nn.LSTM(6, hidden, batch_first=True) for _ in range(n_devices))
        self.embeds = nn.ModuleList(nn.Linear(pooled * hidden, embed) for _ in range(n_devices))
        self.score = nn.Sequential(nn.Linear(embed, score_hidden), nn.ReLU(), nn.Linear(score_hidden, 1))
        self.head = nn.Sequential(nn.Linear(embed, head_hidden), nn.ReLU(), nn.Linear(head_hidden, 2))
        self.register_buffer("shift", torch.tensor([0.0, 0.0, STANDARD_GRAVITY, 0.0, 0.0, 0.0]))
        self.register_buffer("scale", torch.tensor([2.0, 2.0, 2.0, 1.0, 1.0, 1.0]))

    def weights(self, x: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        """Embeddings z (B, D, embed) and fusion weights w (B, D) (0 for absent devices)."""
        if x.shape[1] != self.n_devices:
            raise ConfigError(f"deepit: model built for {self.n_devices} devices, got {x.shape[1]}")
        s = (x - self.shift) / self.scale
        per_device = []
        for j, (lstm, fc) in enumerate(zip(self.lstms, self.embeds)):
            h, _ = lstm(s[:, j])  # (B, L, hidden)
            h = F.adaptive_avg_pool1d(h.transpose(1, 2), self.pooled)  # (B, hidden, pooled)
            per_device.append(F.relu(fc(h.flatten(1))))
        z = torch.stack(per_device, 1)
        return z, masked_softmax(self.score(z).squeeze(-1), mask)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        z, w = self.weights(x, mask)
        return self.head(torch.einsum("bde,bd->be", z, w))


@register(
    "deepit*",
    task="odometry",
    layout="multi",
    description="DeepIT*: an LSTM per device, reliability-weighted fusion of the present devices",
)
def deepit_star(n_devices: int = 3, window: int = 100, **kw) -> DeepIT:
    return DeepIT(n_devices, window, **kw)
