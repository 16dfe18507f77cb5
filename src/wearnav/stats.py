"""Seed statistics shared by the benchmarks: is a difference between two models larger than the
spread over their training seeds?

:func:`welch_p` tests two samples of per-seed numbers (accuracies, ATEs); :func:`bh_adjust`
corrects a table's p values for testing several models against one reference
(Benjamini–Hochberg false discovery rate); a table marks a difference where the adjusted p is
below :data:`SIGNIFICANCE`.
"""

from __future__ import annotations

import warnings

import numpy as np

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
