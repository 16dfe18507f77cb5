import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.trajectory import integrate_displacements, integrate_velocity


def test_constant_velocity_is_a_straight_line():
    t = np.linspace(0, 10, 251)
    pos = integrate_velocity(np.array([0.0, 10.0]), np.array([[1.0, -0.5], [1.0, -0.5]]), t, np.array([2.0, 3.0]))
    np.testing.assert_allclose(pos[-1], [12.0, -2.0])
    np.testing.assert_allclose(pos[0], [2.0, 3.0])


def test_circle_from_true_velocity():
    # v(t) = (-sin t, cos t) integrates to the unit circle starting at (1, 0)
    tc = np.linspace(0, 2 * np.pi, 400)
    vel = np.stack([-np.sin(tc), np.cos(tc)], 1)
    t = np.linspace(0, 2 * np.pi, 2000)
    pos = integrate_velocity(tc, vel, t, np.array([1.0, 0.0]))
    np.testing.assert_allclose(pos, np.stack([np.cos(t), np.sin(t)], 1), atol=1e-3)


def test_displacements():
    pos = integrate_displacements(np.array([[1.0, 0], [0, 2.0], [-1.0, 0]]), np.array([0.0, 0.0]))
    np.testing.assert_allclose(pos, [[0, 0], [1, 0], [1, 2], [0, 2]])


def test_bad_times():
    with pytest.raises(ValidationError):
        integrate_velocity(np.array([1.0, 0.0]), np.zeros((2, 2)), np.arange(3.0), np.zeros(2))
