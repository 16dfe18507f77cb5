"""Batch augmentations on tensors (the one registry: name → function).

Every augmentation takes a collated batch (the dict :class:`wearnav.preprocess.windows.WindowDataset`
yields, stacked: ``x`` (B, D, L, 6) world-frame acc xyz + gyro xyz, ``mask`` (B, D), ``vel`` and
``disp`` (B, 2), ...) and a ``torch.Generator``, and returns a new batch dict; the input is not
modified. Seeding the generator makes an augmentation reproducible.

``rotate_yaw``: heading equivariance as in RoNIN (Herath et al., ICRA 2020), which trains with a
random rotation of input and target about the vertical. A walker's motion looks the same whatever direction
they walk in, so the horizontal channels of every device and the horizontal targets are rotated
together about the vertical by one random angle per sample; vertical channels and speeds are
unchanged.

Decision: docs/decisions/0029-heading-frame.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch

from wearnav.core.rotations import rotate_about_vertical
from wearnav.errors import ConfigError

Batch = dict[str, torch.Tensor]
Augmentation = Callable[[Batch, torch.Generator], Batch]

AUGMENTATIONS: dict[str, Augmentation] = {}

TARGETS_2D = ("vel", "disp")


def register(name: str) -> Callable[[Augmentation], Augmentation]:
    def deco(fn: Augmentation) -> Augmentation:
        if name in AUGMENTATIONS:
            raise ConfigError(f"augmentation {name!r} is registered twice")
        AUGMENTATIONS[name] = fn
        return fn

    return deco


def get(name: str) -> Augmentation:
    if name not in AUGMENTATIONS:
        raise ConfigError(f"unknown augmentation {name!r} (expected one of {', '.join(sorted(AUGMENTATIONS))})")
    return AUGMENTATIONS[name]


def apply(names, batch: Batch, generator: torch.Generator) -> Batch:
    """Apply the named augmentations in order."""
    for name in names:
        batch = get(name)(batch, generator)
    return batch


def rotate_batch(batch: Batch, angle: torch.Tensor) -> Batch:
    """The batch with inputs and 2-D targets rotated about the vertical by ``angle`` (B,) rad
    (v' = Rz(angle) v, counter-clockwise seen from above; :mod:`wearnav.core.rotations`)."""
    out = dict(batch)
    x = batch["x"]
    yaw = angle.to(x.dtype).view(-1, *([1] * (x.dim() - 1)))  # (B, 1, 1, 1): one angle per sample
    # (B, D, L, 6) as (B, D, L, 2, 3): acc and gyro 3-vectors, each rotated about z
    out["x"] = rotate_about_vertical(x.reshape(*x.shape[:-1], -1, 3), yaw).reshape(x.shape)
    for key in TARGETS_2D:
        if key in batch:
            v = batch[key]
            v3 = torch.cat([v, torch.zeros_like(v[..., :1])], dim=-1)
            out[key] = rotate_about_vertical(v3, angle.to(v.dtype).view(-1, *([1] * (v.dim() - 2))))[..., :2]
    return out


@register("rotate_yaw")
def rotate_yaw(batch: Batch, generator: torch.Generator) -> Batch:
    """One uniform random angle in [0, 2π) per sample (see module docstring)."""
    b = batch["x"].shape[0]
    angle = torch.rand(b, generator=generator, dtype=torch.float64, device=generator.device) * (2 * math.pi)
    return rotate_batch(batch, angle.to(batch["x"].device))


# The odometry models' speed comes largely from how hard the device moves; a phone held flat and
# still in front (ILC2) moves less than the simulator's hands or IPIN's, at the same walking
# speed, and a model trained without ILC2 made its paths 31 % short there (length ratio 0.69,
# PDR's step counting 0.93: `wearnav pretrain`'s leave-one-building-out runs).
MOTION_SCALE = (0.6, 1.6)  # log-uniform range of ``scale_motion``'s factor


@register("scale_motion")
def scale_motion(batch: Batch, generator: torch.Generator) -> Batch:
    """The motion within each window scaled by one random factor per sample (log-uniform in
    :data:`MOTION_SCALE`), the targets kept: every channel of every device becomes its window mean
    (gravity, a steady turn) plus the factor times its deviation from it, so that a gentler or a
    stronger way of carrying the device at the same speed is seen in training."""
    x = batch["x"]
    lo, hi = (math.log(v) for v in MOTION_SCALE)
    u = torch.rand(x.shape[0], generator=generator, dtype=torch.float64, device=generator.device)
    s = torch.exp(lo + (hi - lo) * u).to(device=x.device, dtype=x.dtype).view(-1, 1, 1, 1)
    mean = x.mean(dim=2, keepdim=True)
    return {**batch, "x": mean + s * (x - mean)}


# A model of several devices trained on the simulator, where every walk carries them all, meets
# the phone alone on real walks (issue 34): Suite-IN++ masks an absent device (its fusion weighs
# the present ones), but it only learns to do without one where training shows it.
DROP_DEVICE_P = 0.5  # ``drop_devices``: the chance that each present device is left out of a sample


@register("drop_devices")
def drop_devices(batch: Batch, generator: torch.Generator) -> Batch:
    """Each present device of each sample absent with probability :data:`DROP_DEVICE_P`,
    independently; a sample that would lose every device keeps them all. A dropped device's
    inputs become zeros and its mask 0, as an absent device's are; the targets are kept (the walk
    is the same)."""
    mask = batch["mask"]
    u = torch.rand(mask.shape, generator=generator, dtype=torch.float64, device=generator.device)
    keep = (u.to(mask.device) >= DROP_DEVICE_P).to(mask.dtype) * mask
    none_left = keep.sum(dim=1) == 0
    keep[none_left] = mask[none_left]
    return leave_out(batch, keep)


def leave_out(batch: Batch, keep: torch.Tensor) -> Batch:
    """The batch with only the devices ``keep`` (B, D; 1 kept, 0 left out) says: a left-out
    device's inputs zeros and its mask 0. A heading-frame batch (``yaw``, and each device's own in
    ``yaws``) whose carrier is left out is turned into the frame of the first kept device with a
    heading, as :func:`wearnav.preprocess.align` would have framed the window without the others."""
    x = batch["x"] * keep[:, :, None, None].to(batch["x"].dtype)
    out = {**batch, "mask": keep, "x": x}
    if "yaws" not in batch:
        return out
    yaws = batch["yaws"]
    has = torch.isfinite(yaws)
    carrier = _first(has & (batch["mask"] > 0))
    first_kept = _first(has & (keep > 0))
    new = yaws.gather(1, first_kept.clamp(min=0)[:, None])[:, 0]
    change = (first_kept >= 0) & (first_kept != carrier)
    delta = torch.where(change, new - batch["yaw"], torch.zeros_like(new))
    out = rotate_batch(out, -delta.double())  # from the old carrier's frame into the new one's
    out["yaw"] = torch.where(change, new, batch["yaw"])
    return out


def _first(rows: torch.Tensor) -> torch.Tensor:
    """Index of each row's first True (−1 where none)."""
    idx = torch.argmax(rows.to(torch.int8), dim=1)
    return torch.where(rows.any(dim=1), idx, torch.full_like(idx, -1))


# ---- the HAR benchmark's techniques (paper 002, Sec. II-B) --------------------------------------
#
# Two kinds: *expansions* add fixed transformed copies of the training windows to the training
# set, as the paper does (rotation eqs. 9–11, "all axes", additive noise eq. 12); the moving
# average (eq. 13) is preprocessing applied to train and test sequences alike; ``rotate_random``
# is a batch augmentation (a fresh draw every batch), registered above with ``rotate_yaw``.

PAPER_ANGLE = math.pi / 6


def axis_rotation(axis: str, angle: float = PAPER_ANGLE) -> torch.Tensor:
    """The paper's transformation matrix T (eq. 8) about ``axis`` "x" (eq. 9), "y" (eq. 10) or
    "z" (eq. 11), float64 (3, 3). x̃ = T·x, with T as printed in the paper."""
    c, s = math.cos(angle), math.sin(angle)
    mats = {
        "x": [[1, 0, 0], [0, c, s], [0, -s, c]],
        "y": [[c, 0, -s], [0, 1, 0], [s, 0, c]],
        "z": [[c, s, 0], [-s, c, 0], [0, 0, 1]],
    }
    if axis not in mats:
        raise ConfigError(f"rotation axis must be x, y or z, got {axis!r}")
    return torch.tensor(mats[axis], dtype=torch.float64)


def rotate_imu(x: torch.Tensor, T: torch.Tensor) -> torch.Tensor:
    """x (..., 6) acc xyz + gyro xyz with both 3-vectors mapped by T (eq. 8): x̃ = T·x."""
    v = x.reshape(*x.shape[:-1], 2, 3)
    return (v @ T.to(x.dtype).T).reshape(x.shape)


def noise_sigma(x: torch.Tensor, fraction: float = 0.1) -> tuple[float, float]:
    """Eq. 12's σ for one dataset, from its *training* windows x (N, D, L, 6) and mask (N, D):
    ``fraction`` × the standard deviation of the accelerometer (resp. gyroscope) samples pooled
    over axes, devices and windows. One σ for acc (m/s²) and one for gyro (rad/s) because the
    two have different units; a gyroscope that is absent (all zeros) gets σ = 0."""
    acc, gyro = x[..., :3], x[..., 3:]
    s_gyro = float(gyro.std()) if bool(gyro.abs().sum() > 0) else 0.0
    return fraction * float(acc.std()), fraction * s_gyro


def add_noise(x: torch.Tensor, sigma: tuple[float, float], generator: torch.Generator) -> torch.Tensor:
    """Eq. 12: x̃ = x + N(0, σ²), σ = sigma[0] on acc channels and sigma[1] on gyro channels."""
    scale = torch.tensor([sigma[0]] * 3 + [sigma[1]] * 3, dtype=x.dtype)
    return x + torch.randn(x.shape, generator=generator, dtype=x.dtype) * scale


EXPANSIONS = ("rot_x", "rot_y", "rot_z", "rot_all", "noise")


def expansion_copies(name: str) -> list[str]:
    """The transformed copies an expansion adds: "rot_all" is the paper's three extra datasets."""
    if name not in EXPANSIONS:
        raise ConfigError(f"unknown training-set expansion {name!r} (expected one of {', '.join(EXPANSIONS)})")
    return ["rot_x", "rot_y", "rot_z"] if name == "rot_all" else [name]


class ExpandedWindows(torch.utils.data.Dataset):
    """A window dataset plus fixed transformed copies of every window (the paper's "adding the
    new generated data to the existing training set"): item k < N is window k unchanged, item
    c·N + k is window k through copy c. A noise copy's noise is a function of (seed, copy,
    window), so the added data are the same every epoch, as data generated once would be.

    ``base`` is a :class:`wearnav.preprocess.windows.WindowDataset` (batched fetching: ``base[list]``).
    """

    def __init__(self, base, copies: list[str], sigma: tuple[float, float] = (0.0, 0.0), seed: int = 0):
        self.base, self.copies, self.sigma, self.seed = base, list(copies), sigma, seed
        for c in self.copies:
            if c not in ("rot_x", "rot_y", "rot_z", "noise"):
                raise ConfigError(f"unknown copy {c!r}")

    def __len__(self) -> int:
        return len(self.base) * (1 + len(self.copies))

    def _transform(self, copy: str, x: torch.Tensor, windows: np.ndarray, ci: int) -> torch.Tensor:
        if copy.startswith("rot_"):
            return rotate_imu(x, axis_rotation(copy[-1]))
        out = torch.empty_like(x)
        g = torch.Generator()
        for j, w in enumerate(windows):
            g.manual_seed(self.seed * 1_000_003 + ci * 10_000_019 + int(w))
            out[j] = add_noise(x[j], self.sigma, g)
        return out

    def __getitem__(self, k) -> dict:
        k = np.atleast_1d(np.asarray(k, np.int64))
        n = len(self.base)
        copy, win = k // n, k % n
        batch = self.base[win.tolist()]
        x = batch["x"].clone()
        for ci, name in enumerate(self.copies, 1):
            sel = np.flatnonzero(copy == ci)
            if sel.size:
                x[sel] = self._transform(name, x[sel], win[sel], ci)
        x = x * batch["mask"][:, :, None, None]  # an absent device stays zeros (no noise on it)
        return {**batch, "x": x}

    def loader(self, batch: int, shuffle_seed: int | None = None):
        from torch.utils.data import DataLoader

        from wearnav.preprocess.windows import BatchSampler

        return DataLoader(
            self,
            batch_size=None,
            sampler=BatchSampler(len(self), batch, shuffle_seed),
            num_workers=0,
            generator=torch.Generator(),
        )


def moving_average(x: np.ndarray, n: int, axis: int = 0) -> np.ndarray:
    """Eq. 13, the forward moving average x̃_t = (1/n) Σ_{i=0}^{n−1} x_{t+i} along ``axis``.

    Where fewer than n samples remain (the last n − 1 samples of a sequence) the mean runs over
    the samples that exist, so the output keeps the input's length. Preprocessing: applied to
    training and test sequences alike (:mod:`wearnav.train.classify`).
    """
    if n < 1:
        raise ConfigError(f"moving-average window must be ≥ 1 sample, got {n}")
    x = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    T = x.shape[0]
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)], axis=0)
    start = np.arange(T)
    end = np.minimum(start + n, T)
    shape = (T,) + (1,) * (x.ndim - 1)
    out = (c[end] - c[start]) / (end - start).reshape(shape)
    return np.moveaxis(out, 0, axis)


def random_rotation_matrices(n: int, generator: torch.Generator) -> torch.Tensor:
    """n rotation matrices (n, 3, 3) uniform on SO(3) (normalised Gaussian quaternions)."""
    q = torch.randn(n, 4, generator=generator, dtype=torch.float64)
    q = q / q.norm(dim=1, keepdim=True)
    w, x, y, z = q.unbind(1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        dim=1,
    ).reshape(n, 3, 3)


@register("rotate_random")
def rotate_random(batch: Batch, generator: torch.Generator) -> Batch:
    """Beyond the paper (an extra row of the HAR benchmark): every device of every window is
    rotated by its own uniform random rotation, acc and gyro alike, a fresh draw each batch.
    For device-frame input (the classification default): how the device sits in a pocket or on a
    wrist is unknown, so its frame is treated as arbitrary."""
    x = batch["x"]
    B, D = x.shape[:2]
    R = random_rotation_matrices(B * D, generator).to(x.dtype).reshape(B, D, 1, 1, 3, 3)
    v = x.reshape(B, D, x.shape[2], 2, 3, 1)
    return {**batch, "x": (R @ v).reshape(x.shape)}
