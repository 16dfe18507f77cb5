"""Error metrics (DESIGN.md, "Metric definitions": the only definitions; nowhere else).

Positions are metres in a recording's local world frame; "horizontal" means the first two
coordinates (x/east, y/north) whatever the array's width.

Decisions: docs/decisions/0008-label-noise-model.md, docs/decisions/0024-speed-heading-along-across.md.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from wearnav.core.timeseries import interp_onto
from wearnav.errors import ValidationError


def _track(t, pos, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    if t.ndim != 1 or pos.ndim != 2 or pos.shape[0] != t.size or pos.shape[1] < 2:
        raise ValidationError(
            f"{name}: times {t.shape} and positions {pos.shape} do not match (expected (N,) and (N, 2 or 3))"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(pos[:, :2]))):
        raise ValidationError(f"{name}: non-finite times or positions")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValidationError(f"{name}: times are not strictly increasing")
    return t, pos[:, :2]


# The one gap rule for a phone's location fixes (seconds), used by every reader of fixes: fixes are
# interpolated across a fix-to-fix gap of at most this (``fixlabels``, timeseries rule "hole"), and
# a surveyed point is scored against the fixes only if one lies within this of it (fix error at
# reference points, rule "nearest"). Phones fix at 1 Hz: of IPIN 2023's 7739 fix-to-fix gaps 7646
# are 1.0 s, 20 are one missed fix (19 × 2.000 s, one 2.022 s), the next longest 3.0 s (9 of them);
# 2.5 s bridges one missed fix with room for clock jitter and never two (≥ 3 s: an outage).
FIX_MAX_GAP_S = 2.5


def errors_at_reference(t_est, pos_est, t_ref, pos_ref, max_gap: float) -> np.ndarray:
    """Horizontal distance between an estimate and reference points, at the reference times.

    The estimate is linearly interpolated at each reference time. A reference point is kept only
    if some estimate sample lies within ``max_gap`` seconds of it (gap rule ``"nearest"`` of
    :func:`wearnav.core.timeseries.interp_onto`); reference times just outside the estimate's span
    (but within ``max_gap`` of its first / last sample) take that end sample's position, never an
    extrapolation. Returns one error per kept reference point, in
    reference order (possibly empty, never NaN).

    This is how sparse ground truth is scored (DESIGN.md: "errors are taken at the waypoint
    times only"), e.g. phone GNSS fixes at surveyed reference points.
    """
    t_est, p_est = _track(t_est, pos_est, "estimate")
    t_ref, p_ref = _track(t_ref, pos_ref, "reference")
    if not max_gap >= 0:
        raise ValidationError(f"max_gap must be >= 0 seconds, got {max_gap}")
    if t_est.size == 0 or t_ref.size == 0:
        return np.empty(0)
    p_at_ref, keep = interp_onto(t_ref, t_est, p_est, max_gap=max_gap, rule="nearest")
    return np.linalg.norm(p_at_ref[keep] - p_ref[keep], axis=1)


def along_cross_errors(t_est, pos_est, t_ref, pos_ref, max_gap: float) -> tuple[np.ndarray, np.ndarray]:
    """The error of :func:`errors_at_reference` at the same reference points, split along the walk
    and across it: ``(along, cross)`` in metres, ``hypot(along, cross)`` the error.

    The walk's direction at reference point k is that of the reference from point k − 1 to point
    k + 1 (from k to k + 1 at the first point, from k − 1 to k at the last): at a turn, the turn's
    bisector. ``along`` is the error's component in that direction (positive: the estimate is ahead
    of the walker), ``cross`` its component to the walker's left (counter-clockwise from the
    direction: positive left). Where the reference does not move between those points (a standing
    walker) there is no direction, and both are NaN. A plan corrects a path across a corridor
    (``cross``) everywhere, along it only where the corridor turns or ends (issue 36).
    """
    t_est, p_est = _track(t_est, pos_est, "estimate")
    t_ref, p_ref = _track(t_ref, pos_ref, "reference")
    if not max_gap >= 0:
        raise ValidationError(f"max_gap must be >= 0 seconds, got {max_gap}")
    if t_est.size == 0 or t_ref.size == 0:
        return np.empty(0), np.empty(0)
    ahead = p_ref[np.minimum(np.arange(1, len(p_ref) + 1), len(p_ref) - 1)]
    behind = p_ref[np.maximum(np.arange(-1, len(p_ref) - 1), 0)]
    d = ahead - behind
    norm = np.linalg.norm(d, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(norm[:, None] > 0, d / norm[:, None], np.nan)
    p_at_ref, keep = interp_onto(t_ref, t_est, p_est, max_gap=max_gap, rule="nearest")
    e, u = p_at_ref[keep] - p_ref[keep], u[keep]
    return e[:, 0] * u[:, 0] + e[:, 1] * u[:, 1], u[:, 0] * e[:, 1] - u[:, 1] * e[:, 0]


# A segment between surveyed points shorter than this (m) has no direction worth scoring: the
# surveyed points' own error (decimetres) would dominate its angle.
MIN_SEGMENT_M = 1.0


def segment_speed_heading(t_est, pos_est, t_ref, pos_ref, min_length_m: float = MIN_SEGMENT_M) -> dict:
    """An estimate's error split into speed and heading between consecutive reference points.

    For each pair of consecutive reference points inside the estimate's time span, with the
    reference moving at least ``min_length_m`` between them: the estimate's displacement over the
    same interval (linear interpolation at both times) against the reference's. Returns arrays
    (one entry per segment): ``t0_s``, ``t1_s``, ``true_speed_m_s`` (reference length / duration),
    ``speed_ratio`` (estimate length / reference length: below 1 the path is short) and
    ``heading_error_deg`` (the estimate's direction minus the reference's, counter-clockwise
    positive, wrapped to (−180, 180]).
    """
    t_est, p_est = _track(t_est, pos_est, "estimate")
    t_ref, p_ref = _track(t_ref, pos_ref, "reference")
    keys = ("t0_s", "t1_s", "true_speed_m_s", "speed_ratio", "heading_error_deg")
    inside = (t_ref >= t_est[0]) & (t_ref <= t_est[-1]) if t_est.size else np.zeros(len(t_ref), bool)
    t_ref, p_ref = t_ref[inside], p_ref[inside]
    if len(t_ref) < 2:
        return {k: np.empty(0) for k in keys}
    at = np.stack([np.interp(t_ref, t_est, p_est[:, j]) for j in range(2)], axis=1)
    d_true, d_est, dt = np.diff(p_ref, axis=0), np.diff(at, axis=0), np.diff(t_ref)
    length = np.linalg.norm(d_true, axis=1)
    k = (length >= min_length_m) & (dt > 0)
    ang = np.arctan2(d_est[:, 1], d_est[:, 0]) - np.arctan2(d_true[:, 1], d_true[:, 0])
    ang = -np.degrees(np.angle(np.exp(-1j * ang)))  # wrapped to (−180, 180]
    return {
        "t0_s": t_ref[:-1][k],
        "t1_s": t_ref[1:][k],
        "true_speed_m_s": (length / np.where(dt > 0, dt, 1.0))[k],
        "speed_ratio": (np.linalg.norm(d_est, axis=1) / np.where(length > 0, length, 1.0))[k],
        "heading_error_deg": ang[k],
    }


def label_noise(t_fix, pos_fix, t_true, pos_true, max_gap: float = np.inf) -> np.ndarray:
    """|d_e| of each segment between consecutive location fixes (EasyTrack, paper 004, eqs. 5–7).

    A phone label is the displacement between two fixes, d̃_i = P̃_{i+1} − P̃_i; its noise is
    d_e,i = d_i − d̃_i (eq. 5) = P_e,i+1 − P_e,i (eq. 6), the increment of the fixes' position
    error, so consecutive noises are dependent (eq. 7). Returns ‖d_e,i‖ (horizontal, metres) for
    every pair of consecutive fixes at which the truth is known: truth interpolated at the fix
    times, across truth gaps of at most ``max_gap`` seconds (default: any gap, the truth is taken
    as a continuous path). Fixes without truth are skipped and their neighbours paired.
    """
    t_fix, p_fix = _track(t_fix, pos_fix, "fixes")
    t_true, p_true = _track(t_true, pos_true, "truth")
    if t_fix.size == 0 or t_true.size == 0:
        return np.empty(0)
    p_true_at_fix, inside = interp_onto(t_fix, t_true, p_true, max_gap=max_gap)
    d_true = np.diff(p_true_at_fix[inside], axis=0)
    d_fix = np.diff(p_fix[inside], axis=0)
    return np.linalg.norm(d_true - d_fix, axis=1)


def label_noise_correlation(noise, consecutive) -> tuple[float, float]:
    """Pearson r per horizontal axis between the label noise of consecutive segments (EasyTrack
    eq. 7: d_e,i = P_e,i+1 − P_e,i and d_e,i+1 share the fix error P_e,i+1 with opposite signs, so
    white fix errors give r = −0.5; slowly wandering errors give increments near r = 0).

    ``noise`` (n, 2) are the vectors d_e of eq. 5; ``consecutive`` the indices i (into ``noise``)
    whose segment i+1 follows on the same trajectory and fix. Pairs with a NaN are skipped; fewer
    than 3 pairs give NaN."""
    e = np.asarray(noise, dtype=np.float64)
    i = np.asarray(consecutive, dtype=np.int64)
    if e.ndim != 2 or e.shape[1] < 2 or (i.size and (i.min() < 0 or i.max() + 1 >= e.shape[0])):
        raise ValidationError(f"label-noise correlation needs (n, 2) noise and indices in [0, n-1), got {e.shape}")
    i = i[np.isfinite(e[i, :2]).all(1) & np.isfinite(e[i + 1, :2]).all(1)]
    if i.size < 3:
        return float("nan"), float("nan")
    rx, ry = (float(np.corrcoef(e[i, k], e[i + 1, k])[0, 1]) for k in (0, 1))
    return rx, ry


def _common(t, pos_est, pos_true) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    est = np.asarray(pos_est, dtype=np.float64)
    true = np.asarray(pos_true, dtype=np.float64)
    if est.shape != true.shape:
        raise ValidationError(f"estimate {est.shape} and truth {true.shape} differ in shape")
    t, est = _track(t, est, "estimate")
    _, true = _track(t, true, "truth")
    if t.size == 0:
        raise ValidationError("empty trajectory")
    return t, est, true


def position_errors(t, pos_est, pos_true) -> np.ndarray:
    """Per-timestamp horizontal position error ‖p̂(t) − p(t)‖ at common timestamps."""
    _, est, true = _common(t, pos_est, pos_true)
    return np.linalg.norm(est - true, axis=1)


def ate(t, pos_est, pos_true) -> float:
    """Absolute trajectory error: RMS of the 2-D position error at common timestamps, with no
    alignment (the estimate starts at the true start; DESIGN.md "Metric definitions")."""
    e = position_errors(t, pos_est, pos_true)
    return float(np.sqrt(np.mean(e**2)))


def rte(t, pos_est, pos_true, delta: float = 60.0) -> float:
    """Relative trajectory error over ``delta`` seconds (DESIGN.md "Metric definitions").

    For every start time t_i with t_i + Δ inside the sequence, e_i = ‖(p̂(t_j) − p̂(t_i)) −
    (p(t_j) − p(t_i))‖ where t_j is the first sample at or after t_i + Δ (exactly t_i + Δ on a
    uniform clock whose period divides Δ); RTE = RMS of e. A sequence shorter than Δ uses its
    whole length once and scales that error by Δ / length (RoNIN's convention).
    """
    if not delta > 0:
        raise ValidationError(f"RTE delta must be positive seconds, got {delta}")
    t, est, true = _common(t, pos_est, pos_true)
    length = t[-1] - t[0]
    if length <= 0:
        raise ValidationError("RTE needs a trajectory spanning a positive time")
    tol = 1e-9 * max(1.0, abs(t[-1]))
    if length + tol < delta:
        e = (est[-1] - est[0]) - (true[-1] - true[0])
        return float(np.linalg.norm(e) * delta / length)
    j = np.searchsorted(t, t + delta - tol)
    i = np.flatnonzero(j < t.size)
    j = j[i]
    e = (est[j] - est[i]) - (true[j] - true[i])
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def ecdf(values) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF of a sample (``scipy.stats.ecdf``): its distinct values ascending and
    P(X ≤ x) at each, a right-continuous step function (draw it with
    :func:`wearnav.report.plots.plot_ecdf`). Every CDF of wearnav (position errors, label
    noise, fix statistics) comes from here.

    >>> ecdf([3.0, 1.0, 2.0, 2.0])
    (array([1., 2., 3.]), array([0.25, 0.75, 1.  ]))
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0 or not np.all(np.isfinite(v)):
        raise ValidationError("an empirical CDF needs at least one value, all finite")
    cdf = stats.ecdf(v).cdf
    return cdf.quantiles, cdf.probabilities


def ade(disp_est, disp_true) -> float:
    """Average displacement error: mean Euclidean error of per-segment displacements (EasyTrack)."""
    est = np.asarray(disp_est, dtype=np.float64)
    true = np.asarray(disp_true, dtype=np.float64)
    if est.shape != true.shape or est.ndim != 2 or est.shape[0] == 0:
        raise ValidationError(f"ADE needs matching (N, 2) displacements, got {est.shape} and {true.shape}")
    return float(np.mean(np.linalg.norm(est[:, :2] - true[:, :2], axis=1)))


# ---- classification (activity / placement recognition, paper 002 Sec. III) -------------------


def _labels(y_true, y_pred, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(y_true, dtype=np.int64).ravel()
    p = np.asarray(y_pred, dtype=np.int64).ravel()
    if t.shape != p.shape or t.size == 0:
        raise ValidationError(f"classification metrics need matching non-empty labels, got {t.shape} and {p.shape}")
    if n_classes < 1 or t.min() < 0 or p.min() < 0 or max(t.max(), p.max()) >= n_classes:
        raise ValidationError(f"class indices must lie in [0, {n_classes})")
    return t, p


def confusion_matrix(y_true, y_pred, n_classes: int) -> np.ndarray:
    """Counts C[i, j] of windows of true class i predicted as class j."""
    t, p = _labels(y_true, y_pred, n_classes)
    return np.bincount(t * n_classes + p, minlength=n_classes**2).reshape(n_classes, n_classes)


def accuracy(y_true, y_pred, n_classes: int) -> float:
    """Share of windows whose predicted class is the true one."""
    c = confusion_matrix(y_true, y_pred, n_classes)
    return float(np.trace(c) / c.sum())


def macro_f1(y_true, y_pred, n_classes: int) -> float:
    """Unweighted mean over classes of F1 = 2·TP / (2·TP + FP + FN), over the classes that occur
    in the truth or the predictions (a class absent from both is not scored; one predicted but
    never true scores 0)."""
    c = confusion_matrix(y_true, y_pred, n_classes).astype(np.float64)
    tp = np.diag(c)
    fp = c.sum(axis=0) - tp
    fn = c.sum(axis=1) - tp
    seen = (c.sum(axis=0) + c.sum(axis=1)) > 0
    return float(np.mean(2 * tp[seen] / (2 * tp[seen] + fp[seen] + fn[seen])))
