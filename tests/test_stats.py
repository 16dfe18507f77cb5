"""The walk bootstrap of :func:`wearnav.stats.walk_bootstrap_difference` (paired by walk)."""

import numpy as np
import pytest

from wearnav.errors import ValidationError
from wearnav.stats import percentiles_of_draws, walk_bootstrap_difference


def _walks(rng, n=12, points=15):
    return [rng.gamma(2.0, 3.0, points) * rng.uniform(0.5, 2.0) for _ in range(n)]


def test_a_constant_shift_is_the_difference_with_a_zero_width_interval():
    a = _walks(np.random.default_rng(0))
    d = walk_bootstrap_difference([x + 2.0 for x in a], a)
    assert d["walks"] == 12 and d["quantiles"] == [50, 75, 95]
    np.testing.assert_allclose(d["difference"], 2.0, atol=1e-9)
    np.testing.assert_allclose(d["low"], 2.0, atol=1e-9)
    np.testing.assert_allclose(d["high"], 2.0, atol=1e-9)


def test_equal_paths_differ_by_zero():
    a = _walks(np.random.default_rng(1))
    d = walk_bootstrap_difference(a, [x.copy() for x in a])
    assert d["difference"] == [0.0, 0.0, 0.0] and d["low"] == [0.0, 0.0, 0.0] and d["high"] == [0.0, 0.0, 0.0]


def test_the_interval_holds_the_point_and_brackets_zero_for_noise_only():
    rng = np.random.default_rng(2)
    a = _walks(rng, n=10)
    b = [x + rng.normal(0.0, 3.0, x.size) for x in a]  # no systematic difference, walk-to-walk noise
    d = walk_bootstrap_difference(a, b, seed=0)
    assert all(lo <= p <= hi for lo, p, hi in zip(d["low"], d["difference"], d["high"]))
    assert d["low"][0] < 0.0 < d["high"][0]
    # a 30 % larger error everywhere is found, its interval clear of zero at the median
    d = walk_bootstrap_difference([1.3 * x for x in a], a, seed=0)
    assert d["low"][0] > 0.0


def test_the_interval_is_by_walk_not_by_point():
    """One walk that is far worse widens the interval: resampling walks, not points."""
    rng = np.random.default_rng(3)
    a = _walks(rng, n=10, points=40)
    b = [x.copy() for x in a]
    b[0] = b[0] + 30.0
    d = walk_bootstrap_difference(b, a, seed=0)
    assert d["difference"][2] > 0.0 and d["low"][2] == pytest.approx(0.0, abs=1e-9)


def test_mismatched_or_missing_walks_are_refused():
    a = _walks(np.random.default_rng(4), n=3)
    with pytest.raises(ValidationError, match="same walks"):
        walk_bootstrap_difference(a, a[:2])
    with pytest.raises(ValidationError, match="at least 2 walks"):
        walk_bootstrap_difference(a[:1], a[:1])


def test_percentiles_of_draws_equal_numpys_on_the_drawn_walks_put_together():
    """Each draw's quantiles without concatenating its walks (the bootstrap's inner loop) are
    np.nanpercentile's of the concatenation: NaN points skipped, ties, a walk with no points, a walk
    drawn several times, and a draw of walks with no points at all (NaN)."""
    rng = np.random.default_rng(5)
    walks = _walks(rng, n=7, points=9)
    walks[1][::3] = np.nan
    walks[2] = np.full(4, np.nan)
    walks[3] = np.round(walks[3])  # ties
    walks[4] = walks[3].copy()
    draws = rng.integers(0, len(walks), (50, len(walks)))
    draws[0] = 2  # no points at all
    q = [0, 10, 50, 75, 95, 100]
    got = percentiles_of_draws(walks, draws, q)
    assert got.shape == (len(q), len(draws)) and np.isnan(got[:, 0]).all()
    for r in range(1, len(draws)):
        want = np.nanpercentile(np.concatenate([walks[i] for i in draws[r]]), q)
        np.testing.assert_allclose(got[:, r], want, rtol=0, atol=1e-12)
