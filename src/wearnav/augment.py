"""Batch augmentations on tensors (the one registry: name → function).

Every augmentation takes a collated batch (the dict :class:`wearnav.windows.WindowDataset`
yields, stacked: ``x`` (B, D, L, 6) world-frame acc xyz + gyro xyz, ``mask`` (B, D), ``vel`` and
``disp`` (B, 2), ...) and a ``torch.Generator``, and returns a new batch dict; the input is not
modified. Seeding the generator makes an augmentation reproducible.

``rotate_yaw``: heading equivariance as in RoNIN (Herath et al., ICRA 2020), which trains with a
random rotation of input and target about the vertical. A walker's motion looks the same whatever direction
they walk in, so the horizontal channels of every device and the horizontal targets are rotated
together about the vertical by one random angle per sample; vertical channels and speeds are
unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from wearnav.errors import ConfigError

Batch = dict[str, torch.Tensor]
Augmentation = Callable[[Batch, torch.Generator], Batch]

AUGMENTATIONS: dict[str, Augmentation] = {}

# (x, y) channel pairs of the 6 IMU channels that rotate about the vertical: acc xy, gyro xy
HORIZONTAL_PAIRS = ((0, 1), (3, 4))
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


def rotate_xy(v: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
    """Rotate the last axis (x, y) of ``v`` (B, ..., 2) by angles given per sample as cos/sin (B,)."""
    shape = (-1,) + (1,) * (v.dim() - 2)
    c, s = cos.view(shape).to(v.dtype), sin.view(shape).to(v.dtype)
    x, y = v[..., 0], v[..., 1]
    return torch.stack([c * x - s * y, s * x + c * y], dim=-1)


def rotate_batch(batch: Batch, angle: torch.Tensor) -> Batch:
    """The batch with inputs and 2-D targets rotated about the vertical by ``angle`` (B,) rad
    (v' = Rz(angle) v, counter-clockwise seen from above)."""
    out = dict(batch)
    cos, sin = torch.cos(angle), torch.sin(angle)
    x = batch["x"].clone()
    for i, j in HORIZONTAL_PAIRS:
        x[..., [i, j]] = rotate_xy(batch["x"][..., [i, j]], cos, sin)
    out["x"] = x
    for key in TARGETS_2D:
        if key in batch:
            out[key] = rotate_xy(batch[key], cos, sin)
    return out


@register("rotate_yaw")
def rotate_yaw(batch: Batch, generator: torch.Generator) -> Batch:
    """One uniform random angle in [0, 2π) per sample (see module docstring)."""
    b = batch["x"].shape[0]
    angle = torch.rand(b, generator=generator, dtype=torch.float64, device=generator.device) * (2 * math.pi)
    return rotate_batch(batch, angle.to(batch["x"].device))
