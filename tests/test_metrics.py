import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.metrics import errors_at_reference, label_noise

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
    err = errors_at_reference(
        [0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [1.0, 5.0, 8.0], [[0.0, 0.0], [5.0, 0.0], [8.0, 3.0]], max_gap=2.0
    )
    np.testing.assert_allclose(err, [1.0, 3.0])
    assert errors_at_reference([0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [2.0], [[2.0, 0.0]], 2.0).size == 1
    assert errors_at_reference([0.0, 10.0], [[0.0, 0.0], [10.0, 0.0]], [2.001], [[2.0, 0.0]], 2.0).size == 0


def test_horizontal_only():
    # heights differ by 100 m, horizontal offset 3, 4 -> 5
    err = errors_at_reference([0.0, 1.0], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [0.5], [[3.0, 4.0, 100.0]], 0.5)
    np.testing.assert_allclose(err, [5.0])


def test_no_reference_in_reach_gives_empty_and_no_nan():
    err = errors_at_reference(T_EST, P_EST, [10.0, 20.0], [[0.0, 0.0], [1.0, 1.0]], 2.0)
    assert err.shape == (0,)
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 100, 50))
    err = errors_at_reference(t, rng.normal(size=(50, 2)), np.linspace(-10, 110, 200), rng.normal(size=(200, 2)), 2.0)
    assert err.size < 200 and np.all(np.isfinite(err))


@pytest.mark.parametrize(
    "args",
    [
        ([1.0, 0.0, 2.0], P_EST, [0.5], [[0.0, 0.0]], 1.0),  # unsorted estimate times
        (T_EST, P_EST[:2], [0.5], [[0.0, 0.0]], 1.0),  # length mismatch
        (T_EST, P_EST, [0.5], [[0.0, np.nan]], 1.0),  # NaN reference
        (T_EST, P_EST, [0.5], [[0.0, 0.0]], -1.0),  # negative gap
    ],
)
def test_bad_input(args):
    with pytest.raises(ValidationError):
        errors_at_reference(*args)


# ---- label noise (EasyTrack eqs. 5–7) ---------------------------------------------------------


def test_label_noise_is_the_increment_of_the_fix_error():
    t = np.arange(0.0, 6.0)
    truth = np.stack([1.3 * t, 0.2 * t], 1)
    err = np.array([[0, 0], [3, 4], [3, 4], [0, 0], [1, 0], [1, 0]], float)
    # eq. 6: d_e,i = P_e,i+1 − P_e,i; a constant offset (i = 1 → 2, 4 → 5) is no label noise
    np.testing.assert_allclose(label_noise(t, truth + err, t, truth), [5, 0, 5, 1, 0], atol=1e-12)


def test_label_noise_interpolates_truth_at_fix_times_and_skips_fixes_without_truth():
    t_true = np.arange(0.0, 10.01, 0.01)
    truth = np.stack([t_true, np.zeros_like(t_true)], 1)
    t_fix = np.array([0.5, 1.5, 2.5, 20.0])  # the last fix is after the truth ends
    fix = np.stack([t_fix, np.zeros(4)], 1) + [[0, 0], [0, 0.3], [0, 0], [50, 50]]
    np.testing.assert_allclose(label_noise(t_fix, fix, t_true, truth), [0.3, 0.3])
    assert label_noise(t_fix[:1], fix[:1], t_true, truth).size == 0
    # truth with a 5-s hole is trusted across it only if max_gap allows
    hole = (t_true < 1.0) | (t_true > 6.0)
    assert label_noise(t_fix, fix, t_true[hole], truth[hole]).size == 2
    assert label_noise(t_fix, fix, t_true[hole], truth[hole], max_gap=1.0).size == 0
