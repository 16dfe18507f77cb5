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
from wearnav.rotations import rotate_about_vertical

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
    (v' = Rz(angle) v, counter-clockwise seen from above; :mod:`wearnav.rotations`)."""
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
