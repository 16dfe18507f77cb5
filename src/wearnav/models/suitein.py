"""Suite-IN++ and its predecessor Suite-IN (paper 000, Sec. IV, eqs. 1–25; set-up Sec. V-A).

Read top to bottom: configuration, the per-device extractors (eqs. 1–2), the losses that separate
global from local features (eqs. 3–5), weighted global fusion (eqs. 9–15), attentive local
analysis (eqs. 16–20), velocity fusion and the total loss (eqs. 21–25), then the registered
constructors.

Shapes. Input ``x`` (B, D, L, 6): world-frame acc + gyro of D devices (phone, watch, earbuds), L =
100 samples at 25 Hz; ``mask`` (B, D) is 1.0 where a device is present. Output: the window's mean
horizontal velocity (B, 2) in m/s.

Flexible device number. An absent device (mask 0) never enters a computation for its sample: it
is left out of the batch-norm statistics, of the fusion weights' normalisation (eq. 12), of the
contrastive and orthogonality pairs (eqs. 3–5), of the attention keys (eq. 18) and of the mean
over devices after it. A sample's output does not depend on an absent device's input. A sample
with one device has no pairs: its contrastive and orthogonality terms are zero, not NaN.

Choices where the paper is silent (aimed at its budget of ≈ 0.5 M parameters, 0.020 GFLOPs):

* Extractors (eqs. 1–2): six blocks conv → batch norm → ReLU → max-pool → dropout 0.2 with
  temporal kernels [3, 2, 2, 2, 2, 2] (the paper's), widths ``widths`` and pool sizes ``pools``
  (max-pool over time by 2 in blocks 4–6; time goes 100 → 11 steps, so the GRU of eq. 14 still
  sees a sequence). Two readings of "six 1-D CNN blocks", both at the paper's size (498.8 K
  parameters, 0.020 G MACs, Table VI; its "FLOPs" are MACs, GRU included):
  - ``extractor="mixed"`` (the default): the six IMU axes are the first convolution's input
    channels (block 1 mixes them). Widths 48, 64, 64, 76, 72, 68: 496.8 K parameters, 19.4 M MACs.
  - ``extractor="paper"`` (``suitein++-rows``, ``ROWS_SIZE``): the kernels slide "over the time
    dimension ... without altering the sensor channel dimensionality" (Sec. IV-B): each axis is
    a row of its own (kernels (1, k) on one input channel, shared by the rows, as in
    DeepConvLSTM [7]), the rows flattened into the features after block 6. Widths 16, 24, 32,
    32, 32, 28: 498.9 K parameters, 21.0 M MACs. The paper also pools "along the temporal and
    sensor channel dimension"; ``sensor_pools`` does that along the rows, but off by default:
    with kernels shared by the rows, a max over rows is symmetric in them (swap acc x and y →
    the same features; tested), so the model could not tell a velocity's x from its y.
  The default is "mixed": the row reading takes 10× the training time on a CPU and learns later
  (Decision: docs/decisions/0012-table-iii-models-at-table-vi-size.md). Max-pool comes before ReLU (they commute) and
  dropout after the pool, which is the paper's block with less work.
* All D devices' global and local extractors run as ONE grouped convolution (groups = devices ×
  branches) in channels-last layout; arithmetic is that of separate extractors (tested). Small
  temporal convolutions are memory-bound, so at inference batch norm is folded into the
  convolution, ReLU is fused into it (oneDNN), max-pool is a strided maximum and windows pass
  in chunks of 64 that stay in cache; in training the masked batch norm has a hand-written
  backward. Measurements: :mod:`wearnav.bench.efficiency`.
* Features compared in eqs. 3–5 are the flattened extractor outputs H (T' × C); cosine
  similarity needs no projection head since global and local extractors share a shape.
* τ = 0.1 (eq. 4): the usual InfoNCE temperature for cosine similarities (SimCLR, CoCoA).
  Eq. 3 is summed over ordered device pairs as printed and averaged over the batch.
* Eq. 5 is "a cosine embedding loss": PyTorch's CosineEmbeddingLoss with target −1 and margin 0,
  i.e. max(0, cos). The printed raw cosine would be minimised at −1 (anti-parallel), which is not
  orthogonality.
* Eq. 9 pools time by ``glb_pool`` = 3 (11 → 3 steps, average, the last step left out); eq. 10's
  w_glb, b_glb are shared by the devices (no device index in the paper) and l_glb = len(u_glb)
  (flattened).
* Eq. 14: a 2-layer GRU (hidden 64) over the 3 pooled steps; its last output is r_glb; FC_glb
  (eq. 15) is one linear layer. The GRU is kept when Weighted.GF is switched off (then
  α_j = 1/J_present, Suite-IN's mean), so an ablation changes exactly one mechanism.
* Eqs. 16–17: per-device linear maps of the flattened local features, divided by l_loc =
  len(u_loc) as printed. Eq. 18: multi-head self-attention (4 heads, with query/key/value and
  output projections) over the device tokens, absent devices masked as keys; the mean over
  present devices, ReLU(FC) (eq. 19), FC_loc (eq. 20).
* Eq. 21's FC(v_glb ⊕ v_loc) starts as v_glb + v_loc, the reading eq. 22 gives it (v_loc is a
  correction of v_glb); it is trained freely from there.
* Eq. 22's target v − v_glb is a target: v_glb is detached there, so the local branch cannot
  move the global estimate through it.
* Ablation switches (Table V): ``contrast`` (Contrast.FE, eqs. 3–5), ``weighted`` (Weighted.GF,
  eqs. 9–13; off = mean fusion) and ``attentive`` (Attentive.LA, eqs. 16–22; off = the output is
  v_glb and the loss is λ_v·MSE(v_glb, v)). Local extractors exist only where something uses them
  (contrast or attentive); without both, each device has one "hybrid" extractor — variant (1).

Table V variants → switches (registered as ``suitein++-abl1`` … ``-abl5``; (6) is ``suitein++``):

    (1) contrast=False weighted=False attentive=False   hybrid features, mean fusion
    (2) contrast=False weighted=True  attentive=False
    (3) contrast=True  weighted=False attentive=True
    (4) contrast=False weighted=True  attentive=True    two extractors, separated implicitly
    (5) contrast=True  weighted=True  attentive=False
    (6) contrast=True  weighted=True  attentive=True    Suite-IN++
    Suite-IN [3]: contrast=True weighted=False attentive=False (local features only in eq. 3–5).

Suite-IN is built at its own size (Table VI: 104.3 K parameters, 0.026 G MACs; its widths are
not given in this paper): ``SUITEIN_SIZE`` (the row-keeping extractor, widths 24, 32, 36, 36,
24, 16, GRU 56: 102.5 K parameters, 26.6 M MACs; the mixed reading has ≥ 235 K parameters by
the time it reaches 16 M MACs, so it cannot be Suite-IN's size). Its ``widths`` etc. can be overridden like any hyper-parameter.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import cast

import torch
from torch import Tensor, nn
from torch.nn import functional as F
from torch.utils.flop_counter import conv_flop_count, flop_registry, register_flop_formula

from wearnav.errors import ConfigError
from wearnav.models.base import OdometryModel, velocity_loss
from wearnav.models.registry import register

IMU_CHANNELS = 6  # acc xyz + gyro xyz, world frame
EXTRACTORS = ("paper", "mixed")  # SuiteINConfig.extractor


@dataclass(frozen=True)
class SuiteINConfig:
    n_devices: int = 3
    window: int = 100  # samples at 25 Hz (Sec. V-A)
    widths: tuple[int, ...] = (48, 64, 64, 76, 72, 68)
    kernels: tuple[int, ...] = (3, 2, 2, 2, 2, 2)  # the paper's temporal kernels
    pools: tuple[int, ...] = (1, 1, 1, 2, 2, 2)
    # "paper": each IMU axis stays a row of its own through the blocks (temporal kernels (1, k)
    # slide over time on every row, max-pool by ``sensor_pools`` along the axes; ROWS_SIZE gives
    # it the paper's size); "mixed" (default, measured: module docstring): the six axes are the
    # first convolution's input channels (block 1 mixes them).
    extractor: str = "mixed"
    sensor_pools: tuple[int, ...] = (1, 1, 1, 1, 1, 1)  # paper: rows kept (module docstring)
    dropout: float = 0.2
    glb_pool: int = 3  # eq. 9
    gru_hidden: int = 64  # eq. 14
    loc_dim: int = 64  # d^j of eq. 17
    heads: int = 4  # eq. 18
    loc_hidden: int = 64  # r_loc of eq. 19
    tau: float = 0.1  # eq. 4
    lambda_a: float = 9.0  # eq. 11
    lambda_b: float = 0.01
    lambda_c: float = 10.0
    w_vel: float = 1.0  # eq. 25: λ_v, λ_v^glb, λ_v^loc, λ_c(on), λ_o(rth)
    w_vel_glb: float = 0.1
    w_vel_loc: float = 1.0
    w_con: float = 0.2
    w_orth: float = 0.05
    contrast: bool = True  # Contrast.FE
    weighted: bool = True  # Weighted.GF
    attentive: bool = True  # Attentive.LA

    def __post_init__(self) -> None:
        if not (len(self.widths) == len(self.kernels) == len(self.pools) == len(self.sensor_pools)):
            raise ConfigError("suitein: widths, kernels, pools and sensor_pools need one entry per block")
        if self.extractor not in EXTRACTORS:
            raise ConfigError(f"suitein: extractor must be one of {EXTRACTORS}, got {self.extractor!r}")
        if self.sensor_rows < 1:
            raise ConfigError(f"suitein: sensor_pools {self.sensor_pools} pool the 6 axes below one row")
        if self.n_devices < 1:
            raise ConfigError(f"suitein: n_devices must be ≥ 1, got {self.n_devices}")
        if self.loc_dim % self.heads:
            raise ConfigError(f"suitein: loc_dim {self.loc_dim} is not a multiple of heads {self.heads}")
        if self.feature_steps < self.glb_pool:
            raise ConfigError(f"suitein: window {self.window} is too short for the extractor's pooling")

    @property
    def branches(self) -> int:
        """Extractors per device: global and local, or one hybrid one (ablation (1)/(2))."""
        return 2 if (self.contrast or self.attentive) else 1

    @property
    def row_pools(self) -> tuple[int, ...]:
        """Max-pool along the sensor axis per block: ``sensor_pools`` for the paper's extractor,
        none for the mixed one (it has a single row)."""
        return self.sensor_pools if self.extractor == "paper" else (1,) * len(self.widths)

    @property
    def sensor_rows(self) -> int:
        """Rows left of the input's 6 (paper) or 1 (mixed) after the blocks' sensor pooling."""
        rows = IMU_CHANNELS if self.extractor == "paper" else 1
        for p in self.row_pools:
            rows //= p
        return rows

    @property
    def feature_steps(self) -> int:
        """T', the time steps left after the six blocks."""
        t = self.window
        for i, (k, p) in enumerate(zip(self.kernels, self.pools)):
            t = (t + 2 * (k // 2 if i == 0 else 0) - k + 1) // p
        return t


# --- Extractors (eqs. 1–2) --------------------------------------------------------------------


class _MaskedBatchNormFn(torch.autograd.Function):
    """Training batch norm of y (B, T, G, C) with statistics over the present samples of each
    group (mask m (B, G)), written out with its closed-form gradient: a few passes over
    contiguous channels, where PyTorch's channels-last batch-norm backward is slow on a CPU."""

    @staticmethod
    def forward(ctx, y, m, weight, bias, eps):
        n = (m.sum(0) * y.shape[1])[:, None]  # (G, 1)
        mb = m[:, :, None]  # (B, G, 1)
        mean = (y.sum(1) * mb).sum(0) / n.clamp(min=1)  # (G, C)
        # One pass, E[y²] − mean²: exact enough in fp32 while |mean|/std ≪ 10³ (gravity on the
        # world z axis gives ~10²) and it saves a pass over the largest activations.
        var = (((y * y).sum(1) * mb).sum(0) / n.clamp(min=1) - mean.square()).clamp(min=0)
        # A group nobody in the batch has passes through unscaled (its outputs are unused):
        # 1/sqrt(eps) per block would blow its values up towards inf.
        var = torch.where(n > 0, var, 1.0)
        invstd = torch.rsqrt(var + eps)
        scale = weight * invstd
        ctx.save_for_backward(y, m, mean, invstd, weight, n.clamp(min=1))
        return torch.addcmul(bias - mean * scale, y, scale), mean, var

    @staticmethod
    def backward(ctx, dout, _dmean, _dvar):
        y, m, mean, invstd, weight, n = ctx.saved_tensors
        dbias = dout.sum((0, 1))
        dweight = ((dout * y).sum((0, 1)) - mean * dbias) * invstd  # Σ dout·x̂
        # Every output depends on the statistics; only present inputs move them.
        scale = weight * invstd
        k1 = -scale * invstd * dweight / n
        k0 = -scale * dbias / n - k1 * mean
        dx = torch.addcmul(k0, y, k1).mul_(m[:, None, :, None]).addcmul_(dout, scale)
        return dx, None, dweight, dbias, None


class MaskedBatchNorm(nn.Module):
    """Batch norm over (batch, time) per channel whose training statistics skip absent devices.

    Input (B, G·C, H, T) (H sensor rows) with a per-(sample, group) mask (B, G); at inference it
    is an affine map that :class:`GroupedExtractors` folds into the preceding convolution.
    """

    running_mean: Tensor  # buffers (register_buffer), typed
    running_var: Tensor

    def __init__(self, groups: int, channels: int, momentum: float = 0.1, eps: float = 1e-5):
        super().__init__()
        self.groups, self.channels, self.momentum, self.eps = groups, channels, momentum, eps
        self.weight = nn.Parameter(torch.ones(groups * channels))
        self.bias = nn.Parameter(torch.zeros(groups * channels))
        self.register_buffer("running_mean", torch.zeros(groups * channels))
        self.register_buffer("running_var", torch.ones(groups * channels))

    def scale_shift(self) -> tuple[Tensor, Tensor]:
        """The inference affine map y = x·scale + shift."""
        scale = self.weight * torch.rsqrt(self.running_var + self.eps)
        return scale, self.bias - self.running_mean * scale

    def forward(self, y: Tensor, group_mask: Tensor) -> Tensor:
        if not self.training:
            scale, shift = self.scale_shift()
            return y * scale.view(1, -1, 1, 1) + shift.view(1, -1, 1, 1)
        B, _, H, T = y.shape
        G, C = self.groups, self.channels
        # (B, H·T, G, C) is the memory order of a channels-last (B, G·C, H, T): a view.
        yt = y.permute(0, 2, 3, 1).reshape(B, H * T, G, C)
        out, mean, var = _MaskedBatchNormFn.apply(
            yt, group_mask.to(y.dtype), self.weight.view(G, C), self.bias.view(G, C), self.eps
        )
        with torch.no_grad():  # running statistics move only where someone was present
            n = (group_mask.sum(0) * H * T)[:, None].expand(G, C).reshape(-1)
            step = torch.where(n > 1, self.momentum, 0.0)
            self.running_mean.lerp_(mean.reshape(-1), step)
            self.running_var.lerp_(var.reshape(-1) * n / (n - 1).clamp(min=1), step)  # unbiased
        return out.reshape(B, H, T, G * C).permute(0, 3, 1, 2)


def max_pool_time(h: Tensor, p: int, rows: int = 1) -> Tensor:
    """Max-pool (B, C, H, T) over time by p and over the rows H by ``rows`` (tails dropped) as
    element-wise maxima of strided views: for inference it keeps the channels-last layout and is
    several times faster on a CPU than F.max_pool2d, which also computes indices."""
    if p > 1:
        T = h.shape[-1] // p * p
        out = h[..., 0:T:p]
        for i in range(1, p):
            out = torch.maximum(out, h[..., i:T:p])
        h = out
    if rows > 1:
        H = h.shape[-2] // rows * rows
        out = h[..., 0:H:rows, :]
        for i in range(1, rows):
            out = torch.maximum(out, h[..., i:H:rows, :])
        h = out
    return h


# oneDNN convolution with the ReLU fused in (what torch.compile uses on a CPU); inference only.
_CONV_RELU = getattr(torch.ops.mkldnn, "_convolution_pointwise", None) if torch.backends.mkldnn.is_available() else None
if _CONV_RELU is not None and _CONV_RELU not in flop_registry:  # FlopCounterMode counts it

    @register_flop_formula(_CONV_RELU)
    def _conv_relu_flops(x_shape, w_shape, *args, out_shape=None, **kwargs) -> int:
        return conv_flop_count(x_shape, w_shape, out_shape)


def conv_relu(h: Tensor, w: Tensor, b: Tensor, conv: nn.Conv2d, fused: bool = True) -> Tensor:
    """ReLU(conv(h)) with weights w, bias b and ``conv``'s geometry; ``fused``: oneDNN's fused
    kernel where it applies (CPU inference), else plain ``F.conv2d`` (what an export traces)."""
    if fused and _CONV_RELU is not None and h.device.type == "cpu" and not torch.is_grad_enabled():
        return _CONV_RELU(
            h, w, b, list(conv.padding), list(conv.stride), list(conv.dilation), conv.groups, "relu", [], ""
        )
    return F.relu_(F.conv2d(h, w, b, conv.stride, conv.padding, conv.dilation, conv.groups))


class GroupedExtractors(nn.Module):
    """Every device's global and local extractor F^j_glb, F^j_loc (eqs. 1–2) as one stack of
    grouped convolutions: group g = device·branches + branch has its own weights, exactly as if
    each extractor were a separate network.

    Tensors are (B, groups·C, H, T) in channels-last memory, so a temporal convolution is one
    oneDNN call over all extractors. H is the sensor rows: with the paper's extractor each of
    the six IMU axes is a row (the first block reads one input channel per device, kernels
    (1, k) slide over time on every row, max-pool also along the rows by ``sensor_pools``);
    with the mixed one H = 1 and the six axes are the first block's input channels. The first
    block has one group per device and writes all of the device's branches, since they read the
    same input X^j. At inference the batch norm is folded into the convolution, ReLU is fused
    into it and max-pool follows (ReLU and max commute). ``separate = True`` runs the plain
    reading instead, one Conv2d/BatchNorm/ReLU/MaxPool2d stack per extractor in a Python loop,
    from the same parameters (inference only; tests compare the two, the benchmark times both).
    ``fused = False`` keeps the folded batch norm but runs plain ``F.conv2d`` + ReLU over the
    whole batch at once: no CPU-only kernel and no chunking that depends on the batch size, so
    TorchScript tracing and ONNX export (:meth:`SuiteIN.for_export`) see one graph for any batch.
    """

    def __init__(self, cfg: SuiteINConfig):
        super().__init__()
        D, nb = cfg.n_devices, cfg.branches
        self.groups, self.devices, self.branches = D * nb, D, nb
        self.paper = cfg.extractor == "paper"
        self.pools, self.row_pools, self.p = cfg.pools, cfg.row_pools, cfg.dropout
        self.separate = False
        self.fused = True
        self.chunk = 64  # windows per inference pass through the blocks
        self.convs = nn.ModuleList()
        self.norms = nn.ModuleList()
        self.c_first = c_in = 1 if self.paper else IMU_CHANNELS
        for i, (c, k) in enumerate(zip(cfg.widths, cfg.kernels)):
            g = D if i == 0 else D * nb
            self.convs.append(nn.Conv2d(g * c_in, D * nb * c, (1, k), padding=(0, k // 2 if i == 0 else 0), groups=g))
            self.norms.append(MaskedBatchNorm(D * nb, c))
            c_in = c
        self.rows = cfg.sensor_rows
        self.out_channels = c_in * self.rows  # per extractor, rows flattened into channels

    @property
    def _convs(self) -> Sequence[nn.Conv2d]:
        """``convs``, typed (an nn.ModuleList's items are typed nn.Module)."""
        return cast("Sequence[nn.Conv2d]", self.convs)

    @property
    def _norms(self) -> Sequence[MaskedBatchNorm]:
        """``norms``, typed."""
        return cast("Sequence[MaskedBatchNorm]", self.norms)

    def _inputs(self, x: Tensor) -> Tensor:
        """x (B, D, L, 6) → (B, D·c_first, H, L) in channels-last memory."""
        B, D, L, _ = x.shape
        if self.paper:  # (B, D, 6, L), memory order (B, 6, L, D)
            return x.permute(0, 3, 2, 1).contiguous().permute(0, 3, 1, 2)
        return x.permute(0, 2, 1, 3).reshape(B, 1, L, D * IMU_CHANNELS).permute(0, 3, 1, 2)

    def _features(self, h: Tensor) -> Tensor:
        """(B, G·C, H', T') → (B, 1, T', G·C·H'), group g's C·H' features contiguous."""
        B, _, H, T = h.shape
        if H == 1:
            return h.permute(0, 2, 3, 1)
        return h.reshape(B, self.groups, -1, H, T).permute(0, 4, 1, 2, 3).reshape(B, 1, T, -1)

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        """x (B, D, L, 6), mask (B, D) → features (B, 1, T', groups·C·H'), the features of group
        g in g·C·H' … (g+1)·C·H' − 1."""
        if self.paper and not self.separate and all(r == 1 for r in self.row_pools):
            # Kernels (1, k) never mix rows: each axis row is run as a sample of its own,
            # (B·6, D, 1, L), through the one-row code (the same arithmetic and batch-norm
            # statistics, several times faster than convolutions over 6-row images).
            B, D, L, R = x.shape
            rows = x.permute(0, 3, 2, 1).reshape(B * R, 1, L, D).permute(0, 3, 1, 2)
            h = self._blocks(rows, mask.repeat_interleave(R, dim=0))  # (B·6, 1, T', G·C)
            T = h.shape[2]
            return h.reshape(B, R, T, self.groups, -1).permute(0, 2, 3, 4, 1).reshape(B, 1, T, -1)
        return self._blocks(self._inputs(x), mask)

    def _blocks(self, h: Tensor, mask: Tensor) -> Tensor:
        """The six blocks on (B, D·c_in, H, L) channels-last input → (B, 1, T', groups·C·H')."""
        if self.training:
            group_mask = mask.repeat_interleave(self.branches, dim=1)
            for conv, norm, pool, rows in zip(self._convs, self._norms, self.pools, self.row_pools):
                h = norm(conv(h), group_mask)
                if pool > 1 or rows > 1:  # F.max_pool2d: its backward is 2× faster than max_pool_time's
                    h = F.max_pool2d(h, (rows, pool))
                h = F.dropout(F.relu(h), self.p, True)
            return self._features(h)
        if self.separate:
            return self._features(self._separate(h))
        folded = []
        for conv, norm in zip(self._convs, self._norms):
            assert conv.bias is not None  # built with bias=True
            scale, shift = norm.scale_shift()
            folded.append((conv.weight * scale.view(-1, 1, 1, 1), conv.bias * scale + shift))
        # On a CPU a chunk of windows keeps every block's activations in the core's cache; a
        # whole large batch streams them through memory (measured: 1.5× slower at batch 256).
        out = []
        chunks = h.split(self.chunk) if self.fused and h.device.type == "cpu" else (h,)
        for hc in chunks:
            for conv, pool, rows, (w, b) in zip(self._convs, self.pools, self.row_pools, folded):
                hc = max_pool_time(conv_relu(hc, w, b, conv, self.fused), pool, rows)
            out.append(self._features(hc))
        return out[0] if len(out) == 1 else torch.cat(out)

    def _separate(self, h: Tensor) -> Tensor:
        """One extractor at a time (inference, unfused): (B, D·c_first, H, L) → (B, G·C, H', T')."""
        x = h.contiguous()
        outs = []
        for g in range(self.groups):
            dev = g // self.branches
            y = x[:, dev * self.c_first : (dev + 1) * self.c_first]
            for conv, norm, pool, rows_p in zip(self._convs, self._norms, self.pools, self.row_pools):
                assert conv.bias is not None  # built with bias=True
                c = conv.out_channels // self.groups
                rows = slice(g * c, (g + 1) * c)
                y = F.conv2d(y, conv.weight[rows], conv.bias[rows], padding=conv.padding)
                y = F.batch_norm(
                    y,
                    norm.running_mean[rows],
                    norm.running_var[rows],
                    norm.weight[rows],
                    norm.bias[rows],
                    False,
                    0.0,
                    norm.eps,
                )
                y = F.relu(y)
                if pool > 1 or rows_p > 1:
                    y = F.max_pool2d(y, (rows_p, pool))
            outs.append(y)
        return torch.cat(outs, 1)


# --- Separating global and local features (eqs. 3–5) -------------------------------------------


def contrastive_loss(h_glb: Tensor, h_loc: Tensor, mask: Tensor, tau: float) -> Tensor:
    """InfoNCE of eqs. 3–4. h_glb, h_loc (B, D, F); mask (B, D). Positives: global features of
    two present devices; negatives: each present device's global vs its local feature, and the
    local features of two present devices (ordered pairs, as eq. 4 sums them). Summed over
    ordered pairs, averaged over samples; a sample with < 2 devices contributes 0."""
    g, l = F.normalize(h_glb, dim=-1), F.normalize(h_loc, dim=-1)
    D = mask.shape[1]
    off_diag = 1.0 - torch.eye(D, device=mask.device, dtype=mask.dtype)
    pairs = (mask[:, :, None] * mask[:, None, :] * off_diag).bool()  # (B, D, D)
    pos = g @ g.transpose(1, 2) / tau  # s(H_glb^i, H_glb^j)
    # Left-out terms get the most negative finite logit, not −inf: exp() is 0 all the same, and
    # a sample without any device keeps a finite gradient.
    never = torch.finfo(g.dtype).min
    neg_gl = ((g * l).sum(-1) / tau).masked_fill(mask == 0, never)  # (B, D)
    neg_ll = (l @ l.transpose(1, 2) / tau).masked_fill(~pairs, never)  # (B, D, D)
    log_neg = torch.logsumexp(torch.cat([neg_gl, neg_ll.flatten(1)], 1), dim=1)  # (B,)
    log_ratio = pos - torch.logaddexp(pos, log_neg[:, None, None])
    return -(log_ratio * pairs).sum((1, 2)).mean()


def orthogonality_loss(h_glb: Tensor, h_loc: Tensor, mask: Tensor) -> Tensor:
    """Eq. 5 as a cosine embedding loss with target −1, margin 0: Σ_{i≠j} max(0, ⟨l_i, l_j⟩) +
    Σ_j max(0, ⟨g_j, l_j⟩) over present devices, averaged over samples."""
    g, l = F.normalize(h_glb, dim=-1), F.normalize(h_loc, dim=-1)
    D = mask.shape[1]
    off_diag = 1.0 - torch.eye(D, device=mask.device, dtype=mask.dtype)
    pairs = mask[:, :, None] * mask[:, None, :] * off_diag
    ll = (F.relu(l @ l.transpose(1, 2)) * pairs).sum((1, 2))
    gl = (F.relu((g * l).sum(-1)) * mask).sum(1)
    return (ll + gl).mean()


# --- Weighted global fusion (eqs. 9–15) --------------------------------------------------------


def fusion_weights(
    e: Tensor, mask: Tensor, lambda_a: float, lambda_b: float, lambda_c: float, weighted: bool = True
) -> Tensor:
    """α (B, D) of eqs. 11–12 from quality scores e (B, D): the sigmoid rescaling bounded in
    [λ_c, λ_a + λ_c], normalised over the PRESENT devices only; absent devices get 0. With
    ``weighted=False`` the mean over present devices (Suite-IN). Rows without any device are 0."""
    alpha = lambda_a * torch.sigmoid(e / lambda_b) + lambda_c if weighted else torch.ones_like(e)
    alpha = alpha * mask
    return alpha / alpha.sum(1, keepdim=True).clamp(min=torch.finfo(alpha.dtype).tiny)


class WeightedGlobalFusion(nn.Module):
    """Eqs. 9–15: pool each device's global features over time (9), score its quality (10),
    weight (11–12), sum (13), 2-layer GRU (14), linear velocity head (15)."""

    def __init__(self, cfg: SuiteINConfig, channels: int):
        super().__init__()
        self.cfg = cfg
        self.steps = cfg.feature_steps // cfg.glb_pool
        self.quality = nn.Linear(self.steps * channels, 1)  # w_glb, b_glb (shared)
        self.gru = nn.GRU(channels, cfg.gru_hidden, num_layers=2, batch_first=True)
        self.head = nn.Linear(cfg.gru_hidden, 2)  # FC_glb

    def forward(self, h_glb: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        """h_glb (B, T', D, C) → (v_glb (B, 2), α (B, D))."""
        B, T, D, C = h_glb.shape
        p = self.cfg.glb_pool
        u = h_glb[:, : self.steps * p].reshape(B, self.steps, p, D, C).mean(2)  # eq. 9
        flat = u.permute(0, 2, 1, 3).reshape(B, D, self.steps * C)
        e = self.quality(flat).squeeze(-1) / flat.shape[-1]  # eq. 10
        c = self.cfg
        alpha = fusion_weights(e, mask, c.lambda_a, c.lambda_b, c.lambda_c, c.weighted)
        g = torch.einsum("btdc,bd->btc", u, alpha)  # eq. 13
        r, _ = self.gru(g)  # eq. 14
        return self.head(r[:, -1]), alpha  # eq. 15


# --- Attentive local analysis (eqs. 16–20) ----------------------------------------------------


class AttentiveLocalAnalysis(nn.Module):
    """Eqs. 16–20: per-device linear maps of the flattened local features (16–17), multi-head
    self-attention across present devices (18), mean over present devices, ReLU(FC) (19) and the
    local correction velocity (20)."""

    def __init__(self, cfg: SuiteINConfig, channels: int):
        super().__init__()
        D, n_in, d = cfg.n_devices, cfg.feature_steps * channels, cfg.loc_dim
        self.heads = cfg.heads
        self.w_loc = nn.Parameter(torch.empty(D, n_in, d))  # eq. 17, one per device
        self.b_loc = nn.Parameter(torch.zeros(D, d))
        nn.init.uniform_(self.w_loc, -1 / math.sqrt(n_in), 1 / math.sqrt(n_in))
        self.qkv = nn.Linear(d, 3 * d)
        self.out = nn.Linear(d, d)
        self.fc = nn.Linear(d, cfg.loc_hidden)
        self.head = nn.Linear(cfg.loc_hidden, 2)  # FC_loc

    def forward(self, h_loc: Tensor, mask: Tensor) -> Tensor:
        """h_loc (B, D, T'·C) flattened (eq. 16) → v_loc (B, 2)."""
        B, D, n_in = h_loc.shape
        d = torch.baddbmm(self.b_loc[:, None], h_loc.transpose(0, 1), self.w_loc) / n_in  # eq. 17
        d = d.transpose(0, 1)  # D: (B, D, d)
        q, k, v = self.qkv(d).view(B, D, 3, self.heads, -1).permute(2, 0, 3, 1, 4)
        scores = q @ k.transpose(-1, -2) / math.sqrt(q.shape[-1])  # (B, h, D, D)
        keys_absent = (mask == 0)[:, None, None, :]
        scores = scores.masked_fill(keys_absent, torch.finfo(scores.dtype).min)
        att = torch.softmax(scores, -1) @ v  # eq. 18
        d_att = self.out(att.transpose(1, 2).reshape(B, D, -1))
        d_mean = (d_att * mask[..., None]).sum(1) / mask.sum(1, keepdim=True).clamp(min=1)
        return self.head(F.relu(self.fc(d_mean)))  # eqs. 19–20


# --- The model (eqs. 21–25) -------------------------------------------------------------------


class SuiteIN(OdometryModel):
    """Suite-IN++ (all switches on) and its ablations / Suite-IN; see the module docstring."""

    # Training set-up of Sec. V-A, read by the trainer.
    default_lr = 1e-4
    default_batch = 128
    default_window = 100
    default_rate_hz = 25.0

    def __init__(self, cfg: SuiteINConfig = SuiteINConfig()):
        super().__init__()
        self.cfg = cfg
        self.extractors = GroupedExtractors(cfg)
        C = self.extractors.out_channels
        self.fusion = WeightedGlobalFusion(cfg, C)
        self.local = AttentiveLocalAnalysis(cfg, C) if cfg.attentive else None
        if cfg.attentive:
            self.combine = nn.Linear(4, 2)  # eq. 21
            with torch.no_grad():  # starts as v_glb + v_loc: v_loc corrects v_glb (eq. 22)
                self.combine.weight.copy_(torch.cat([torch.eye(2), torch.eye(2)], 1))
                self.combine.bias.zero_()
        self.to(memory_format=torch.channels_last)  # type: ignore[call-overload]  # Module.to takes it (torch's docs); its stub omits it

    def features(self, x: Tensor, mask: Tensor) -> tuple[Tensor, Tensor | None]:
        """Global and local features H (B, T', D, C) (eqs. 1–2); local is None for one branch."""
        if x.ndim != 4 or x.shape[1] != self.cfg.n_devices or x.shape[3] != IMU_CHANNELS:
            raise ConfigError(f"suitein: expected x (B, {self.cfg.n_devices}, L, 6), got {tuple(x.shape)}")
        h = self.extractors(x, mask.to(x.dtype))  # (B, 1, T', D·nb·C)
        B, _, T, _ = h.shape
        h = h.reshape(B, T, self.cfg.n_devices, self.cfg.branches, -1)
        return h[:, :, :, 0], (h[:, :, :, 1] if self.cfg.branches == 2 else None)

    def parts(self, x: Tensor, mask: Tensor) -> dict[str, Tensor]:
        """Every intermediate the losses need: v, v_glb, v_loc, α, flattened H_glb/H_loc."""
        mask = mask.to(x.dtype)
        h_glb, h_loc = self.features(x, mask)
        v_glb, alpha = self.fusion(h_glb, mask)
        out = {"v_glb": v_glb, "alpha": alpha, "v": v_glb}
        flat = lambda h: h.permute(0, 2, 1, 3).flatten(2)  # (B, D, T'·C)
        if h_loc is not None:
            out["h_glb"], out["h_loc"] = flat(h_glb), flat(h_loc)
        if self.local is not None:
            out["v_loc"] = self.local(out["h_loc"], mask)
            out["v"] = self.combine(torch.cat([v_glb, out["v_loc"]], 1))
        return out

    def forward(self, x: Tensor, mask: Tensor) -> Tensor:
        return self.parts(x, mask)["v"]

    def for_export(self) -> SuiteIN:
        """A copy without the fused CPU kernels and batch chunking (:class:`GroupedExtractors`'
        ``fused``), in eval mode: the same arithmetic as one graph for any batch size."""
        model = copy.deepcopy(self).eval()
        model.extractors.fused = False
        return model

    def loss(self, batch: dict[str, Tensor]) -> tuple[Tensor, dict[str, Tensor]]:
        """Eq. 25: λ_v·L_vel (23) + λ_v^glb·L_vel^glb (7) + λ_v^loc·L_vel^loc (22) + λ_c·L_con (3)
        + λ_o·L_orth (5), with the terms of switched-off modules left out; the last two × the
        trainer's ``aux_scale`` (1 in the paper's recipe; ramped in by the "fast" recipe)."""
        c = self.cfg
        x, mask, vel = batch["x"], batch["mask"].to(batch["x"].dtype), batch["vel"]
        p = self.parts(x, mask)
        named = {"vel": velocity_loss(p["v"], vel, self.vel_loss)}
        total = c.w_vel * named["vel"]
        if self.local is not None:
            named["vel_glb"] = velocity_loss(p["v_glb"], vel, self.vel_loss)
            # the local branch corrects v_glb (eq. 22): a residual, small and of any direction, so
            # its own term stays a squared error whichever loss the velocity takes
            named["vel_loc"] = F.mse_loss(p["v_loc"], vel - p["v_glb"].detach())
            total = total + c.w_vel_glb * named["vel_glb"] + c.w_vel_loc * named["vel_loc"]
        if c.contrast:
            named["con"] = contrastive_loss(p["h_glb"], p["h_loc"], mask, c.tau)
            named["orth"] = orthogonality_loss(p["h_glb"], p["h_loc"], mask)
            total = total + self.aux_scale * (c.w_con * named["con"] + c.w_orth * named["orth"])
        return total, named


# --- Registered constructors ------------------------------------------------------------------


def _build(n_devices: int = 3, window: int = 100, **overrides) -> SuiteIN:
    unknown = set(overrides) - set(SuiteINConfig.__dataclass_fields__)
    if unknown:
        raise TypeError(f"unknown hyper-parameter(s) {', '.join(sorted(unknown))}")
    return SuiteIN(replace(SuiteINConfig(), n_devices=n_devices, window=window, **overrides))


@register(
    "suitein++",
    task="odometry",
    layout="multi",
    description="Suite-IN++: contrastive global/local features, weighted global fusion, "
    "attentive local analysis (paper 000)",
)
def suitein_pp(n_devices: int = 3, window: int = 100, **kw) -> SuiteIN:
    return _build(n_devices, window, **{"contrast": True, "weighted": True, "attentive": True, **kw})


# Suite-IN's own size (Table VI: 104.3 K parameters, 0.026 G MACs): no attentive local analysis
# to hold parameters, so wider middle blocks and a narrower last one and GRU.
SUITEIN_SIZE: dict[str, object] = dict(extractor="paper", widths=(24, 32, 36, 36, 24, 16), gru_hidden=56)
# Suite-IN++ with the paper's row-keeping extractor at the paper's size (498.9 K, 21.0 M MACs).
ROWS_SIZE: dict[str, object] = dict(extractor="paper", widths=(16, 24, 32, 32, 32, 28))


@register(
    "suitein",
    task="odometry",
    layout="multi",
    description="Suite-IN: contrastive global/local features, mean fusion of global features",
)
def suitein(n_devices: int = 3, window: int = 100, **kw) -> SuiteIN:
    return _build(n_devices, window, **{"contrast": True, "weighted": False, "attentive": False, **SUITEIN_SIZE, **kw})


# The paper's row-keeping reading of the extractor at the paper's size (module docstring), by name
# so a suite or the CLI can run it (``model_args=ROWS_SIZE`` builds the same).
@register(
    "suitein++-rows",
    task="odometry",
    layout="multi",
    description="Suite-IN++ with the paper's row-keeping extractor (each IMU axis its own row; ~10x the "
    "training time on a CPU)",
)
def suitein_pp_rows(n_devices: int = 3, window: int = 100, **kw) -> SuiteIN:
    return suitein_pp(n_devices, window, **{**ROWS_SIZE, **kw})


# Table V ablations (1)–(5); (6) is suitein++.
ABLATIONS: dict[int, dict[str, bool]] = {
    1: dict(contrast=False, weighted=False, attentive=False),
    2: dict(contrast=False, weighted=True, attentive=False),
    3: dict(contrast=True, weighted=False, attentive=True),
    4: dict(contrast=False, weighted=True, attentive=True),
    5: dict(contrast=True, weighted=True, attentive=False),
    6: dict(contrast=True, weighted=True, attentive=True),
}


def _register_ablation(number: int, switches: dict[str, bool]) -> None:
    on = [
        name
        for name, key in (("Contrast.FE", "contrast"), ("Weighted.GF", "weighted"), ("Attentive.LA", "attentive"))
        if switches[key]
    ]

    def build(n_devices: int = 3, window: int = 100, **kw) -> SuiteIN:
        return _build(n_devices, window, **{**switches, **kw})

    register(
        f"suitein++-abl{number}",
        task="odometry",
        layout="multi",
        description=f"Suite-IN++ ablation ({number}) of Table V: {' + '.join(on) or 'no module'}",
    )(build)


for _n, _sw in ABLATIONS.items():
    if _n != 6:
        _register_ablation(_n, _sw)
