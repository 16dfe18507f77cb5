"""The HAR benchmark's classifier (paper 002, Sec. II-A, Fig. 1) and its multi-head variants
(Sec. II-B-1, Figs. 2–3).

Baseline, per the paper: the inertial window (eq. 1: f_x, f_y, f_z, ω_x, ω_y, ω_z) → one 1-D
convolution with F = 64 filters, kernel 5, stride 1, ReLU (eqs. 2–3) → max pooling of depth 3
(eq. 4) → a Bi-LSTM (eq. 5) → dropout p = 0.25 (eq. 6) → a fully connected layer of 256 (eq. 7)
→ the classifier. Adam, lr 1e-3, batch 64 (``default_lr`` / ``default_batch``).

Choices the paper leaves open (ours, stated here and in the benchmark page):

* LSTM hidden size 64 per direction, one layer; the sequence is summarised by the last forward
  and the first backward hidden state (2·64 = 128 values per head).
* Max pooling with stride 3 (non-overlapping; "reduce its temporal dimension"), no padding.
* A ReLU after the 256-unit FC layer, then a linear layer to the classes (the paper's
  "classifier"; softmax inside the cross-entropy).

Heads (constructor switch ``heads``):

* ``1`` (baseline): one branch over every input channel.
* ``2`` (Head2, Fig. 2): one branch for the accelerometer channels, one for the gyroscope's.
* ``3`` (Head3, Fig. 3): one branch per axis, each with that axis' accelerometer and gyroscope.

Each head is a full conv → pool → Bi-LSTM branch; their summaries are concatenated before the
dropout and FC layer. Input: x (B, D, L, 6) and mask (B, D), layout "concat": the devices'
channels side by side, zeros where a device is absent, so a phone + watch input gives every
head the same channels of both devices (e.g. Head2's acc head sees phone and watch acc).

Placement- and orientation-agnostic input (issue 35; ``gravity_align``, the shipped activity
model ``har-gravity``): each device's window is first turned so that its mean acceleration (the
gravity direction, :func:`gravity_rotation`) points along +z, acc and gyro alike; its heading about
z stays whatever the device's was, so in training every window is also turned by a random yaw
(paper 002's rotation technique about the one axis left free, on the fly) and, with probability
``gyro_dropout``, its gyroscope channels are zeroed (sources and phones without a gyroscope give
zeros there), and each window's motion (acc and gyro about their window means) is scaled by a
random factor within 1 ± ``amp_jitter``, one for the horizontal axes and one for the vertical: a
phone in the hand moves less than one in a pocket and bounces more than it sways (median vertical
/ horizontal acceleration std of walking: ILC2's flat-held phone 3.3 / 0.5 m/s², MotionSense's
pocket 5.2 / 3.0, IPIN's hand-held 0.9 / 0.5), and the walk is the same walk. A model trained this way sees the same input from a phone in the hand, the pocket
or a bag held any way up.

Decision: docs/decisions/0030-activity-context-ensembles-amplitude.md.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn
from torch.nn import functional as F

from wearnav.errors import ConfigError
from wearnav.models.registry import register

# Below this cos(angle) between the window's gravity and +z the device is first turned by π about
# x (the closed form of gravity_rotation divides by 1 + cos and is ill-conditioned near −1).
FLIP_COS = -0.9

ACC, GYRO = (0, 1, 2), (3, 4, 5)
# har-gravity's motion-amplitude jitter: each training window's motion scaled within 1 ± this
# (wearnav.train.activity says why 0.8)
AMP_JITTER = 0.8
HEAD_CHANNELS: dict[int, list[tuple[int, ...]]] = {
    1: [ACC + GYRO],
    2: [ACC, GYRO],
    3: [(0, 3), (1, 4), (2, 5)],
}


def gravity_rotation(acc: Tensor) -> Tensor:
    """Rotation matrices R (..., 3, 3) with R · ĝ = +z for ĝ the unit mean of ``acc`` (..., L, 3)
    over its samples: the smallest rotation (Rodrigues, R = I + K + K²/(1 + c) with K = [ĝ × z]ₓ,
    c = ĝ·z), after a turn by π about x where c < :data:`FLIP_COS`. A window with no mean
    acceleration (all zeros: an absent device) gets the identity."""
    g = acc.mean(dim=-2)
    n = g.norm(dim=-1, keepdim=True)
    u = torch.where(n > 1e-6, g / n.clamp_min(1e-6), torch.zeros_like(g))
    u = torch.where(n > 1e-6, u, torch.tensor([0.0, 0.0, 1.0], dtype=acc.dtype, device=acc.device))
    flip = (u[..., 2] < FLIP_COS)[..., None, None]
    F_x = torch.diag(torch.tensor([1.0, -1.0, -1.0], dtype=acc.dtype, device=acc.device))
    u = torch.where(flip[..., 0], u * torch.tensor([1.0, -1.0, -1.0], dtype=acc.dtype, device=acc.device), u)
    z = torch.zeros_like(u)
    z[..., 2] = 1.0
    v = torch.cross(u, z, dim=-1)
    c = u[..., 2]
    K = torch.zeros(*u.shape[:-1], 3, 3, dtype=acc.dtype, device=acc.device)
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    eye = torch.eye(3, dtype=acc.dtype, device=acc.device).expand_as(K)
    R = eye + K + K @ K / (1.0 + c)[..., None, None].clamp_min(1e-6)
    return torch.where(flip, R @ F_x, R)


def rotate_windows(x: Tensor, R: Tensor) -> Tensor:
    """x (B, D, L, 6) with acc and gyro each turned by R (B, D, 3, 3)."""
    acc = torch.einsum("bdij,bdlj->bdli", R, x[..., :3])
    gyro = torch.einsum("bdij,bdlj->bdli", R, x[..., 3:6])
    return torch.cat([acc, gyro], dim=-1)


def yaw_matrices(theta: Tensor) -> Tensor:
    """Rotations about z by ``theta`` (...,) rad → (..., 3, 3)."""
    c, s = torch.cos(theta), torch.sin(theta)
    R = torch.zeros(*theta.shape, 3, 3, dtype=theta.dtype, device=theta.device)
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


class Branch(nn.Module):
    """Conv1d(64, k 5, s 1) + ReLU → MaxPool(3) → Bi-LSTM; (B, C, L) → (B, 2·hidden)."""

    def __init__(self, c_in: int, filters: int = 64, kernel: int = 5, pool: int = 3, hidden: int = 64):
        super().__init__()
        self.conv = nn.Conv1d(c_in, filters, kernel, stride=1)
        self.pool = nn.MaxPool1d(pool)
        self.lstm = nn.LSTM(filters, hidden, batch_first=True, bidirectional=True)

    def forward(self, x: Tensor) -> Tensor:
        h = self.pool(F.relu(self.conv(x)))
        _, (hn, _) = self.lstm(h.transpose(1, 2))
        return torch.cat([hn[0], hn[1]], dim=1)  # last forward state, first backward state


class HARNet(nn.Module):
    """CNN + Bi-LSTM activity / placement classifier with 1, 2 or 3 heads (module docstring)."""

    default_lr = 1e-3
    default_batch = 64

    def __init__(
        self,
        n_devices: int = 1,
        window: int = 128,
        n_classes: int = 6,
        heads: int = 1,
        filters: int = 64,
        kernel: int = 5,
        pool: int = 3,
        hidden: int = 64,
        dropout: float = 0.25,
        fc: int = 256,
        gravity_align: bool = False,
        gyro_dropout: float = 0.0,
        amp_jitter: float = 0.0,
    ):
        super().__init__()
        if heads not in HEAD_CHANNELS:
            raise ConfigError(f"heads must be 1, 2 or 3, got {heads}")
        if n_devices < 1 or n_classes < 2:
            raise ConfigError(f"need ≥ 1 device and ≥ 2 classes, got {n_devices} and {n_classes}")
        if (window - kernel + 1) // pool < 1:
            raise ConfigError(f"window of {window} samples is too short for kernel {kernel} and pool {pool}")
        if not 0.0 <= gyro_dropout < 1.0:
            raise ConfigError(f"gyro_dropout must be in [0, 1), got {gyro_dropout}")
        self.n_devices, self.window, self.n_classes, self.heads = n_devices, window, n_classes, heads
        if not 0.0 <= amp_jitter < 1.0:
            raise ConfigError(f"amp_jitter must be in [0, 1), got {amp_jitter}")
        self.gravity_align, self.gyro_dropout, self.amp_jitter = gravity_align, gyro_dropout, amp_jitter
        # Input channel indices of each head in the (D·6)-channel concatenated input.
        self.head_channels = [[d * 6 + c for d in range(n_devices) for c in chans] for chans in HEAD_CHANNELS[heads]]
        self.branches = nn.ModuleList(Branch(len(ch), filters, kernel, pool, hidden) for ch in self.head_channels)
        self.dropout = nn.Dropout(dropout)
        self.fc = nn.Linear(2 * hidden * heads, fc)
        self.classifier = nn.Linear(fc, n_classes)

    def head_inputs(self, x: Tensor, mask: Tensor) -> list[Tensor]:
        """What each head sees: (B, C_h, L) per head."""
        B, D, L, _ = x.shape
        if D != self.n_devices:
            raise ConfigError(f"model built for {self.n_devices} devices, got input with {D}")
        x = x * (mask > 0).to(x.dtype)[:, :, None, None]
        if self.gravity_align:
            R = gravity_rotation(x[..., :3])
            if self.training:  # a random heading per window (module docstring)
                R = yaw_matrices(2 * torch.pi * torch.rand(B, D, dtype=x.dtype, device=x.device)) @ R
            x = rotate_windows(x, R)
            if self.training and self.amp_jitter > 0:  # horizontal (x, y) and vertical (z) motion each its own factor
                f = 1.0 + self.amp_jitter * (2 * torch.rand(B, D, 1, 2, dtype=x.dtype, device=x.device) - 1)
                s = f[..., [0, 0, 1, 0, 0, 1]]
                mean = x.mean(dim=2, keepdim=True)
                x = mean + s * (x - mean)
            if self.training and self.gyro_dropout > 0:
                keep = (torch.rand(B, D, 1, 1, device=x.device) >= self.gyro_dropout).to(x.dtype)
                x = torch.cat([x[..., :3], x[..., 3:6] * keep], dim=-1)
        flat = x.permute(0, 1, 3, 2).reshape(B, D * 6, L)
        return [flat[:, ch] for ch in self.head_channels]

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        """Class logits (B, n_classes)."""
        h = torch.cat([b(xi) for b, xi in zip(self.branches, self.head_inputs(x, mask))], dim=1)
        return self.classifier(F.relu(self.fc(self.dropout(h))))

    def loss(self, batch: dict[str, Tensor]) -> tuple[Tensor, dict[str, Tensor]]:
        ce = F.cross_entropy(self(batch["x"], batch["mask"]), batch["label"])
        return ce, {"ce": ce}


@register(
    "har-cnn-bilstm",
    task="classify",
    layout="concat",
    description="HAR baseline: CNN(64,k5) → maxpool 3 → Bi-LSTM → dropout → FC 256 (paper 002)",
)
def har_baseline(n_devices: int = 1, window: int = 128, **kw) -> HARNet:
    return HARNet(n_devices, window, heads=1, **kw)


@register(
    "har-head2",
    task="classify",
    layout="concat",
    description="HAR Head2: accelerometer head + gyroscope head (paper 002, Fig. 2)",
)
def har_head2(n_devices: int = 1, window: int = 128, **kw) -> HARNet:
    return HARNet(n_devices, window, heads=2, **kw)


@register(
    "har-head3",
    task="classify",
    layout="concat",
    description="HAR Head3: one head per axis with its acc + gyro (paper 002, Fig. 3)",
)
def har_head3(n_devices: int = 1, window: int = 128, **kw) -> HARNet:
    return HARNet(n_devices, window, heads=3, **kw)


@register(
    "har-gravity",
    task="classify",
    layout="concat",
    description="HAR baseline on gravity-aligned windows, random yaw and gyro dropout in training (issue 35)",
)
def har_gravity(
    n_devices: int = 1,
    window: int = 128,
    gyro_dropout: float = 0.1,
    amp_jitter: float = AMP_JITTER,
    members: int = 1,
    **kw,
) -> HARNet | HAREnsemble:
    """One network, or with ``members`` > 1 an ensemble of that many (:class:`HAREnsemble`)."""
    if members < 1:
        raise ConfigError(f"members must be ≥ 1, got {members}")
    nets = [
        HARNet(n_devices, window, heads=1, gravity_align=True, gyro_dropout=gyro_dropout, amp_jitter=amp_jitter, **kw)
        for _ in range(members)
    ]
    return nets[0] if members == 1 else HAREnsemble(nets)


class HAREnsemble(nn.Module):
    """Networks of one architecture trained apart (each from its own seed: initial weights, batches,
    which windows are kept); the ensemble's class probabilities are the mean of theirs. ``forward``
    returns the log of that mean, so its softmax is the mean (issue 35: one network's walking recall
    on a held-out source moved by up to 0.26 between seeds; their mean moves far less)."""

    def __init__(self, members: list[HARNet]):
        super().__init__()
        self.members = nn.ModuleList(members)
        self.gravity_align = members[0].gravity_align
        self.n_classes = members[0].n_classes

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        p = torch.stack([torch.softmax(m(x, mask), dim=1) for m in self.members]).mean(dim=0)
        return torch.log(p.clamp_min(1e-12))
