"""wearnav.metrics.along_cross_errors: a position error split along the walk and across it at each
surveyed point (issue 36: what a floor plan can and cannot correct)."""

import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.metrics import along_cross_errors, errors_at_reference


def _line(heading_deg: float, offset=(0.0, 0.0)):
    """A straight truth walk at 1.2 m/s along ``heading_deg`` surveyed every 5 s, and the estimate
    the truth shifted by ``offset`` (m, x/y), sampled at 10 Hz."""
    t = np.arange(0, 30.01, 0.1)
    h = np.radians(heading_deg)
    truth = 1.2 * t[:, None] * np.array([np.cos(h), np.sin(h)])
    k = np.arange(0, len(t), 50)
    return t, truth + np.asarray(offset), t[k], truth[k]


def test_an_estimate_ahead_and_left_of_an_eastward_walk():
    along, cross = along_cross_errors(*_line(0.0, (2.0, 1.0)), max_gap=1.0)
    np.testing.assert_allclose(along, 2.0, atol=1e-9)  # ahead of the walker: +
    np.testing.assert_allclose(cross, 1.0, atol=1e-9)  # to the walker's left: +


def test_the_split_turns_with_the_walk():
    # walking north, an estimate 1 m west is 1 m to the walker's left and neither ahead nor behind
    along, cross = along_cross_errors(*_line(90.0, (-1.0, 0.0)), max_gap=1.0)
    np.testing.assert_allclose(along, 0.0, atol=1e-9)
    np.testing.assert_allclose(cross, 1.0, atol=1e-9)
    # walking south-west, an estimate 3 m back along the walk
    h = np.radians(225.0)
    along, cross = along_cross_errors(*_line(225.0, (-3 * np.cos(h), -3 * np.sin(h))), max_gap=1.0)
    np.testing.assert_allclose(along, -3.0, atol=1e-9)
    np.testing.assert_allclose(cross, 0.0, atol=1e-9)


def test_the_two_parts_make_the_error_at_the_same_points():
    rng = np.random.default_rng(3)
    t = np.arange(0, 60.01, 0.1)
    truth = np.cumsum(rng.normal(0, 0.3, (t.size, 2)), axis=0) + np.c_[1.1 * t, 0.2 * t]
    est = truth + np.cumsum(rng.normal(0, 0.05, (t.size, 2)), axis=0)
    k = np.arange(0, t.size, 40)
    t_est = t[t < 50]  # the estimate ends before the truth: the last points are not scored
    along, cross = along_cross_errors(t_est, est[: t_est.size], t[k], truth[k], max_gap=2.0)
    err = errors_at_reference(t_est, est[: t_est.size], t[k], truth[k], max_gap=2.0)
    assert along.shape == cross.shape == err.shape and err.size < k.size
    np.testing.assert_allclose(np.hypot(along, cross), err, rtol=1e-9)


def test_a_turn_takes_the_direction_through_its_neighbours():
    # east 10 m, then north 10 m: at the corner the walk's direction is north-east
    t_ref = np.array([0.0, 10.0, 20.0])
    p_ref = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    t_est = np.array([0.0, 10.0, 20.0])
    est = p_ref + np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    along, cross = along_cross_errors(t_est, est, t_ref, p_ref, max_gap=1.0)
    np.testing.assert_allclose(along, [0.0, np.sqrt(2.0), 0.0], atol=1e-9)
    np.testing.assert_allclose(cross, [0.0, 0.0, 0.0], atol=1e-9)


def test_a_standing_walker_has_no_direction():
    t_ref = np.array([0.0, 5.0, 10.0])
    p_ref = np.zeros((3, 2))
    along, cross = along_cross_errors(t_ref, p_ref + 1.0, t_ref, p_ref, max_gap=1.0)
    assert np.isnan(along).all() and np.isnan(cross).all()


def test_bad_input_is_refused():
    with pytest.raises(ValidationError):
        along_cross_errors([0.0, 1.0], np.zeros((3, 2)), [0.0], np.zeros((1, 2)), max_gap=1.0)
