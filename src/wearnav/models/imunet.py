"""IMUNet (Zeinali, Zanddizari & Chang, 2024: a 1-D CNN for inertial odometry on edge devices)
and IMUNet* (Suite-IN++'s starred baseline, paper 000 Sec. V-B: the devices' channels
concatenated).

IMUNet keeps RoNIN's ResNet layout (input block, four stride groups, transition and FC head) and
replaces each residual block's dense temporal convolutions by depthwise-separable ones (a kernel-3
depthwise convolution followed by a 1×1 pointwise one, each with batch norm; ELU activations), the
MobileNet recipe for a small compute budget. Its budget is then spent on width: groups of
100-200-400-800 channels (strides 1-2-2-2), so that at Suite-IN++'s 100-sample windows it has
the size of Table VI (IMUNet 4068.2 K, IMUNet* 4073.6 K parameters, 0.020 G multiply-accumulates;
IMUNet* − IMUNet = 5.4 K = the 12 extra input channels of the kernel-7 input conv with 64
filters, as for RoNIN*). The widths are our fit to those two numbers; the head is RoNIN's.

Layouts as RoNIN: ``imunet`` the first present device, ``imunet*`` all devices' channels.
"""

from __future__ import annotations

from torch import Tensor, nn

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel, concat_devices, first_present
from wearnav.models.registry import register
from wearnav.models.ronin import MIN_WINDOW


def separable(c_in: int, c_out: int, stride: int) -> nn.Sequential:
    """Depthwise kernel-3 conv (stride) + BN, then pointwise 1×1 conv + BN: (B, c_in, L) →
    (B, c_out, ⌈L/stride⌉)."""
    return nn.Sequential(
        nn.Conv1d(c_in, c_in, 3, stride, 1, groups=c_in, bias=False),
        nn.BatchNorm1d(c_in),
        nn.Conv1d(c_in, c_out, 1, bias=False),
        nn.BatchNorm1d(c_out),
    )


class SeparableBlock(nn.Module):
    """RoNIN's BasicBlock with depthwise-separable convolutions and ELU."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1):
        super().__init__()
        self.conv1, self.conv2 = separable(c_in, c_out, stride), separable(c_out, c_out, 1)
        self.act = nn.ELU(inplace=True)
        self.shortcut = None
        if stride != 1 or c_in != c_out:
            self.shortcut = nn.Sequential(nn.Conv1d(c_in, c_out, 1, stride, bias=False), nn.BatchNorm1d(c_out))

    def forward(self, x: Tensor) -> Tensor:
        out = self.conv2(self.act(self.conv1(x)))
        return self.act(out + (x if self.shortcut is None else self.shortcut(x)))


class IMUNet(OdometryModel):
    def __init__(
        self,
        n_devices: int = 3,
        window: int = 100,
        concat: bool = False,
        widths: tuple[int, ...] = (100, 200, 400, 800),
        blocks: tuple[int, ...] = (2, 2, 2, 2),
        base: int = 64,
        trans_planes: int = 128,
        fc_dim: int = 512,
        dropout: float = 0.5,
    ):
        super().__init__()
        if window < MIN_WINDOW:
            raise ConfigError(f"IMUNet needs windows of at least {MIN_WINDOW} samples, got {window}")
        if len(widths) != len(blocks):
            raise ConfigError("imunet: widths and blocks need one entry per group")
        self.n_devices, self.concat = n_devices, concat
        c = 6 * n_devices if concat else 6
        self.input_block = nn.Sequential(
            nn.Conv1d(c, base, 7, 2, 3, bias=False), nn.BatchNorm1d(base), nn.ELU(inplace=True), nn.MaxPool1d(3, 2, 1)
        )
        layers, c = [], base
        for i, (w, n) in enumerate(zip(widths, blocks)):
            layers += [SeparableBlock(c, w, 1 if i == 0 else 2)] + [SeparableBlock(w, w) for _ in range(n - 1)]
            c = w
        self.groups = nn.Sequential(*layers)
        self.transition = nn.Sequential(nn.Conv1d(c, trans_planes, 1, bias=False), nn.BatchNorm1d(trans_planes))
        length = -(-window // 2 ** (2 + len(widths) - 1))
        self.fc = nn.Sequential(
            nn.Linear(trans_planes * length, fc_dim),
            nn.ELU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, fc_dim),
            nn.ELU(inplace=True),
            nn.Dropout(dropout),
            nn.Linear(fc_dim, 2),
        )

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        h = concat_devices(x, mask) if self.concat else first_present(x, mask)[0].transpose(1, 2)
        h = self.transition(self.groups(self.input_block(h)))
        return self.fc(h.flatten(1))


@register(
    "imunet",
    task="odometry",
    layout="single",
    description="IMUNet: depthwise-separable 1-D ResNet on one device (phone; else the first present)",
)
def imunet(n_devices: int = 3, window: int = 100, **kw) -> IMUNet:
    return IMUNet(n_devices, window, concat=False, **kw)


@register(
    "imunet*",
    task="odometry",
    layout="concat",
    description="IMUNet*: depthwise-separable 1-D ResNet on all devices' channels (zeros if absent)",
)
def imunet_star(n_devices: int = 3, window: int = 100, **kw) -> IMUNet:
    return IMUNet(n_devices, window, concat=True, **kw)
