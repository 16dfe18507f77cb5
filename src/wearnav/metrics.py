"""Error metrics (DESIGN.md, "Metric definitions": the only definitions; nowhere else).

Positions are metres in a recording's local world frame; "horizontal" means the first two
coordinates (x/east, y/north) whatever the array's width.
"""

from __future__ import annotations

import numpy as np

from wearnav.errors import ValidationError


def _track(t, pos, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    if t.ndim != 1 or pos.ndim != 2 or pos.shape[0] != t.size or pos.shape[1] < 2:
        raise ValidationError(f"{name}: times {t.shape} and positions {pos.shape} do not match "
                              "(expected (N,) and (N, 2 or 3))")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(pos[:, :2]))):
        raise ValidationError(f"{name}: non-finite times or positions")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValidationError(f"{name}: times are not strictly increasing")
    return t, pos[:, :2]


def errors_at_reference(t_est, pos_est, t_ref, pos_ref, max_gap: float) -> np.ndarray:
    """Horizontal distance between an estimate and reference points, at the reference times.

    The estimate is linearly interpolated at each reference time. A reference point is kept only
    if some estimate sample lies within ``max_gap`` seconds of it; reference times just outside
    the estimate's span (but within ``max_gap`` of its first / last sample) take that end
    sample's position, never an extrapolation. Returns one error per kept reference point, in
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
    i = np.searchsorted(t_est, t_ref)
    before = np.abs(t_ref - t_est[np.clip(i - 1, 0, t_est.size - 1)])
    after = np.abs(t_est[np.clip(i, 0, t_est.size - 1)] - t_ref)
    keep = np.minimum(before, after) <= max_gap
    t_k = t_ref[keep]
    interp = np.stack([np.interp(t_k, t_est, p_est[:, k]) for k in range(2)], axis=1)
    return np.linalg.norm(interp - p_ref[keep], axis=1)
