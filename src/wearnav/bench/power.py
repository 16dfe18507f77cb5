"""How many test walks × training seeds a comparison needs to see a given difference (issue 59).

Suite-IN++'s Table V (ablations) on the simulator is flat, but with five test walks and three
seeds it could not have shown the paper's 10 % either. This module states the power calculation:

* A variant's score for one seed is its mean ATE over the W test walks. Its spread over seeds is
  modelled as σ(W)² = σ_b² + σ_c²/W: σ_b a seed's effect on every walk alike, σ_c its effect on
  each walk apart (a walk effect common to all seeds cancels when two variants share the walks).
  :func:`spread_components` estimates both from what a results page gives: the seed spread of
  the walk mean, and each walk's own seed spread.
* Two variants, n seeds each, compared by a two-sided two-sample t-test at level α: its power for a
  difference Δ is that of the noncentral t with 2n − 2 degrees of freedom and noncentrality
  Δ / (σ(W)·√(2/n)) (:func:`t_test_power`, exact, scipy); :func:`seeds_needed` is the smallest n
  reaching the asked power. (Welch's test, which the page uses, has the same power at equal n and σ.)

Decision: docs/decisions/0047-easytrack-amended-and-table-v-power.md.
"""

from __future__ import annotations

import math

import numpy as np

from wearnav.errors import ValidationError


def spread_components(sd_mean: float, sd_walks: list[float], walks: int) -> tuple[float, float]:
    """(σ_b, σ_c) from the seed spread ``sd_mean`` of the mean over ``walks`` test walks and the seed
    spreads ``sd_walks`` of single walks (pooled as the root mean square), by the moments
    var(walk) = σ_b² + σ_c², var(mean) = σ_b² + σ_c²/W. Where the two disagree so that σ_b² < 0
    (few seeds), σ_b is 0 and σ_c keeps its walk-level estimate: the larger, i.e. cautious, spread."""
    if walks < 2 or not sd_walks:
        raise ValidationError(f"need ≥ 2 walks and their spreads (got walks={walks}, {len(sd_walks)} spreads)")
    v_walk = float(np.mean(np.square(sd_walks)))
    v_mean = float(sd_mean) ** 2
    v_c = max((v_walk - v_mean) / (1 - 1 / walks), 0.0)
    v_b = max(v_mean - v_c / walks, 0.0)
    return math.sqrt(v_b), math.sqrt(v_c)


def seed_spread(sd_b: float, sd_c: float, walks: int) -> float:
    """σ(W) = √(σ_b² + σ_c²/W): the seed spread of a variant's mean over ``walks`` test walks."""
    return math.sqrt(sd_b**2 + sd_c**2 / walks)


def t_test_power(delta: float, sd: float, n: int, alpha: float = 0.05) -> float:
    """Power of the two-sided two-sample t-test (n per group, common σ = ``sd``) to find ``delta``."""
    from scipy.stats import nct
    from scipy.stats import t as student

    if n < 2:
        return 0.0
    df = 2 * n - 2
    ncp = abs(delta) / (sd * math.sqrt(2 / n))
    crit = float(student.ppf(1 - alpha / 2, df))
    return float(nct.sf(crit, df, ncp) + nct.cdf(-crit, df, ncp))


def seeds_needed(delta: float, sd: float, alpha: float = 0.05, power: float = 0.8, n_max: int = 10_000) -> int:
    """Smallest n (seeds per variant, ≥ 2) whose t-test finds ``delta`` with ``power``; a
    ValidationError beyond ``n_max``."""
    if not (delta != 0 and sd > 0 and 0 < alpha < 1 and 0 < power < 1):
        raise ValidationError(f"need delta ≠ 0, sd > 0, 0 < alpha, power < 1 (got {delta}, {sd}, {alpha}, {power})")
    n = 2
    while t_test_power(delta, sd, n, alpha) < power:
        n += 1
        if n > n_max:
            raise ValidationError(f"more than {n_max} seeds needed for Δ = {delta} at σ = {sd}")
    return n


def design(
    delta: float, sd_b: float, sd_c: float, walks: list[int], alpha: float = 0.05, power: float = 0.8
) -> list[dict]:
    """Per number of test walks W: σ(W), the seeds per variant needed, and walks × seeds per variant."""
    rows = []
    for w in walks:
        sd = seed_spread(sd_b, sd_c, w)
        n = seeds_needed(delta, sd, alpha, power)
        rows.append({"walks": w, "seed_spread_m": sd, "seeds": n, "walk_runs": w * n})
    return rows
