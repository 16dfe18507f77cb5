"""Smooth scalar building blocks for the kinematics: ramps, bumps and smooth random processes.

Everything here is at least twice continuously differentiable in time, because device
accelerations are second derivatives of positions built from these signals: a kink in a signal
would be an acceleration step, a jump would be an infinite spike.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline

# Mean of Σ B_i(u)² over u for the uniform cubic B-spline: with iid unit coefficients, the
# spline's variance. Dividing by its square root makes ``SmoothNoise.std`` the actual std.
_CUBIC_BSPLINE_VAR = 0.4794


def smootherstep(x) -> np.ndarray:
    """0 for x ≤ 0, 1 for x ≥ 1, C² in between (6x⁵ − 15x⁴ + 10x³)."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def ramp(t, t0: float, t1: float) -> np.ndarray:
    """Smooth 0 → 1 transition over [t0, t1]."""
    return smootherstep((np.asarray(t, dtype=np.float64) - t0) / max(t1 - t0, 1e-9))


def plateau(t, t0: float, t1: float, t2: float, t3: float) -> np.ndarray:
    """0 → 1 over [t0, t1], 1 until t2, 1 → 0 over [t2, t3]."""
    return ramp(t, t0, t1) * (1.0 - ramp(t, t2, t3))


def bump(t, t0: float, t1: float) -> np.ndarray:
    """A C² bump: 0 outside [t0, t1], peak 1 at the middle."""
    w = ramp(t, t0, t1)
    return 4.0 * w * (1.0 - w)


class SmoothNoise:
    """Zero-mean smooth random signal on [t0, t1]: a cubic B-spline with random coefficients.

    ``knot_s`` sets the correlation time (features shorter than about one knot spacing are
    absent), ``std`` the standard deviation. With ``random_walk=True`` the coefficients are a
    Gaussian random walk, so the signal's std grows as ``std · sqrt(t / 1 s)`` (a smooth random
    walk, used for yaw drift and bias instability).
    """

    def __init__(
        self,
        rng: np.random.Generator,
        t0: float,
        t1: float,
        knot_s: float,
        std: float,
        dims: int = 1,
        random_walk: bool = False,
    ):
        n_inner = int(np.ceil((t1 - t0) / knot_s)) + 1
        knots = t0 + knot_s * np.arange(-3, n_inner + 4)
        n_coef = len(knots) - 4
        z = rng.standard_normal((n_coef, dims))
        if random_walk:
            c = std * np.sqrt(knot_s) * np.cumsum(z, axis=0)
            c -= c[1]  # start near zero
        else:
            c = std / np.sqrt(_CUBIC_BSPLINE_VAR) * z
        self.dims = dims
        self._spline = BSpline(knots, c, 3, extrapolate=True)

    def __call__(self, t) -> np.ndarray:
        out = self._spline(np.asarray(t, dtype=np.float64))
        return out[..., 0] if self.dims == 1 else out


class Zero:
    """Stands in for a SmoothNoise that is switched off."""

    def __init__(self, dims: int = 1):
        self.dims = dims

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        return np.zeros(t.shape) if self.dims == 1 else np.zeros(t.shape + (self.dims,))


def smooth_noise(rng, t0, t1, knot_s, std, dims=1, random_walk=False):
    """A SmoothNoise, or a cheap zero signal when ``std`` is 0."""
    if std <= 0:
        return Zero(dims)
    return SmoothNoise(rng, t0, t1, knot_s, std, dims, random_walk)
