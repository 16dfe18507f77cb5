"""wearnav.core.timeseries: one clock onto another with an explicit gap rule, rates, duplicate policy."""

from __future__ import annotations

import numpy as np
import pytest

from wearnav.core import rotations
from wearnav.core.timeseries import (
    covered,
    drop_duplicate_times,
    interp_onto,
    nearest,
    period,
    periods,
    rate,
    sampling,
)
from wearnav.errors import ConfigError, ValidationError

T_SRC = np.array([0.0, 0.1, 0.2, 1.2, 1.3])  # a 1-s hole between 0.2 and 1.2


def test_hole_rule_masks_long_holes_and_outside_the_span():
    t = np.array([-0.05, 0.0, 0.15, 0.7, 1.2, 1.25, 1.3, 1.35])
    ok = covered(t, T_SRC, max_gap=0.25)
    # outside; sample; inside short interval; in the hole; sample after the hole (exact: kept);
    # inside short interval; last sample; outside
    np.testing.assert_array_equal(ok, [False, True, True, False, True, True, True, False])
    assert covered(t, T_SRC, max_gap=1.0)[3]  # the hole is 1.0 s: allowed by a 1-s rule
    assert not covered(t, T_SRC, max_gap=0.99)[3]


def test_nearest_rule_keeps_points_near_a_sample_without_extrapolating():
    t = np.array([-0.5, 0.5, 0.7, 1.0, 1.7, 3.0])
    ok = covered(t, T_SRC, max_gap=0.5, rule="nearest")
    np.testing.assert_array_equal(ok, [True, True, True, True, True, False])
    vals = np.column_stack([T_SRC, -T_SRC])
    out, mask = interp_onto(t, T_SRC, vals, max_gap=0.5, rule="nearest")
    np.testing.assert_array_equal(mask, ok)
    np.testing.assert_allclose(out[0], [0.0, 0.0])  # held at the first sample, not extrapolated
    np.testing.assert_allclose(out[4], [1.3, -1.3])  # held at the last sample
    np.testing.assert_allclose(out[1], [0.5, -0.5])  # linear across the hole


def test_values_fill_and_identical_clocks():
    vals = np.column_stack([T_SRC, 2 * T_SRC])
    t = np.array([0.05, 0.7, 1.25])
    out, mask = interp_onto(t, T_SRC, vals, max_gap=0.25, fill=np.nan)
    np.testing.assert_allclose(out[[0, 2]], [[0.05, 0.1], [1.25, 2.5]])
    assert np.all(np.isnan(out[1])) and mask.tolist() == [True, False, True]
    same, mask = interp_onto(T_SRC, T_SRC, vals, max_gap=0.01)
    assert same is vals and mask.all()  # every target is a sample: nothing interpolated


def test_periods_gap_rule():
    assert periods(3, 50.0) == pytest.approx(0.06)
    t = np.arange(0, 1, 0.02)
    t = np.delete(t, [10, 20, 21, 22])  # one missing sample (0.04 s), then three (0.08 s)
    ok = covered(np.arange(0, 0.98, 0.005), t, max_gap=periods(3, rate(t)))
    holes = ~ok
    assert holes.any() and np.all((np.arange(0, 0.98, 0.005)[holes] > 0.38) & (np.arange(0, 0.98, 0.005)[holes] < 0.46))


def test_quaternions_interpolate_across_sign_flips():
    R = rotations.yaw_matrix(np.linspace(0, 1, 11))
    q = rotations.matrix_to_wxyz(R)
    q[5:] *= -1  # same rotations, opposite sign half-way: naive averaging would pass through 0
    t_src = np.linspace(0, 1, 11)
    t = np.linspace(0, 1, 41)
    out, mask = interp_onto(t, t_src, q, max_gap=0.2, quaternion=True)
    assert mask.all()
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    np.testing.assert_allclose(rotations.yaw_of(out), t, atol=1e-3)


def test_bad_gap_rules():
    with pytest.raises(ConfigError):
        covered([0.0], T_SRC, max_gap=1.0, rule="bracket")
    with pytest.raises(ConfigError):
        covered([0.0], T_SRC, max_gap=-1.0)


def test_rate_period_and_sampling():
    rng = np.random.default_rng(0)
    dt = 0.01 + rng.uniform(-0.001, 0.001, 1000)
    dt[::100] = 0.05  # 10 gaps
    t = np.concatenate([[0.0], np.cumsum(dt)])
    assert rate(t) == pytest.approx(100.0, rel=0.01)
    assert period(t) == pytest.approx(0.01, rel=0.01)
    s = sampling(np.diff(t))
    assert s.rate_hz == pytest.approx(rate(t)) and s.interval_median_s == pytest.approx(period(t))
    assert s.jitter_iqr_s == pytest.approx(0.001, rel=0.1)  # IQR of U(-1, 1) ms is 1 ms
    assert s.gap_share == pytest.approx(0.01)
    assert rate([1.0]) == 0.0 and np.isnan(sampling([]).rate_hz)


def test_duplicate_policy_keeps_first_and_counts():
    t = np.array([0.0, 0.1, 0.1, 0.2, 0.3, 0.3, 0.3] + list(np.arange(0.4, 10, 0.1)))
    keep, n = drop_duplicate_times(t, "ACC", "f.txt")
    assert n == 3 and keep[:5].tolist() == [0, 1, 3, 4, 7]
    assert np.all(np.diff(t[keep]) > 0)
    with pytest.raises(ValidationError, match="f.txt: ACC: 3 of 10 timestamps are duplicated"):
        drop_duplicate_times(t[:10], "ACC", "f.txt")
    keep, n = drop_duplicate_times(np.array([0.0, 0.0]), "POSI")  # one repeat always tolerated
    assert keep.tolist() == [0] and n == 1
    with pytest.raises(ValidationError, match="backwards at row 2"):
        drop_duplicate_times(np.array([0.0, 1.0, 0.5]), "ACC")


def test_nearest_is_the_closest_sample_and_the_earlier_at_a_tie():
    src = np.array([0.0, 1.0, 2.0, 4.0])
    dst = np.array([-5.0, 0.4, 0.5, 0.6, 3.0, 3.1, 9.0])
    want = np.array([np.abs(src - x).argmin() for x in dst])  # argmin: the first (earlier) of equals
    assert np.array_equal(nearest(src, dst), want) and list(want) == [0, 0, 0, 1, 2, 3, 3]
    assert np.array_equal(nearest([7.0], dst), np.zeros(dst.size, int))
