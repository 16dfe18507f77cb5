"""Rotation helpers on stacks of 3×3 matrices (…, 3, 3), vectorised over time.

Conventions: a rotation matrix maps segment/device-frame vectors into the world frame (z up);
``rot_x/rot_y/rot_z(a)`` are right-handed rotations by angle ``a`` (rad) about that axis.
For a segment hanging down, ``rot_y(-a)`` swings its lower end *forward* (+x) by ``a``.
Quaternions (what a device reports) are :mod:`wearnav.core.rotations`' business, as everywhere else.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from wearnav.core.rotations import yaw_matrix


def _rot(a, i: int, j: int) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    k = 3 - i - j
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def rot_x(a) -> np.ndarray:
    return _rot(a, 1, 2)


def rot_y(a) -> np.ndarray:
    return _rot(a, 2, 0)


def rot_z(a) -> np.ndarray:
    return yaw_matrix(a)  # a yaw: wearnav's one definition


def apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R @ v for stacks (broadcasting over leading axes); v (…, 3)."""
    return np.einsum("...ij,...j->...i", R, v)


def apply_t(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rᵀ @ v (world → segment frame)."""
    return np.einsum("...ji,...j->...i", R, v)


def exp_so3(rotvec: np.ndarray) -> np.ndarray:
    rv = np.asarray(rotvec, dtype=np.float64)
    return Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(rv.shape[:-1] + (3, 3))


def log_so3(R: np.ndarray) -> np.ndarray:
    R = np.asarray(R, dtype=np.float64)
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec().reshape(R.shape[:-2] + (3,))


def angle_between(RA: np.ndarray, RB: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad) between rotation stacks."""
    tr = np.einsum("...ji,...ji->...", RA, RB)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))


def from_axes(x, y, z) -> np.ndarray:
    """The matrix whose columns are the given frame axes (expressed in the parent frame)."""
    R = np.stack([np.asarray(x, float), np.asarray(y, float), np.asarray(z, float)], axis=-1)
    if not np.allclose(np.linalg.det(R), 1.0):
        raise ValueError("axes do not form a right-handed orthonormal frame")
    return R


def random_rotation(rng: np.random.Generator, max_deg: float | None = None) -> np.ndarray:
    """A fixed random rotation: uniform on SO(3), or about a random axis by ≤ ``max_deg``."""
    if max_deg is None:
        q = rng.standard_normal(4)  # a normalised Gaussian 4-vector: uniform, in any component order
        return Rotation.from_quat(q / np.linalg.norm(q)).as_matrix()
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    return exp_so3(axis * np.deg2rad(rng.uniform(0, max_deg)))


def blend_rotations(RA: np.ndarray, RB: np.ndarray, w: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Smoothly move from the (moving) rotation RA to the (moving) rotation RB as w goes 0 → 1.

    ``delta`` is the fixed rotation vector log(RAᵀRB) taken at one reference instant; the small
    time-varying residual is blended on top. Unlike a per-sample slerp this never flips branch
    when the relative angle passes π, so the result stays smooth (its derivatives exist).
    """
    w = np.asarray(w)[..., None]
    E = exp_so3(-np.broadcast_to(delta, RA.shape[:-2] + (3,)))
    resid = log_so3(E @ np.swapaxes(RA, -1, -2) @ RB)
    return RA @ exp_so3(w * delta) @ exp_so3(w * resid)
