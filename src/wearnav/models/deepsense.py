"""DeepSense* (Yao et al., WWW 2017; Suite-IN++'s baseline [47], paper 000 Sec. V-B): the classic
multi-sensor network, "three layers of local CNN, three layers of global CNN and two layers of
GRU", turned to positioning as Suite-IN++ does (the window's mean horizontal velocity).

Sensors: each device's accelerometer and gyroscope are two sensors (K = 2·D, in layout order),
their channels side by side with zeros for an absent device ("concat", the starred variant). The
window is cut into ``intervals`` equal time intervals (DeepSense's τ); each interval of each
sensor is a (3 axes × τ samples) image. DeepSense feeds the interval's Fourier coefficients; we
feed the samples themselves, the world-frame signal every other model reads.

- local CNN, per sensor (own weights, shared by the intervals): conv (3 × 2) over axes × time
  collapsing the axes, then convs of temporal kernel 3 and 2; ``local`` filters each, batch norm,
  ReLU, dropout;
- global CNN, shared: the K sensors' local outputs stacked on a sensor axis, conv (K × 2) over
  sensors × time, then temporal kernels 3 and 2, ``global_`` filters;
- the flattened global output of each interval → 2-layer GRU (``gru_hidden``) over the intervals,
  its outputs averaged over intervals → linear → velocity.

Filter counts and GRU width are our fit to Table VI (DeepSense: 318.2 K parameters, 0.007 G
multiply-accumulates; ours: 32 local and 64 global filters, GRU 140 → 317.1 K, 6.7 M); the
original uses 64 filters and GRU 120, which here would cost 14 M MACs.
"""

from __future__ import annotations

from torch import Tensor, nn

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel, concat_devices
from wearnav.models.registry import register


def _block(c_in: int, c_out: int, kernel: tuple[int, int], dropout: float) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, kernel), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True), nn.Dropout(dropout)
    )


class DeepSense(OdometryModel):
    def __init__(
        self,
        n_devices: int = 3,
        window: int = 100,
        intervals: int = 10,
        local: int = 32,
        global_: int = 64,
        gru_hidden: int = 140,
        dropout: float = 0.2,
    ):
        super().__init__()
        tau = window // intervals
        if tau < 6:
            raise ConfigError(f"deepsense: window {window} / {intervals} intervals leaves < 6 samples each")
        self.n_devices, self.intervals, self.tau = n_devices, intervals, tau
        self.sensors = K = 2 * n_devices
        # Local CNN of every sensor as one grouped stack: group k = sensor k.
        self.local = nn.Sequential(
            _block(K, K * local, (3, 2), dropout),
            nn.Sequential(
                nn.Conv2d(K * local, K * local, (1, 3), groups=K),
                nn.BatchNorm2d(K * local),
                nn.ReLU(inplace=True),
                nn.Dropout(dropout),
            ),
            nn.Sequential(
                nn.Conv2d(K * local, K * local, (1, 2), groups=K),
                nn.BatchNorm2d(K * local),
                nn.ReLU(inplace=True),
                nn.Dropout(dropout),
            ),
        )
        self.local_channels = local
        self.global_ = nn.Sequential(
            _block(local, global_, (K, 2), dropout),
            _block(global_, global_, (1, 3), dropout),
            _block(global_, global_, (1, 2), dropout),
        )
        steps = tau - 1 - 2 - 1 - 1 - 2 - 1
        self.gru = nn.GRU(global_ * steps, gru_hidden, num_layers=2, batch_first=True)
        self.head = nn.Linear(gru_hidden, 2)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        B = x.shape[0]
        if x.shape[1] != self.n_devices:
            raise ConfigError(f"deepsense: model built for {self.n_devices} devices, got {x.shape[1]}")
        h = concat_devices(x, mask)[..., : self.intervals * self.tau]  # (B, 6D, L)
        K, T, tau = self.sensors, self.intervals, self.tau
        # (B, K, 3, T, tau) → (B·T, K, 3, tau): one image per sensor and interval.
        h = h.view(B, K, 3, T, tau).permute(0, 3, 1, 2, 4).reshape(B * T, K, 3, tau)
        h = self.local(h)  # (B·T, K·c, 1, t)
        h = h.view(B * T, K, self.local_channels, -1).transpose(1, 2)  # (B·T, c, K, t)
        h = self.global_(h)  # (B·T, g, 1, t')
        r, _ = self.gru(h.reshape(B, T, -1))
        return self.head(r.mean(1))


@register(
    "deepsense*",
    task="odometry",
    layout="concat",
    description="DeepSense*: local CNN per sensor, global CNN across sensors, 2-layer GRU over intervals",
)
def deepsense_star(n_devices: int = 3, window: int = 100, **kw) -> DeepSense:
    return DeepSense(n_devices, window, **kw)
