"""Seed statistics shared by the benchmarks: is a difference between two models larger than the
spread over their training seeds?

:func:`welch_p` tests two samples of per-seed numbers (accuracies, ATEs); :func:`bh_adjust`
corrects a table's p values for testing several models against one reference
(Benjamini–Hochberg false discovery rate); a table marks a difference where the adjusted p is
below :data:`SIGNIFICANCE`. :func:`walk_bootstrap_difference` asks the same of two paths scored on
the same walks: is a difference in a quantile of the error larger than the walk-to-walk spread?

Decisions: docs/decisions/0011-odometry-grid-and-page.md,
docs/decisions/0021-smoother-tried-simulator-confidence.md.
"""

from __future__ import annotations

import warnings

import numpy as np

from wearnav.errors import ValidationError

SIGNIFICANCE = 0.05  # the false discovery rate a table's † marks control, per table


def welch_p(a: list[float], b: list[float]) -> float | None:
    """Two-sided p of Welch's t-test between two models' per-seed numbers (e.g. accuracies). None with
    fewer than 2 seeds on either side; two constant samples give 0 where they differ, 1 where
    they agree (the test is undefined there). With 3 seeds only a large, consistent difference
    has a small p."""
    from scipy.stats import ttest_ind

    if len(a) < 2 or len(b) < 2:
        return None
    if np.ptp(a) == 0 and np.ptp(b) == 0:
        return 0.0 if a[0] != b[0] else 1.0
    with warnings.catch_warnings():  # nearly equal seeds (a collapsed model) trip a precision warning
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(ttest_ind(a, b, equal_var=False).pvalue)


def bh_adjust(p: dict[str, float | None]) -> dict[str, float | None]:
    """Benjamini–Hochberg-adjusted p values (``scipy.stats.false_discovery_control``, method
    'bh') of one table's models against its reference; None stays None (not tested)."""
    from scipy.stats import false_discovery_control

    tested = [k for k, v in p.items() if v is not None]
    adj = false_discovery_control([p[k] for k in tested], method="bh") if tested else []
    out: dict[str, float | None] = dict.fromkeys(p)
    out.update({k: float(v) for k, v in zip(tested, adj)})
    return out


def walk_bootstrap_difference(
    a: list, b: list, quantiles=(50, 75, 95), confidence: float = 0.9, n_resamples: int = 2000, seed: int = 0
) -> dict:
    """Quantiles of path ``a``'s errors minus path ``b``'s, with a percentile interval from
    resampling *walks* (``scipy.stats.bootstrap``, paired: both paths' errors of a drawn walk go
    in together). ``a``, ``b``: per walk, the errors (m) at its points (NaN: none there), the same
    walks in the same order. Points of one walk share its fixes and its route, so they are not independent; resampling
    walks keeps that, and a tail made by one walk gets the wide interval it deserves. Returns
    ``quantiles``, ``difference``, ``low``, ``high`` (lists, m) and ``walks``."""
    from scipy.stats import bootstrap

    if len(a) != len(b):
        raise ValidationError(f"both paths must be scored on the same walks; got {len(a)} and {len(b)}")
    if len(a) < 2:
        raise ValidationError(f"a walk bootstrap needs at least 2 walks; got {len(a)}")
    a = [np.asarray(x, float) for x in a]
    b = [np.asarray(x, float) for x in b]
    q = list(quantiles)

    def diff(idx, axis=-1):
        idx = np.moveaxis(np.asarray(idx, int), axis, -1)
        return percentiles_of_draws(a, idx, q) - percentiles_of_draws(b, idx, q)

    point = diff(np.arange(len(a)))[:, 0]
    with warnings.catch_warnings():  # identical paths: a degenerate (zero-width) distribution
        warnings.simplefilter("ignore")
        ci = bootstrap(
            (np.arange(len(a)),),
            diff,
            vectorized=True,
            paired=True,
            n_resamples=n_resamples,
            confidence_level=confidence,
            method="percentile",
            random_state=seed,
        ).confidence_interval
    low, high = (np.where(np.isfinite(v), v, point) for v in (ci.low, ci.high))
    r = lambda v: [round(float(x), 3) for x in v]
    return {
        "quantiles": q,
        "difference": r(point),
        "low": r(np.minimum(low, point)),
        "high": r(np.maximum(high, point)),
        "walks": len(a),
        "confidence": confidence,
    }


def percentiles_of_draws(walks: list, draws, q) -> np.ndarray:
    """``np.nanpercentile(np.concatenate([walks[i] for i in draw]), q)`` (its default, linear
    method) for every draw at once, shape ``(len(q), draws)``; a draw with no finite point gives
    NaN. The walks' points are sorted once; a draw weights each point by how often its walk was
    drawn, and the k-th value of the concatenation is the first point whose cumulative weight
    exceeds k (one search for all draws of a chunk: each draw's cumulative weights are offset
    past the previous draw's, so the rows put end to end stay sorted). ``draws``: walk indices,
    shape ``(n_draws, walks_per_draw)`` or one draw."""
    finite = [np.asarray(x, float)[np.isfinite(x)] for x in walks]
    values = np.concatenate(finite)
    walk_of = np.repeat(np.arange(len(finite)), [len(x) for x in finite])
    order = np.argsort(values, kind="stable")
    values, walk_of = values[order], walk_of[order]
    draws = np.atleast_2d(np.asarray(draws, int))
    out = np.full((len(q), len(draws)), np.nan)
    if values.size == 0:
        return out
    frac = np.asarray(q, float) / 100.0
    for start in range(0, len(draws), 256):  # bounded memory: (256, points) weights at a time
        chunk = draws[start : start + 256]
        rows = np.arange(len(chunk))
        counts = np.zeros((len(chunk), len(finite)), np.int64)
        np.add.at(counts, (rows[:, None], chunk), 1)
        cum = np.cumsum(counts[:, walk_of], axis=1)
        n = cum[:, -1]
        offset = rows * (int(n.max()) + 1)  # row r's weights lie in [offset_r, offset_r + n_r]
        flat = (cum + offset[:, None]).ravel()
        pos = frac[None, :] * (n[:, None] - 1)
        lo = np.floor(pos)
        k = np.stack([lo, np.minimum(lo + 1, n[:, None] - 1)])  # the ranks (0-based) to read, (2, rows, q)
        i = np.searchsorted(flat, (k + offset[:, None]).ravel(), side="right").reshape(k.shape)
        x0, x1 = values[np.minimum(i - (rows * values.size)[:, None], values.size - 1)]
        t = pos - lo
        # numpy's lerp, exactly (from the nearer end, so t = 1 gives x1 itself)
        v = np.where(t >= 0.5, x1 - (x1 - x0) * (1 - t), x0 + (x1 - x0) * t)
        out[:, start : start + len(chunk)] = np.where(n[:, None] > 0, v, np.nan).T
    return out


def mean_sd_text(values) -> str:
    """A page cell of values over seeds: "mean ± sd" (sample sd), the value alone when there is one,
    "—" when none is finite (None and NaN are left out)."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    if not len(v):
        return "—"
    return f"{v.mean():.2f} ± {v.std(ddof=1):.2f}" if len(v) > 1 else f"{v[0]:.2f}"


def difference_cells(d: dict) -> dict[str, str]:
    """A table's cells of a :func:`walk_bootstrap_difference` result: one per quantile, e.g.
    ``{"median (m)": "-1.35 [-1.70, -0.94]", "p95 (m)": ...}`` (difference and its interval, m)."""
    return {
        f"{'median' if q == 50 else f'p{q}'} (m)": f"{p:+.2f} [{lo:+.2f}, {hi:+.2f}]"
        for q, p, lo, hi in zip(d["quantiles"], d["difference"], d["low"], d["high"])
    }
