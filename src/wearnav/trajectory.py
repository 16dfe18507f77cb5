"""Velocity and displacement integration back to a trajectory (the only place this is done)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from wearnav.errors import ValidationError


def integrate_velocity(t_vel: np.ndarray, vel: np.ndarray, t_out: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Positions at ``t_out`` from window velocities, starting at the true start ``p0``.

    Suite-IN++ eq. (8): y_t = y_{t0} + ∫ v̂ dt, where each sampling moment takes its velocity from
    the window estimates. Here the window estimates (at their centre times ``t_vel``) are
    interpolated linearly to every time of ``t_out`` (held constant before the first and after the
    last centre) and integrated with the trapezoid rule; ``p0`` is the position at ``t_out[0]``.
    """
    t_vel = np.asarray(t_vel, np.float64)
    vel = np.asarray(vel, np.float64)
    t_out = np.asarray(t_out, np.float64)
    if vel.ndim != 2 or vel.shape[0] != t_vel.size or t_vel.size == 0:
        raise ValidationError(f"velocity shape {vel.shape} does not match {t_vel.size} times")
    if np.any(np.diff(t_vel) <= 0) or np.any(np.diff(t_out) <= 0):
        raise ValidationError("integration times must be strictly increasing")
    if not (np.all(np.isfinite(vel)) and np.all(np.isfinite(t_vel)) and np.all(np.isfinite(t_out))):
        raise ValidationError(
            "velocities or times are not finite (NaN or inf); a path cannot be integrated through them"
        )
    v = np.stack([np.interp(t_out, t_vel, vel[:, k]) for k in range(vel.shape[1])], axis=1)
    return np.asarray(p0, np.float64)[None, :] + cumulative_trapezoid(v, t_out, axis=0, initial=0.0)


def integrate_displacements(disp: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Positions (N+1, d) at the segment boundaries from N consecutive segment displacements."""
    disp = np.asarray(disp, np.float64)
    return np.concatenate([np.asarray(p0, np.float64)[None, :], p0 + np.cumsum(disp, axis=0)], axis=0)
