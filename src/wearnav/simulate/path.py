"""The walker's 2-D route and how it is travelled over time.

:func:`plan_route` steers a point through a square area towards random waypoints: straight runs
where the heading is already right, curves of a few metres radius, and sharp turns of about a
metre radius. The curvature profile is smoothed (people turn over a couple of steps) and the
route is re-integrated from it, so heading and position are consistent.

:class:`BaseMotion` moves along the route: speed = preferred speed × slow variation × walking
envelope (0 while standing) × slow-down in tight turns; cadence follows speed (∝ speed^0.5);
gait phase is the integral of cadence. It is sampled on a fine grid and held as a cubic spline,
so it can be evaluated (and differentiated by finite differences) at any time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from wearnav.errors import ConfigError
from wearnav.simulate.config import SubjectParams
from wearnav.simulate.signals import plateau, smooth_noise

GRID_HZ = 200.0  # internal rate of the base motion grid (the spline makes it continuous)
ROUTE_DS = 0.1  # m, arc-length step of the route planner
TURN_SMOOTH_M = 0.4  # std of the Gaussian smoothing of curvature along the route


@dataclass(frozen=True)
class Route:
    """Arc-length parametrised route: heading ``theta(s)`` and curvature ``kappa(s)``."""

    s: np.ndarray
    theta: np.ndarray
    kappa: np.ndarray
    xy: np.ndarray
    area_m: float


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def plan_route(rng: np.random.Generator, area_m: float, length_m: float) -> Route:
    """A smooth route of at least ``length_m`` inside the square [0, area_m]²."""
    for _ in range(20):
        route = _try_route(rng, area_m, length_m)
        lo, hi = route.xy.min(0), route.xy.max(0)
        if lo.min() >= 0.5 and hi.max() <= area_m - 0.5:
            return route
    raise ConfigError(f"could not plan a route inside a {area_m:.0f} m area; use a larger area")


def _try_route(rng, area_m: float, length_m: float) -> Route:
    margin = float(np.clip(0.12 * area_m, 3.0, 12.0))
    r_sharp = (0.6, 1.2)
    r_broad = (2.0, max(2.5, min(12.0, (margin - 1.0) / 1.5)))
    n = int(np.ceil(length_m / ROUTE_DS)) + 2
    meander = smooth_noise(rng, 0, length_m + 1, 6.0, 0.02)(np.arange(n) * ROUTE_DS)

    def waypoint(p):
        for _ in range(100):
            w = rng.uniform(margin, area_m - margin, 2)
            if np.linalg.norm(w - p) > 0.35 * (area_m - 2 * margin):
                return w
        return w

    p = start = rng.uniform(margin, area_m - margin, 2)
    theta = rng.uniform(-np.pi, np.pi)
    wp, radius, budget = p, 1.0, 0
    theta_s = np.empty(n)
    for i in range(n):
        if np.hypot(*(wp - p)) < 1.5 or budget <= 0:
            # next waypoint; give up on it (and pick another) if it is not reached in time,
            # e.g. when it lies inside the turning circle
            wp = waypoint(p)
            radius = rng.uniform(*(r_sharp if rng.uniform() < 0.55 else r_broad))
            budget = int((np.hypot(*(wp - p)) + 2 * np.pi * radius) / ROUTE_DS * 1.5)
        d = wp - p
        err = _wrap(np.arctan2(d[1], d[0]) - theta)
        kappa = float(np.clip(1.2 * err, -1 / radius, 1 / radius)) + meander[i]
        theta += kappa * ROUTE_DS
        p = p + ROUTE_DS * np.array([np.cos(theta), np.sin(theta)])
        theta_s[i] = theta
        budget -= 1
    kappa = gaussian_filter1d(np.gradient(theta_s, ROUTE_DS), TURN_SMOOTH_M / ROUTE_DS)
    s = np.arange(n) * ROUTE_DS
    theta_sm = theta_s[0] + cumulative_trapezoid(kappa, s, initial=0.0)
    xy = start + np.stack(
        [
            cumulative_trapezoid(np.cos(theta_sm), s, initial=0.0),
            cumulative_trapezoid(np.sin(theta_sm), s, initial=0.0),
        ],
        1,
    )
    return Route(s, theta_sm, kappa, xy, area_m)


def turn_slowdown(kappa: np.ndarray) -> np.ndarray:
    """Speed factor in a turn of curvature κ (1/m): people slow down in tight turns."""
    return 1.0 / (1.0 + (0.55 * np.abs(kappa)) ** 2)


class BaseMotion:
    """Horizontal progression, heading, gait phase and walking envelope as smooth functions of t.

    Columns of the spline: x, y (m), heading θ (rad), gait phase φ (rad, 2π per step),
    envelope e (0 standing … 1 walking), speed ratio v/v₀, travelled distance s (m).
    """

    X, Y, THETA, PHASE, ENV, SPEED_RATIO, DIST = range(7)

    def __init__(
        self,
        subject: SubjectParams,
        bouts: list[tuple[float, float]],
        duration: float,
        area_m: float,
        speed_variation: float,
        rng: np.random.Generator,
        ramp_s: float,
    ):
        t = np.arange(-1.0, duration + 1.0 + 1 / GRID_HZ, 1 / GRID_HZ)
        env = np.zeros_like(t)
        for a, b in bouts:
            env += plateau(t, a, a + ramp_s, b - ramp_s, b)
        v0 = subject.speed_mps
        speed_noise = smooth_noise(rng, t[0], t[-1], 12.0, speed_variation)
        v_nom = np.clip(v0 * (1.0 + speed_noise(t)), 0.6, 1.9)
        cadence = subject.cadence_hz * np.sqrt(v_nom / v0)
        phase0 = rng.uniform(0, 2 * np.pi)

        length = float(np.trapezoid(v_nom * env, t)) + 30.0
        route = plan_route(rng, area_m, length)
        kappa_s = CubicSpline(route.s, route.kappa)
        theta_s = CubicSpline(route.s, route.theta)
        # ds/dt = v·e·slowdown(κ(s)): a few fixed-point passes of the integral equation.
        s = cumulative_trapezoid(v_nom * env, t, initial=0.0)
        for _ in range(4):
            speed = v_nom * env * turn_slowdown(kappa_s(np.minimum(s, route.s[-1])))
            s = cumulative_trapezoid(speed, t, initial=0.0)
        theta = theta_s(np.minimum(s, route.s[-1]))
        xy0 = route.xy[0]
        x = xy0[0] + cumulative_trapezoid(speed * np.cos(theta), t, initial=0.0)
        y = xy0[1] + cumulative_trapezoid(speed * np.sin(theta), t, initial=0.0)

        # Step-to-step timing variability: the cadence wanders with a correlation of about one
        # step (drawn after the route so the route of a seed does not depend on it).
        step_noise = smooth_noise(rng, t[0], t[-1], 1.0 / subject.cadence_hz, subject.step_time_cv)
        cadence = cadence * (1.0 + step_noise(t))
        phase = phase0 + 2 * np.pi * cumulative_trapezoid(cadence, t, initial=0.0)

        self.t_grid = t
        self.route = route
        self.cadence_grid = cadence
        self.walking = env > 0.5
        cols = np.stack([x, y, theta, phase, env, v_nom / v0, s], axis=1)
        self._spline = CubicSpline(t, cols, axis=0)

    def __call__(self, t) -> np.ndarray:
        """(N, 7) columns at times t (see the class docstring)."""
        return self._spline(np.asarray(t, dtype=np.float64))

    @property
    def mean_cadence_hz(self) -> float:
        """Mean step frequency over the time spent walking (envelope > 0.5)."""
        return float(self.cadence_grid[self.walking].mean()) if self.walking.any() else 0.0
