import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.metrics import errors_at_reference

T_EST = [0.0, 1.0, 2.0]
P_EST = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]


def test_interpolates_estimate_and_drops_far_references():
    # t=0.5: estimate (0.5, 0) vs (0.5, 1) -> 1; t=1.5: (1, 0.5) vs (1, 0.5) -> 0;
    # t=5: nearest estimate sample 3 s away > max_gap -> dropped
    err = errors_at_reference(T_EST, P_EST, [0.5, 1.5, 5.0], [[0.5, 1.0], [1.0, 0.5], [0.0, 0.0]], 1.0)
    np.testing.assert_allclose(err, [1.0, 0.0])


def test_just_outside_the_estimate_uses_the_end_sample_not_extrapolation():
    # t=2.5 is 0.5 s after the last sample (1, 1): distance to (4, 5) is 5 (3-4-5 triangle);
    # t=-0.5 is 0.5 s before the first sample (0, 0): distance to (0, -2) is 2
    err = errors_at_reference(T_EST, P_EST, [-0.5, 2.5], [[0.0, -2.0], [4.0, 5.0]], 1.0)
    np.testing.assert_allclose(err, [2.0, 5.0])


def test_gap_is_inclusive_and_measured_to_the_nearest_sample():
    # estimate samples 10 s apart: t=1 is 1 s from the first sample, so it is kept and the
    # estimate interpolated a tenth of the way: (1, 0) vs (0, 0) -> 1; t=5 is 5 s from both: dropped
    err = errors_at_reference([0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [1.0, 5.0, 8.0],
                              [[0.0, 0.0], [5.0, 0.0], [8.0, 3.0]], max_gap=2.0)
    np.testing.assert_allclose(err, [1.0, 3.0])
    assert errors_at_reference([0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [2.0], [[2.0, 0.0]], 2.0).size == 1
    assert errors_at_reference([0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [2.001], [[2.0, 0.0]], 2.0).size == 0


def test_horizontal_only():
    # heights differ by 100 m, horizontal offset 3, 4 -> 5
    err = errors_at_reference([0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [0.5],
                              [[3.0, 4.0, 100.0]], 0.5)
    np.testing.assert_allclose(err, [5.0])


def test_no_reference_in_reach_gives_empty_and_no_nan():
    err = errors_at_reference(T_EST, P_EST, [10.0, 20.0], [[0.0, 0.0], [1.0, 1.0]], 2.0)
    assert err.shape == (0,)
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 100, 50))
    err = errors_at_reference(t, rng.normal(size=(50, 2)), np.linspace(-10, 110, 200),
                              rng.normal(size=(200, 2)), 2.0)
    assert err.size < 200 and np.all(np.isfinite(err))


@pytest.mark.parametrize("args", [
    ([1.0, 0.0, 2.0], P_EST, [0.5], [[0.0, 0.0]], 1.0),          # unsorted estimate times
    (T_EST, P_EST[:2], [0.5], [[0.0, 0.0]], 1.0),               # length mismatch
    (T_EST, P_EST, [0.5], [[0.0, np.nan]], 1.0),                # NaN reference
    (T_EST, P_EST, [0.5], [[0.0, 0.0]], -1.0),                  # negative gap
])
def test_bad_input(args):
    with pytest.raises(ValidationError):
        errors_at_reference(*args)
