"""RoNIN ResNet-18-1D (Herath, Yan & Furukawa, ICRA 2020), the RoNIN baseline of Suite-IN++.

RoNIN regresses the horizontal velocity from a window of IMU samples rotated into a
heading-agnostic world frame, the accelerometer *including gravity* (its data loader feeds the
rotated raw specific force and angular rate, no gravity removal, no normalisation). Our input is
the same kind of signal (world-frame acc incl. gravity + gyro), so it is fed unchanged; the
constant ≈ +9.8 m/s² on the vertical channel is absorbed by the first BatchNorm.

Architecture (RoNIN's "RoNIN ResNet", as in its official code, which Suite-IN++ Sec. V-B extends):

- input block: Conv1d(C, 64, kernel 7, stride 2) + BN + ReLU + MaxPool(3, stride 2);
- four residual groups of two BasicBlocks (kernel 3) with widths 64-128-256-512 and strides
  1-2-2-2, a 1×1 conv + BN shortcut where the shape changes;
- output block: 1×1 transition conv to 128 channels + BN, flatten, FC 512 → ReLU → dropout 0.5
  → FC 512 → ReLU → dropout 0.5 → FC 2.

The temporal length after the backbone is ⌈L/32⌉ (five halvings), so the first FC layer has
128·⌈L/32⌉ inputs: 128·7 for RoNIN's 200-sample windows, 128·4 for Suite-IN++'s 100 samples at
25 Hz. With the latter this model has 4.44 M parameters (Suite-IN++ Table VI lists 4438.2 K for
RoNIN and 4443.7 K for RoNIN*, which is exactly the 12 extra input channels of the first conv).

Device layouts (Suite-IN++ Sec. V-B):

- ``ronin`` ("single"): RoNIN is a phone-only method. Each sample uses the first device of the
  layout that is present (mask 1): the phone where it is present; where it is absent, the next
  present device in layout order (watch, then earbuds), chosen per sample. A sample with no
  device present sees zeros (its prediction is then the network's bias only).
- ``ronin*`` ("concat"): the starred baseline; the devices' 6 channels side by side in layout
  order (6·D input channels), zeros for absent devices.
"""

from __future__ import annotations

from torch import Tensor, nn

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel, concat_devices, first_present
from wearnav.models.registry import register

MIN_WINDOW = 32  # five stride-2 stages: anything shorter has no temporal sample left to pool


class BasicBlock1D(nn.Module):
    """Two kernel-3 convolutions with BN; identity or 1×1-conv shortcut (He et al. 2016)."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1, kernel: int = 3):
        super().__init__()
        pad = kernel // 2
        self.conv1 = nn.Conv1d(c_in, c_out, kernel, stride, pad, bias=False)
        self.bn1 = nn.BatchNorm1d(c_out)
        self.conv2 = nn.Conv1d(c_out, c_out, kernel, 1, pad, bias=False)
        self.bn2 = nn.BatchNorm1d(c_out)
        self.relu = nn.ReLU(inplace=True)
        self.shortcut = None
        if stride != 1 or c_in != c_out:
            self.shortcut = nn.Sequential(nn.Conv1d(c_in, c_out, 1, stride, bias=False), nn.BatchNorm1d(c_out))

    def forward(self, x: Tensor) -> Tensor:
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        skip = x if self.shortcut is None else self.shortcut(x)
        return self.relu(out + skip)


def resnet_layers(
    in_channels: int, blocks=(2, 2, 2, 2), base: int = 64, trans_planes: int = 128, input_stride: int = 2
) -> tuple[nn.Sequential, nn.Sequential, nn.Sequential, int]:
    """RoNIN's ResNet-18-1D body: the input block (7-tap convolution with ``input_stride``, batch
    norm, ReLU, and a stride-2 max-pool where ``input_stride`` > 1), the residual groups (widths
    ``base`` · 2^i, stride 2 from the second) and the 1×1 transition to ``trans_planes``; and how
    many times they halve the length (all padded: L → ceil(L / 2^halvings))."""
    layers: list[nn.Module] = [
        nn.Conv1d(in_channels, base, 7, input_stride, 3, bias=False),
        nn.BatchNorm1d(base),
        nn.ReLU(inplace=True),
    ]
    if input_stride > 1:
        layers.append(nn.MaxPool1d(3, 2, 1))
    groups, c = [], base
    for i, n in enumerate(blocks):
        width, stride = base * 2**i, 1 if i == 0 else 2
        groups += [BasicBlock1D(c, width, stride)] + [BasicBlock1D(width, width) for _ in range(n - 1)]
        c = width
    transition = nn.Sequential(nn.Conv1d(c, trans_planes, 1, bias=False), nn.BatchNorm1d(trans_planes))
    halvings = (2 if input_stride > 1 else 0) + len(blocks) - 1
    return nn.Sequential(*layers), nn.Sequential(*groups), transition, halvings


class ResNet1D(nn.Module):
    """RoNIN's ResNet-18-1D backbone and FC output head: (B, C, L) → (B, n_out)."""

    def __init__(
        self,
        in_channels: int,
        window: int,
        n_out: int = 2,
        blocks=(2, 2, 2, 2),
        base: int = 64,
        trans_planes: int = 128,
        fc_dim: int = 512,
        dropout: float = 0.5,
    ):
        super().__init__()
        if window < MIN_WINDOW:
            raise ConfigError(f"RoNIN ResNet needs windows of at least {MIN_WINDOW} samples, got {window}")
        self.input_block, self.groups, self.transition, halvings = resnet_layers(
            in_channels, blocks, base, trans_planes, input_stride=2
        )
        length = -(-window // 2**halvings)
        self.fc = nn.Sequential(
            nn.Linear(trans_planes * length, fc_dim),
            nn.ReLU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, fc_dim),
            nn.ReLU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, n_out),
        )
        self._init_weights()

    def _init_weights(self) -> None:
        # RoNIN's initialisation: He (fan-out) convolutions, unit BN, small-normal linear layers.
        for m in self.modules():
            if isinstance(m, nn.Conv1d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            elif isinstance(m, nn.BatchNorm1d):
                nn.init.ones_(m.weight)
                nn.init.zeros_(m.bias)
            elif isinstance(m, nn.Linear):
                nn.init.normal_(m.weight, 0.0, 0.01)
                nn.init.zeros_(m.bias)

    def forward(self, x: Tensor) -> Tensor:
        h = self.transition(self.groups(self.input_block(x)))
        return self.fc(h.flatten(1))


class RoNIN(OdometryModel):
    """RoNIN ResNet-18-1D on one device or on all devices' channels (see module docstring)."""

    def __init__(self, n_devices: int = 3, window: int = 100, concat: bool = False, **resnet_kw):
        super().__init__()
        if n_devices < 1:
            raise ConfigError(f"n_devices must be ≥ 1, got {n_devices}")
        self.n_devices, self.window, self.concat = n_devices, window, concat
        self.net = ResNet1D(6 * n_devices if concat else 6, window, **resnet_kw)

    def inputs(self, x: Tensor, mask: Tensor) -> Tensor:
        """The network input (B, C, L) for x (B, D, L, 6) and mask (B, D)."""
        B, D, L, _ = x.shape
        if D != self.n_devices:
            raise ConfigError(f"model built for {self.n_devices} devices, got input with {D}")
        if self.concat:
            return concat_devices(x, mask)
        return first_present(x, mask)[0].transpose(1, 2)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self.net(self.inputs(x, mask))


@register(
    "ronin",
    task="odometry",
    layout="single",
    description="RoNIN ResNet-18-1D on one device (phone; else the first present device)",
)
def ronin(n_devices: int = 3, window: int = 100, **kw) -> RoNIN:
    return RoNIN(n_devices, window, concat=False, **kw)


@register(
    "ronin*",
    task="odometry",
    layout="concat",
    description="RoNIN ResNet-18-1D on all devices' channels concatenated (zeros if absent)",
)
def ronin_star(n_devices: int = 3, window: int = 100, **kw) -> RoNIN:
    return RoNIN(n_devices, window, concat=True, **kw)
