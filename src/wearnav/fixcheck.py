"""Which location fixes may anchor a path (issue 18 §5), decided before any fit.

A phone's first fixes are often its last known position (cached: possibly hundreds of metres
away, sometimes claiming a small accuracy) or very wide (network location, 100–2000 m); such fixes
must not pull the anchoring of :mod:`wearnav.fuse`, and the output says which fixes were used.
:func:`check_fixes` gives every fix one status, the first reason below that applies:

``no position``       a NaN or infinite east/north;
``outside the walk``  a time outside the odometry path's span (or NaN);
``wide``              a reported accuracy wider than ``wide_m`` (:class:`wearnav.fuse.FuseConfig`,
                      100 m): too coarse to place a walking path;
``repeat``            the same position as the previous kept fix (a stale fix re-reported: only the
                      first of a run is used);
``jump``              a position the walker cannot have been at (:func:`jumps`): reaching it from the
                      fixes the walk's majority agrees on would take more than ``MAX_SPEED_M_S``
                      beyond twice both fixes' reported accuracies, e.g. a cached first fix.

Those are ``dropped``; the rest are kept, and the anchoring then marks each kept fix ``used``,
``down-weighted`` (the smoother's robust weight below :data:`wearnav.fuse.DOWNWEIGHT`) or
``unused`` (first-fix anchoring: after its first ``ANCHOR_S`` seconds of kept fixes). Where most
fixes would be jumps the fixes disagree with each other, not with a few outliers: none is dropped
as a jump (the smoother's robust loss and its fallback judge them; a warning says so).

Decision: docs/decisions/0015-fixcheck-bad-fixes.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np

USED, DOWN_WEIGHTED, UNUSED, DROPPED = "used", "down-weighted", "unused", "dropped"
NO_POSITION, OUTSIDE, WIDE, REPEAT, JUMP = "no position", "outside the walk", "wide", "repeat", "jump"
MAX_SPEED_M_S = 10.0  # a walker (or runner) does not move faster; a fix implying more is a jump
# The accuracy (a 68 % radius, 1.515 σ per axis) allowed twice over in the jump test: two fixes'
# honest errors then differ by more than the margin with odds of about 1e-4 (a 2-D Gaussian of
# σ √2 beyond 6.1 σ), whatever their rate; and no fix counts as better than 3 m (phones report
# 1–3 m at best, and fixes a tenth of a second apart still scatter by metres).
JUMP_MARGIN = 2.0
JUMP_MIN_ACCURACY_M = 3.0
JUMP_SHARE = 0.5  # more than this share of the kept fixes jumping: they disagree, drop none for it
FILL_ACCURACY_M = 1.515  # accuracy assumed where no fix reports one (1 m per axis, as fuse.fix_sigma_m)


@dataclasses.dataclass
class FixCheck:
    """Per fix, in the order given: ``status`` (M,) one of used / down-weighted / unused / dropped,
    ``reason`` (M,) why dropped or unused ("" otherwise), ``weight`` (M,) its weight in the fit
    relative to a fix of its reported accuracy (0 where not used); ``warnings`` about the fixes."""

    status: np.ndarray
    reason: np.ndarray
    weight: np.ndarray
    warnings: list[str]

    @property
    def kept(self) -> np.ndarray:
        """(M,) bool: not dropped."""
        return self.status != DROPPED

    def mark(self, index, status: str, reason: str = "", weight: float | np.ndarray = 0.0) -> None:
        self.status[index], self.reason[index], self.weight[index] = status, reason, weight

    def counts(self) -> dict[str, int]:
        """How many fixes have each status (every status listed)."""
        return {s: int(np.sum(self.status == s)) for s in (USED, DOWN_WEIGHTED, UNUSED, DROPPED)}

    def dropped(self) -> dict[str, list[int]]:
        """The dropped fixes' indices, by reason."""
        return {
            r: np.flatnonzero((self.status == DROPPED) & (self.reason == r)).tolist()
            for r in (NO_POSITION, OUTSIDE, WIDE, REPEAT, JUMP)
            if np.any(self.reason == r)
        }

    def info(self) -> dict:
        """The compact record for :class:`wearnav.fuse.FuseResult` ``info``."""
        return {
            "fix_status": self.counts(),
            "fixes_dropped": {r: len(i) for r, i in self.dropped().items()},
            "fixes_dropped_index": self.dropped(),
        }


def filled_accuracy(accuracy: np.ndarray) -> np.ndarray:
    """The reported accuracy (m), NaN or non-positive ones replaced by the median of the others."""
    acc = np.asarray(accuracy, np.float64)
    ok = np.isfinite(acc) & (acc > 0)
    return np.where(ok, acc, float(np.median(acc[ok])) if ok.any() else FILL_ACCURACY_M)


def repeated_fixes(fix_pos: np.ndarray) -> np.ndarray:
    """True for a fix at exactly the previous fix's position (a stale fix re-reported)."""
    return (
        np.concatenate([[False], np.all(np.diff(fix_pos, axis=0) == 0, axis=1)]) if len(fix_pos) else np.zeros(0, bool)
    )


def _consistent(t, z, margin, i, j, max_speed_m_s: float) -> np.ndarray:
    """Can the walker have been at fix i and at fix j: |z_i − z_j| ≤ v |t_i − t_j| + m_i + m_j."""
    return np.linalg.norm(z[i] - z[j], axis=-1) <= max_speed_m_s * np.abs(t[i] - t[j]) + margin[i] + margin[j]


def jumps(t: np.ndarray, z: np.ndarray, accuracy: np.ndarray, max_speed_m_s: float = MAX_SPEED_M_S) -> np.ndarray:
    """True for each fix (times ``t`` (M,) s increasing, positions ``z`` (M, 2) m, accuracies (M,) m)
    that jumps: consecutive fixes are consistent when the walker can have been at both
    (:func:`_consistent`, each fix's margin ``JUMP_MARGIN`` × its accuracy, at least
    ``JUMP_MIN_ACCURACY_M``); runs of consistent fixes form segments, and the one with most fixes (the
    later one on a tie: cached fixes come first) is trusted. From its ends the fixes are walked
    outwards in time, each kept when consistent with the last kept fix. So a cached start, however
    many fixes long, is judged against the later fixes, and a glitch against the fixes on both sides."""
    n = len(t)
    if n < 2:
        return np.zeros(n, bool)
    acc = JUMP_MARGIN * np.maximum(filled_accuracy(accuracy), JUMP_MIN_ACCURACY_M)
    ok = _consistent(t, z, acc, np.arange(n - 1), np.arange(1, n), max_speed_m_s)
    starts = np.concatenate([[0], np.flatnonzero(~ok) + 1])
    ends = np.append(starts[1:], n)
    k = len(starts) - 1 - int(np.argmax((ends - starts)[::-1]))  # the largest, the latest of equals
    keep = np.zeros(n, bool)
    keep[starts[k] : ends[k]] = True
    last = ends[k] - 1
    for j in range(ends[k], n):
        if _consistent(t, z, acc, last, j, max_speed_m_s):
            keep[j], last = True, j
    first = starts[k]
    for j in range(starts[k] - 1, -1, -1):
        if _consistent(t, z, acc, j, first, max_speed_m_s):
            keep[j], first = True, j
    return ~keep


def check_fixes(t0: float, t1: float, fix_t, fix_pos, fix_accuracy, wide_m: float) -> FixCheck:
    """Every fix's status before a fit (module docstring): the walk spans [``t0``, ``t1``] s,
    fixes at ``fix_t`` (M,) s, ``fix_pos`` (M, 2) m east/north, ``fix_accuracy`` (M,) m."""
    ft = np.asarray(fix_t, np.float64)
    fp = np.asarray(fix_pos, np.float64)
    fp = fp[:, :2] if fp.ndim == 2 and fp.shape[0] else np.empty((len(ft), 2))
    acc = np.asarray(fix_accuracy, np.float64)
    m = len(ft)
    check = FixCheck(np.full(m, USED, dtype=object), np.full(m, "", dtype=object), np.ones(m), [])
    reasons = [
        (NO_POSITION, ~np.all(np.isfinite(fp), axis=1)),
        (OUTSIDE, ~(np.isfinite(ft) & (ft >= t0) & (ft <= t1))),
        (WIDE, np.isfinite(acc) & (acc > wide_m)),
    ]
    for reason, bad in reasons:
        check.mark(check.kept & bad, DROPPED, reason)
    kept = np.flatnonzero(check.kept)
    check.mark(kept[repeated_fixes(fp[kept])], DROPPED, REPEAT)
    kept = np.flatnonzero(check.kept)
    order = kept[np.argsort(ft[kept], kind="stable")]
    jump = jumps(ft[order], fp[order], acc[order])
    if jump.sum() > JUMP_SHARE * len(order):
        check.warnings.append(
            f"{int(jump.sum())} of {len(order)} location fixes jump faster than "
            f"{MAX_SPEED_M_S:g} m/s from the others: they disagree with each other, so none "
            "was dropped for it"
        )
    else:
        check.mark(order[jump], DROPPED, JUMP)
    if m and not check.kept.any() and (check.reason == WIDE).any():
        check.warnings.append(
            f"every usable location fix is wider than {wide_m:g} m (approximate location?): none was used"
        )
    return check


__all__ = [
    "FixCheck",
    "check_fixes",
    "jumps",
    "repeated_fixes",
    "filled_accuracy",
    "MAX_SPEED_M_S",
    "USED",
    "DOWN_WEIGHTED",
    "UNUSED",
    "DROPPED",
    "NO_POSITION",
    "OUTSIDE",
    "WIDE",
    "REPEAT",
    "JUMP",
]
