"""IONet (Chen et al., AAAI 2018, EasyTrack's baseline [1]): a 2-layer bidirectional LSTM with 96
hidden units per direction over a window of raw IMU, its last step through a linear layer.

Differences from the paper, on purpose: IONet reads the phone's device-frame IMU and outputs a
polar displacement (Δl, Δψ) that must be chained through the heading; here, as for every wearnav
odometry model, the input is the world-frame IMU (the phone's own orientation applied) and the
output is the horizontal vector (the odometry contract's velocity; the EasyTrack benchmark reads
it as a segment displacement), so it can be scored window by window like the others. Input
standardisation: gravity off z, acc / 2 m/s² (fixed, so ``wearnav train --model ionet`` needs no
data statistics).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from wearnav.models.base import OdometryModel, first_present
from wearnav.models.registry import register
from wearnav.recording import STANDARD_GRAVITY


class IONet(OdometryModel):
    def __init__(self, n_devices: int = 3, window: int = 200, hidden: int = 96, layers: int = 2):
        super().__init__()
        self.n_devices, self.window = n_devices, window
        self.lstm = nn.LSTM(6, hidden, num_layers=layers, batch_first=True, bidirectional=True)
        self.fc = nn.Linear(2 * hidden, 2)
        self.register_buffer("shift", torch.tensor([0.0, 0.0, STANDARD_GRAVITY, 0.0, 0.0, 0.0]))
        self.register_buffer("scale", torch.tensor([2.0, 2.0, 2.0, 1.0, 1.0, 1.0]))

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        s = (first_present(x, mask)[0] - self.shift) / self.scale
        h, _ = self.lstm(s)
        return self.fc(h[:, -1])


@register("ionet", task="odometry", layout="single",
          description="IONet: 2-layer Bi-LSTM (96) on one device's IMU window → horizontal vector")
def ionet(n_devices: int = 3, window: int = 200, **kw) -> IONet:
    return IONet(n_devices=n_devices, window=window, **kw)
