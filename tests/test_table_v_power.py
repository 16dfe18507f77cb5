"""Issue 59: the power calculation behind Table V's walks × seeds (wearnav.bench.power)."""

import math

import numpy as np
import pytest

from wearnav.bench.power import design, seed_spread, seeds_needed, spread_components, t_test_power
from wearnav.errors import ValidationError


def test_seeds_needed_matches_cohens_table():
    """Two-sided α = 0.05, power 0.8, n per group (Cohen 1988, Table 2.4.1): d = 0.5 → 64,
    0.8 → 26, 1.0 → 17."""
    assert [seeds_needed(d, 1.0) for d in (0.5, 0.8, 1.0)] == [64, 26, 17]
    assert t_test_power(1.0, 1.0, 17) >= 0.8 > t_test_power(1.0, 1.0, 16)
    assert t_test_power(0.0, 1.0, 10) == pytest.approx(0.05, abs=1e-9)  # no difference: the test's level
    assert seeds_needed(-0.5, 1.0) == 64  # the sign does not matter
    assert seeds_needed(1.0, 1.0, alpha=0.01) > 17  # a stricter level costs seeds
    with pytest.raises(ValidationError):
        seeds_needed(1.0, 0.0)


def test_spread_components_by_the_moments():
    # σ_b = 0.1, σ_c = 0.5, W = 5: var(walk) = 0.26, var(mean) = 0.01 + 0.05 = 0.06
    b, c = spread_components(math.sqrt(0.06), [math.sqrt(0.26)] * 5, 5)
    assert (b, c) == pytest.approx((0.1, 0.5))
    assert seed_spread(b, c, 5) == pytest.approx(math.sqrt(0.06))
    assert seed_spread(b, c, 1000) == pytest.approx(0.1, abs=2e-3)  # more walks cannot remove σ_b
    # inconsistent moments (σ_b² < 0): σ_b = 0 and σ_c from the walks, the cautious (larger) spread
    b, c = spread_components(0.1, [0.5] * 5, 5)
    assert b == 0 and seed_spread(b, c, 5) > 0.1
    with pytest.raises(ValidationError):
        spread_components(0.1, [0.5], 1)


def test_table_v_of_the_results_page_needs_more_walks_and_seeds():
    """docs/results.md (suite `odometry`, commit f316092): Table V's test-ATE seed spreads (3 seeds)
    and Suite-IN++'s per-walk spreads (Table III, `test`: one walk per mode). A 10 % difference of
    Suite-IN++'s 2.38 m: the page's 5 walks × 3 seeds have ~15 % power; the decision record's
    numbers (docs/decisions/0047-easytrack-amended-and-table-v-power.md) follow."""
    sd_mean = float(np.sqrt(np.mean(np.square([0.13, 0.16, 0.26, 0.32, 0.36, 0.17]))))
    b, c = spread_components(sd_mean, [0.27, 0.99, 0.62, 0.36, 1.03], 5)
    delta = 0.1 * 2.38
    assert sd_mean == pytest.approx(0.249, abs=1e-3) and b == 0 and c == pytest.approx(0.761, abs=1e-3)
    assert t_test_power(delta, sd_mean, 3) == pytest.approx(0.15, abs=0.01)
    rows = {r["walks"]: r["seeds"] for r in design(delta, b, c, [5, 10, 20, 40])}
    assert rows == {5: 34, 10: 18, 20: 10, 40: 6}
    assert {r["walks"]: r["seeds"] for r in design(delta, b, c, [40], alpha=0.01)} == {40: 8}
    assert seeds_needed(delta, sd_mean) == 19  # if more walks did not help at all
