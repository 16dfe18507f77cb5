"""wearnav.core.rotations: the one place for quaternion conventions (w, x, y, z; world←device)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from wearnav.core import rotations as rot

X, Y, Z = np.eye(3)


def random_wxyz(n, seed=0):
    q = np.random.default_rng(seed).standard_normal((n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def same_rotation(a, b, tol=1e-9):
    return np.all(np.abs(np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1)) - 1) < tol)


def test_wxyz_is_scalar_first():
    # A 90° turn about z: w = cos 45°, z = sin 45°, in that order.
    q = rot.to_wxyz(Rotation.from_euler("z", 90, degrees=True))
    np.testing.assert_allclose(q, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], atol=1e-12)
    np.testing.assert_allclose(rot.from_wxyz([1.0, 0, 0, 0]).as_matrix(), np.eye(3))


def test_world_from_device_90_degree_yaw_maps_x_to_y():
    q = np.array([[np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]])
    np.testing.assert_allclose(rot.apply(q, [X]), [Y], atol=1e-12)
    np.testing.assert_allclose(rot.apply(q, [Y], inverse=True), [X], atol=1e-12)
    np.testing.assert_allclose(rot.yaw_matrix(np.pi / 2) @ X, Y, atol=1e-12)
    np.testing.assert_allclose(rot.rotate_about_vertical(X, np.pi / 2), Y, atol=1e-12)
    np.testing.assert_allclose(rot.as_matrix(q)[0], rot.yaw_matrix(np.pi / 2), atol=1e-12)


def test_round_trips():
    q = random_wxyz(200)
    assert same_rotation(rot.to_wxyz(rot.from_wxyz(q)), q)
    assert same_rotation(rot.matrix_to_wxyz(rot.as_matrix(q)), q)
    R = rot.as_matrix(q.reshape(10, 20, 4))
    assert R.shape == (10, 20, 3, 3)
    np.testing.assert_allclose(R.reshape(-1, 3, 3), rot.as_matrix(q), atol=1e-12)
    v = np.random.default_rng(1).standard_normal((200, 3))
    np.testing.assert_allclose(rot.apply(q, rot.apply(q, v), inverse=True), v, atol=1e-12)


def test_matrix_columns_are_device_axes_in_world():
    q = random_wxyz(5, seed=3)
    R = rot.as_matrix(q)
    for k, axis in enumerate((X, Y, Z)):
        np.testing.assert_allclose(rot.apply(q, np.tile(axis, (5, 1))), R[:, :, k], atol=1e-12)


def test_sign_continuity():
    q = random_wxyz(50, seed=2)
    smooth = np.cumsum(0.05 * q, axis=0) + [1, 0, 0, 0]
    smooth /= np.linalg.norm(smooth, axis=1, keepdims=True)
    flipped = smooth * np.where(np.arange(50) % 3 == 0, -1.0, 1.0)[:, None]
    out = rot.sign_continuous(flipped, first_w_positive=True)
    np.testing.assert_allclose(out, smooth, atol=1e-12)
    out = rot.matrix_to_wxyz(rot.as_matrix(flipped))
    assert np.all(np.sum(out[1:] * out[:-1], axis=1) >= 0) and out[0, 0] >= 0


def test_android_rotation_vector():
    q = random_wxyz(100, seed=4)
    q[:, 0] = np.abs(q[:, 0])  # Android's w ≥ 0
    # x, y, z only: w rebuilt; x, y, z, w: taken as logged.
    np.testing.assert_allclose(rot.from_android_rotation_vector(q[:, 1:]), q, atol=1e-12)
    np.testing.assert_allclose(rot.from_android_rotation_vector(np.column_stack([q[:, 1:], q[:, 0]])), q)
    # A 90° yaw logged as a rotation vector sin(45°)·z.
    q90 = rot.from_android_rotation_vector([[0, 0, np.sin(np.pi / 4)]])
    np.testing.assert_allclose(rot.apply(q90, [X]), [Y], atol=1e-12)


def test_normalize_refuses_non_unit_rows():
    q = random_wxyz(10) * 1.01
    np.testing.assert_allclose(np.linalg.norm(rot.normalize_wxyz(q), axis=1), 1.0)
    q[6] *= 2
    with pytest.raises(rot.NotUnitQuaternion) as info:
        rot.normalize_wxyz(q)
    assert info.value.row == 6 and info.value.norm == pytest.approx(2.02)


def test_euler_zxy_is_rz_rx_ry():
    yaw, pitch, roll = 0.7, -0.3, 1.1
    R = rot.from_euler("ZXY", [yaw, pitch, roll]).as_matrix()
    Rx = Rotation.from_euler("x", pitch).as_matrix()
    Ry = Rotation.from_euler("y", roll).as_matrix()
    np.testing.assert_allclose(R, rot.yaw_matrix(yaw) @ Rx @ Ry, atol=1e-12)


def test_yaw_of_known_and_additive():
    for a in (-3.0, -1.0, 0.0, 0.5, 2.5):
        assert rot.yaw_of(rot.to_wxyz(Rotation.from_rotvec([0, 0, a]))) == pytest.approx(a)
    # A phone upright in a pocket (pitch 90°: Euler gimbal lock) still has a yaw, and a world yaw
    # offset adds to it.
    q = random_wxyz(100, seed=5)
    q[0] = rot.to_wxyz(rot.from_euler("ZXY", [0.4, np.pi / 2, 0.0]))
    delta = 0.9
    shifted = rot.to_wxyz(Rotation.from_rotvec([0, 0, delta]) * rot.from_wxyz(q))
    diff = np.angle(np.exp(1j * (rot.yaw_of(shifted) - rot.yaw_of(q))))
    np.testing.assert_allclose(diff, delta, atol=1e-9)
    assert rot.yaw_of(q[0]) == pytest.approx(0.4)


def test_rotate_about_vertical_numpy_and_torch():
    v = np.random.default_rng(6).standard_normal((4, 7, 3))
    yaw = np.linspace(-2, 2, 4)[:, None]
    out = rot.rotate_about_vertical(v, yaw)
    expect = np.einsum("bij,btj->bti", rot.yaw_matrix(yaw[:, 0]), v)
    np.testing.assert_allclose(out, expect, atol=1e-12)
    out_t = rot.rotate_about_vertical(torch.tensor(v, dtype=torch.float32), torch.tensor(yaw))
    assert isinstance(out_t, torch.Tensor) and out_t.dtype == torch.float32
    np.testing.assert_allclose(out_t.numpy(), expect, atol=1e-5)
    # Norms and the vertical component are kept.
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), np.linalg.norm(v, axis=-1))
    np.testing.assert_array_equal(out[..., 2], v[..., 2])


def test_increments_are_scipys_relative_rotations():
    """rot.increments: the rotation vectors of q_i⁻¹·q_{i+1} (and of the inverted sequence's), as
    scipy computes them, on random rotations, with q and −q mixed and near-identity steps."""
    r = Rotation.random(400, random_state=3)
    small = r * Rotation.from_rotvec(np.random.default_rng(4).normal(0, 1e-9, (400, 3)))
    seq = Rotation.concatenate([r, small])
    q = rot.to_wxyz(seq)
    q[::3] *= -1  # the same rotations written with the other sign
    for inverse in (False, True):
        s = seq.inv() if inverse else seq
        want = (s[:-1].inv() * s[1:]).as_rotvec()
        got = rot.increments(q, inverse=inverse)
        assert got.shape == (len(q) - 1, 3)
        np.testing.assert_allclose(got, want, atol=1e-12)
    assert rot.increments(q[:1]).shape == (0, 3)
