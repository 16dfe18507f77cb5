"""Quaternion and rotation conventions of wearnav (the only place they are written down).

wearnav stores orientation as unit quaternions **(w, x, y, z), scalar first**, rotating
device-frame vectors into the world frame (**world←device**): ``v_world = R(q) v_device``. The
world frame is z up, gravity aligned, with an arbitrary but fixed yaw (the "game rotation vector"
convention). Everything else in the package converts through these functions, which are thin
wrappers over :class:`scipy.spatial.transform.Rotation` (that class stores x, y, z, w by default;
the wrappers make the order explicit so no caller reorders columns by hand).

Sources this module translates, and the function each uses:

* Android rotation vector (ILC2, IPIN AHRS): x, y, z[, w] = sin(θ/2)·axis, cos(θ/2) →
  :func:`from_android_rotation_vector` (w rebuilt as ``sqrt(max(0, 1 − |xyz|²))`` when absent,
  as ``SensorManager.getQuaternionFromVector`` does).
* Core Motion / Sensor Logger Euler angles, Tait–Bryan intrinsic z-x'-y'' (yaw, then pitch about
  the new x, then roll about the newest y): R = Rz(yaw)·Rx(pitch)·Ry(roll) →
  :func:`from_euler` with ``"ZXY"`` (scipy's upper-case sequences are intrinsic).
* Rotation matrices (the simulator) → :func:`from_matrix` / :func:`as_matrix`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from wearnav.errors import ValidationError

# |q| of a stored or imported quaternion may differ from 1 by float rounding and logging
# precision only; beyond this it is not a rotation at all.
UNIT_NORM_TOL = 0.05


class NotUnitQuaternion(ValidationError):
    """A quaternion whose norm is not 1 within :data:`UNIT_NORM_TOL`; ``row`` and ``norm`` say
    which (importers reword it with their own line numbering)."""

    def __init__(self, row: int, norm: float):
        self.row, self.norm = row, norm
        super().__init__(f"row {row} is not a unit quaternion (|q| = {norm:.3g})")


# ---- quaternions (w, x, y, z) <-> Rotation ------------------------------------------------


def from_wxyz(q) -> Rotation:
    """Rotation(s) from (…, 4) quaternions w, x, y, z (normalised by scipy)."""
    q = np.asarray(q, dtype=np.float64)
    return Rotation.from_quat(q.reshape(-1, 4) if q.ndim > 2 else q, scalar_first=True)


def to_wxyz(rot: Rotation, continuous: bool = False) -> np.ndarray:
    """(N, 4) or (4,) quaternions w, x, y, z of ``rot``.

    ``continuous``: flip signs so that consecutive quaternions have a non-negative dot product
    and the first has w ≥ 0 (q and −q are the same rotation; a smooth sequence interpolates and
    differentiates without jumps).
    """
    q = rot.as_quat(scalar_first=True)
    return sign_continuous(q, first_w_positive=True) if continuous and q.ndim == 2 else q


def sign_continuous(q: np.ndarray, first_w_positive: bool = False) -> np.ndarray:
    """(N, 4) quaternions with signs flipped so that consecutive ones point the same way."""
    q = np.asarray(q, dtype=np.float64)
    if len(q) > 1:
        flip = np.einsum("ij,ij->i", q[1:], q[:-1]) < 0
        q = q * np.concatenate([[1.0], np.cumprod(np.where(flip, -1.0, 1.0))])[:, None]
    if first_w_positive and len(q) and q[0, 0] < 0:
        q = -q
    return q


def normalize_wxyz(q, tol: float = UNIT_NORM_TOL) -> np.ndarray:
    """(N, 4) unit quaternions q / |q|; :class:`NotUnitQuaternion` for the first row whose norm
    is off by more than ``tol`` (such a row was never a rotation: wrong columns or units)."""
    q = np.asarray(q, dtype=np.float64)
    norm = np.linalg.norm(q, axis=1)
    bad = np.abs(norm - 1.0) > tol
    if np.any(bad):
        i = int(np.argmax(bad))
        raise NotUnitQuaternion(i, float(norm[i]))
    return q / norm[:, None]


def from_matrix(R) -> Rotation:
    """Rotation(s) from (N, 3, 3) or (3, 3) matrices whose columns are the device axes in the world."""
    return Rotation.from_matrix(np.asarray(R, dtype=np.float64))


def as_matrix(q) -> np.ndarray:
    """(…, 3, 3) rotation matrices of (…, 4) quaternions w, x, y, z."""
    q = np.asarray(q, dtype=np.float64)
    return from_wxyz(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))


def matrix_to_wxyz(R) -> np.ndarray:
    """(N, 3, 3) matrices → (N, 4) quaternions w, x, y, z, sign-continuous along the sequence."""
    R = np.asarray(R, dtype=np.float64)
    return to_wxyz(from_matrix(R.reshape(-1, 3, 3)), continuous=True)


# ---- the sources' conventions -------------------------------------------------------------


def from_android_rotation_vector(v) -> np.ndarray:
    """Android rotation-vector values (N, 3) x, y, z or (N, ≥4) x, y, z, w → (N, 4) w, x, y, z,
    not normalised (so that the caller can check the norm with :func:`normalize_wxyz`).

    Missing w is rebuilt as Android does: ``sqrt(max(0, 1 − |xyz|²))`` (so w ≥ 0).
    """
    v = np.asarray(v, dtype=np.float64)
    xyz = v[:, :3]
    if v.shape[1] >= 4:
        w = v[:, 3]
    else:
        w = np.sqrt(np.clip(1.0 - np.sum(xyz**2, axis=1), 0.0, None))
    return np.column_stack([w, xyz])


def from_euler(seq: str, angles) -> Rotation:
    """Rotation(s) from Euler angles (rad), ``seq`` in scipy's notation: upper case = intrinsic.

    ``from_euler("ZXY", [yaw, pitch, roll])`` is R = Rz(yaw)·Rx(pitch)·Ry(roll), the Tait–Bryan
    z-x'-y'' convention of Core Motion's attitude and Sensor Logger's orientation angles.
    """
    return Rotation.from_euler(seq, np.asarray(angles, dtype=np.float64))


# ---- applying rotations and the vertical axis ---------------------------------------------


def apply(q, v, inverse: bool = False) -> np.ndarray:
    """Rotate (N, 3) vectors by (N, 4) quaternions w, x, y, z: device → world
    (``inverse``: world → device)."""
    rot = from_wxyz(q)
    return (rot.inv() if inverse else rot).apply(np.asarray(v, dtype=np.float64))


def increments(q, inverse: bool = False) -> np.ndarray:
    """(N − 1, 3) rotation vectors (rad) of the body-frame increments q_i⁻¹·q_{i+1} of (N, 4) unit
    quaternions w, x, y, z (``inverse``: of the inverted rotations, q_i·q_{i+1}⁻¹): scipy's
    ``(r[:-1].inv() * r[1:]).as_rotvec()``, written out in numpy because scipy 1.17's product and
    ``as_rotvec`` cost about 1.5 µs a row (measured; the importer checks every orientation sample
    this way, the live receiver every few seconds of every session: issue 61)."""
    q = np.asarray(q, dtype=np.float64)
    if inverse:
        q = q * np.array([1.0, -1.0, -1.0, -1.0])  # the inverted rotations: their conjugates
    a, b = q[:-1], q[1:]
    w1, x1, y1, z1 = a[:, 0], -a[:, 1], -a[:, 2], -a[:, 3]  # conj(a)
    w2, x2, y2, z2 = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    w = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    v = np.stack(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=1,
    )
    norm = np.sqrt(w * w + np.einsum("ij,ij->i", v, v))
    v, w = v * np.where(w < 0, -1.0, 1.0)[:, None] / norm[:, None], np.abs(w) / norm  # the shorter way round
    s = np.linalg.norm(v, axis=1)
    angle = 2.0 * np.arctan2(s, w)
    scale = np.where(s > 1e-7, angle / np.where(s > 1e-7, s, 1.0), 2.0 + angle**2 / 12.0)  # θ / sin(θ/2)
    return v * scale[:, None]


def yaw_matrix(yaw) -> np.ndarray:
    """(…, 3, 3) right-handed rotations by ``yaw`` (rad) about the world z axis (a 90° yaw maps
    x to y)."""
    a = np.asarray(yaw, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    R[..., 0, 0] = c
    R[..., 0, 1] = -s
    R[..., 1, 0] = s
    R[..., 1, 1] = c
    R[..., 2, 2] = 1.0
    return R


def yaw_of(q) -> np.ndarray:
    """Heading (rad, in (−π, π]) of (…, 4) world←device quaternions w, x, y, z: the angle of
    their twist about world z (swing–twist decomposition, 2·atan2(q_z, q_w)).

    Unlike an Euler yaw it has no gimbal lock when the device stands upright (a phone in a
    trouser pocket), and it is additive under a change of world yaw: yaw_of(Rz(δ)·R) =
    yaw_of(R) + δ (mod 2π). Undefined only for a device exactly upside down (q_w = q_z = 0).
    """
    q = np.asarray(q, dtype=np.float64)
    a = 2.0 * np.arctan2(q[..., 3], q[..., 0])
    return np.angle(np.exp(1j * a))  # wrap to (−π, π]


def rotate_about_vertical(v, yaw):
    """Vectors ``v`` (…, 3) rotated by ``yaw`` (rad, broadcast against ``v[..., 0]``) about z.

    Works on numpy arrays and torch tensors alike (same type out), so the same function turns
    a batch of world-frame windows or velocities during augmentation or frame alignment.
    """
    if type(v).__module__.startswith("torch"):
        import torch

        yaw = torch.as_tensor(yaw, dtype=v.dtype, device=v.device)
        c, s = torch.cos(yaw), torch.sin(yaw)
        x, y = v[..., 0], v[..., 1]
        return torch.stack([c * x - s * y, s * x + c * y, v[..., 2]], dim=-1)
    v = np.asarray(v)
    c, s = np.cos(yaw), np.sin(yaw)
    x, y = v[..., 0], v[..., 1]
    return np.stack([c * x - s * y, s * x + c * y, np.broadcast_to(v[..., 2], np.shape(c * x))], axis=-1)
