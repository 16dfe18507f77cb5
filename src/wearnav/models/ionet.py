"""IONet (Chen et al., AAAI 2018, EasyTrack's baseline [1]) and IONet* (Suite-IN++'s starred
baseline, paper 000 Sec. V-B): a 2-layer LSTM with 96 hidden units over a window of raw IMU, its
last step through a linear layer.

``ionet`` ("single"): IONet as its own paper builds it, bidirectional (96 per direction), on the
first present device (the phone where present). ``ionet*`` ("concat"): the devices' channels side
by side (6·D inputs, zeros for an absent device), unidirectional: that is the size Suite-IN++'s
Table VI lists (IONet 114.6 K, IONet* 119.2 K parameters, exactly a one-direction 2-layer LSTM of
96 plus the linear head; ``bidirectional`` switches either).

Differences from the paper, on purpose: IONet reads the phone's device-frame IMU and outputs a
polar displacement (Δl, Δψ) that must be chained through the heading; here, as for every wearnav
odometry model (and as Suite-IN++ adapts it), the input is the world-frame IMU and the output is
the horizontal velocity, so it can be scored window by window like the others. Input
standardisation: gravity off z, acc / 2 m/s² (fixed, so training needs no data statistics).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from wearnav.models.base import OdometryModel, concat_devices, first_present
from wearnav.models.registry import register
from wearnav.recording import STANDARD_GRAVITY


class IONet(OdometryModel):
    shift: Tensor  # buffers (register_buffer), typed
    scale: Tensor

    def __init__(
        self,
        n_devices: int = 3,
        window: int = 200,
        hidden: int = 96,
        layers: int = 2,
        concat: bool = False,
        bidirectional: bool = True,
    ):
        super().__init__()
        self.n_devices, self.window, self.concat = n_devices, window, concat
        reps = n_devices if concat else 1
        self.lstm = nn.LSTM(6 * reps, hidden, num_layers=layers, batch_first=True, bidirectional=bidirectional)
        self.fc = nn.Linear(hidden * (2 if bidirectional else 1), 2)
        self.register_buffer("shift", torch.tensor([0.0, 0.0, STANDARD_GRAVITY, 0.0, 0.0, 0.0]).repeat(reps))
        self.register_buffer("scale", torch.tensor([2.0, 2.0, 2.0, 1.0, 1.0, 1.0]).repeat(reps))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        if self.concat:
            present = (mask > 0).to(x.dtype).repeat_interleave(6, dim=1)[:, None]  # (B, 1, 6D)
            s = (concat_devices(x, mask).transpose(1, 2) - self.shift) / self.scale * present
        else:
            s = (first_present(x, mask)[0] - self.shift) / self.scale
        h, _ = self.lstm(s)
        return self.fc(h[:, -1])


@register(
    "ionet",
    task="odometry",
    layout="single",
    description="IONet: 2-layer Bi-LSTM (96) on one device's IMU window → horizontal vector",
)
def ionet(n_devices: int = 3, window: int = 200, **kw) -> IONet:
    return IONet(n_devices=n_devices, window=window, **kw)


@register(
    "ionet*",
    task="odometry",
    layout="concat",
    description="IONet*: 2-layer LSTM (96) on all devices' channels concatenated (zeros if absent)",
)
def ionet_star(n_devices: int = 3, window: int = 100, **kw) -> IONet:
    return IONet(n_devices=n_devices, window=window, **{"concat": True, "bidirectional": False, **kw})
