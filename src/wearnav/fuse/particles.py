"""The map-aware path: a particle filter over the odometry with the floor plan's walls (issue 36).

Each particle is a hypothesis of where the walker is (x, y in the plan's metric frame), how the
odometry's frame is turned against the plan (θ, a heading offset that drifts slowly: the learned
models' heading errs by 15–25° per walk on unseen buildings, bench real-odometry) and how long the
odometry's steps are (log-scale s: the learned paths run 0.7–0.9 of the true length there). Every
``step_s`` the odometry's displacement d (from the path the model integrated) moves every particle:

    θ ← θ + N(0, σ_θ² Δt),   s ← s + N(0, σ_s² Δt),
    p ← p + e^s R(θ) d + N(0, (σ_rel |d| + σ_abs)²)   (per axis),

a particle whose move ends in, or passes through, a cell that is not walkable
(:class:`wearnav.plans.Walkable`, the move tested at its midpoint and end) has its weight multiplied
by ``wall_penalty`` (soft, not zero: plans are imperfect — 0–1.7 % of ILC2's surveyed points lie
outside the walkable space — and a filter whose particles all die has nothing left), and every
absolute observation between two steps multiplies it by its likelihood: a location fix by a
Student-t in the distance over the fix's σ (indoor fixes carry errors of many σ for minutes: a
Gaussian would let one biased fix collapse the cloud), a beacon reading by the caller's path-loss
model at the particle's 3-D distance to the beacon. Particles are resampled (systematic) when the
effective sample size falls below ``resample_ess`` of their number.

The path returned is not the running mean (which jumps when a hypothesis dies) but the smoothed
one of the surviving lineages: every step's particles and their parents are kept, and the path is
the final weights' mean of each final particle's ancestry (genealogy smoothing: a fixed-interval
smoother by the paths that survived, which respect the walls by construction; its σ is their
weighted spread). Backward simulation (FFBSi, Godsill, Doucet & West 2004: 100 paths drawn
backwards through every step's particles, the wall penalty of each move's midpoint in the backward
kernel) was tried in its place and not kept (Decision: docs/decisions/0027-particle-filter-map-aware.md).
Memory: 12 bytes per particle and step (1000 particles, 2 steps/s, 1 hour: 86 MB).

The constants (:class:`MapConfig`) were chosen on ILC2's training floors (B1, F1, F3), never on
its test floors; what was tried, with its numbers: Decision: docs/decisions/0027-particle-filter-map-aware.md.

Where the walls are the only evidence (a known start, no fix, no beacon: ``track --map --start``)
the scale is not a state but fixed (``walls_only_scale``: with a heading offset the walls keep the
particles that walk short); with fixes or beacons it stays a state.

With a known start and heading, a referee bounds the cloud: a particle farther from the map-less path
than the odometry's measured drift allows costs like a wall; :mod:`wearnav.fuse.mapcheck` reads the
per-step record (``MapResult.steps``) to say whether the path can be trusted (issue 57).

The floor is not a particle state: the caller gives the floor over time (a barometer's floor track,
or the recording's one floor), and each step is constrained by that floor's plan; a floor without
a plan constrains nothing.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from typing import Protocol

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fuse.config import fix_sigma_m

# The odometry's direction of travel at the start (to turn it onto a given start heading) is that of
# its first START_DIR_M metres of path (a step or two is too noisy: the body sways ±10° per step).
START_DIR_M = 3.0


class Walls(Protocol):
    """Where a walker can be: :class:`wearnav.plans.Walkable` (or a plan moved for a test of trust)."""

    def inside(self, xy: np.ndarray) -> np.ndarray: ...


class PathLossModel(Protocol):
    """log p(rssi | 3-D distance, floors between) (:class:`wearnav.fuse.beacons.PathLoss`)."""

    @property
    def floor_height_m(self) -> float: ...

    def loglik(self, rssi_dbm, dist_m, floors=0) -> np.ndarray: ...


@dataclasses.dataclass(frozen=True)
class MapConfig:
    """Every constant of the map-aware filter (saved with its result)."""

    particles: int = 1000
    step_s: float = 0.5  # the odometry's displacement is taken in steps of this length
    start_sigma_m: float = 1.0  # a known start position's σ per axis
    start_heading_sigma_deg: float = 10.0  # a known start heading's σ (10: chosen on ILC2 training floors, below)
    heading_walk_deg_per_sqrt_s: float = 1.0  # the heading offset's random walk (σ after 1 min: 7.7°)
    scale_log_sigma: float = 0.05  # prior σ of the odometry's log-scale (wider shrinks paths: below)
    scale_prior: float = 1.0  # its prior median
    scale_walk_per_sqrt_s: float = 0.005  # the log-scale's random walk
    # Where the filter has no fix and no beacon (a known start: the walls its only evidence), the scale
    # is not a state: every particle takes this one (None: the state above, as with fixes). The walls
    # would select short scales (module docstring); 1.04 was the best of 1.00–1.08 on ILC2's training floors.
    walls_only_scale: float | None = 1.04
    # ... and its heading walk and relative step noise are these (leave one floor of ILC2 site 1 out, five
    # folds, 12 settings each: three folds chose 0.5 °/√s, two 1 °/√s; all five 0.2; decision 0046)
    walls_only_heading_walk_deg_per_sqrt_s: float = 0.5
    walls_only_step_sigma_rel: float = 0.2
    step_sigma_rel: float = 0.1  # noise per step, relative to the step's length, per axis
    step_sigma_m: float = 0.05  # and absolute, per axis (a standing walker's sway)
    wall_penalty: float = 1e-3  # weight factor of a move that ends in, or crosses, non-walkable space
    resample_ess: float = 0.5  # resample when the effective sample size falls below this share
    fix_sigma_scale: float = 1.0  # each fix's σ (from its reported accuracy) times this
    fix_dof: float = 3.0  # Student-t degrees of freedom of a fix's distance over its σ
    # a beacon reading's σ (the path-loss model's, fitted per reading) times this: a phone hears a beacon
    # several times a second at nearly one position, and those readings' errors (multipath there) are
    # not independent. Chosen on IPIN 2023's training walks (31, PDR, user protocol): median / p95
    # 5.89 / 19.34 m at 1, 4.55 / 15.60 at 2, 5.59 / 14.33 at 3.
    beacon_sigma_scale: float = 2.0
    # a fix stamped t is where the walker was at t − fix_lag_s (the smoother's FuseConfig.fix_lag_s:
    # IPIN 2023's fixes lag by 3.5 s on its training walks, wearnav.fuse.fix_lag_of)
    fix_lag_s: float = 0.0
    # A shared offset of the fixes as a state per particle (prior σ 1.5–8 m per axis, random walk
    # 0.01–0.2 m/√s), for indoor fixes that sit metres off for a whole walk, was tried on the same 31
    # training walks (PDR) and not kept: median / p95 5.24–7.60 / 13.35–21.71 m against 4.55 / 15.60
    # without it (probably because the beacons hold the path too loosely to tell the two offsets apart).
    # The referee (issue 57): with a known start and heading, the map-less path from that start bounds where
    # the walker can be: a particle farther from it than max(referee_m, referee_rel × distance walked) costs
    # like a wall. Both are the odometry's own drift, measured (the map-less error's p99 on ILC2 site 1, per
    # distance walked beyond 10 m and within the first 10 m), never a filter tuning: decision 0046. None: off.
    referee_rel: float | None = 0.47
    referee_m: float = 5.7
    # ... and the 95th percentiles (0.31 per metre walked, 4.2 m within 10 m): a path the plan moved further
    # from the odometry than this is doubtful (wearnav.fuse.mapcheck), a warning says so
    doubt_rel: float = 0.31
    doubt_m: float = 4.2
    seed: int = 0

    def __post_init__(self) -> None:
        if self.particles < 10:
            raise ValidationError(f"particles must be at least 10; got {self.particles}")
        if not self.step_s > 0:
            raise ValidationError(f"step_s must be positive; got {self.step_s}")
        if not 0 < self.wall_penalty <= 1:
            raise ValidationError(f"wall_penalty must be in (0, 1]; got {self.wall_penalty}")
        if not self.fix_lag_s >= 0:
            raise ValidationError(f"fix_lag_s must be 0 or more seconds; got {self.fix_lag_s}")
        if self.walls_only_scale is not None and not self.walls_only_scale > 0:
            raise ValidationError(f"walls_only_scale must be positive or None; got {self.walls_only_scale}")


@dataclasses.dataclass
class Beacons:
    """Beacon readings for the filter: times, each reading's beacon position (x, y, floor) and RSSI,
    and the path-loss model giving log p(rssi | 3-D distance)."""

    t: np.ndarray
    pos: np.ndarray  # (N, 3): x, y (m), floor index of the beacon heard
    rssi_dbm: np.ndarray
    model: PathLossModel


@dataclasses.dataclass
class MapResult:
    """The map-aware path at the input times: ``xy`` (N, 2) m, ``sigma_m`` (N,) the surviving lineages'
    weighted spread per axis, ``floor`` (N,) the floor each point was constrained by (NaN: none),
    ``info`` what the filter found and did."""

    xy: np.ndarray
    sigma_m: np.ndarray
    floor: np.ndarray
    info: dict
    steps: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)


def start_heading_offset(t: np.ndarray, xy: np.ndarray, heading_rad: float) -> float:
    """The rotation (rad, counter-clockwise) that turns the odometry's first ``START_DIR_M`` metres
    onto ``heading_rad`` (the direction of travel at the start, counter-clockwise from +x)."""
    d = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    k = int(np.searchsorted(np.cumsum(d), START_DIR_M))
    v = xy[min(k + 1, len(xy) - 1)] - xy[0]
    if not np.linalg.norm(v) > 0:
        return float(heading_rad)
    return float(heading_rad - np.arctan2(v[1], v[0]))


def _systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = w.size
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.searchsorted(c, (rng.random() + np.arange(n)) / n)


def _student_t_loglik(r: np.ndarray, dof: float) -> np.ndarray:
    """log of a 2-D Student-t in the normalised distance r (up to a constant)."""
    return -0.5 * (dof + 2.0) * np.log1p(r * r / dof)


def map_filter(
    t: np.ndarray,
    xy: np.ndarray,
    plans: Mapping[int | None, Walls],
    start_xy: np.ndarray | None,
    heading_offset_rad: float | None,
    floor_at: Callable[[np.ndarray], np.ndarray] | None = None,
    fixes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    beacons: Beacons | None = None,
    cfg: MapConfig = MapConfig(),
    progress: Callable[[int, int], None] | None = None,
) -> MapResult:
    """The map-aware path of the odometry path ``xy`` (N, 2) at times ``t`` (see the module docstring).

    ``plans`` maps a floor index to its rasterised plan (key None: the plan whatever the floor);
    ``floor_at(times) -> floors`` gives the floor over time (None: the plan of key None, or the only
    plan). The start: ``start_xy`` (a known position, σ ``start_sigma_m``) or else the first fix
    (σ its own); ``heading_offset_rad`` the rotation from the odometry's frame into the plan's (σ
    ``start_heading_sigma_deg``), or None: unknown, drawn uniformly (needs fixes or beacons to
    settle). ``fixes`` is (t, pos (M, 2), accuracy (M,)), positions in the plan's frame.
    """
    t0_wall = time.perf_counter()
    t = np.asarray(t, np.float64)
    xy = np.asarray(xy, np.float64)
    if t.size < 2 or xy.shape != (t.size, 2):
        raise ValidationError(f"map_filter needs a path of at least 2 points; got t {t.shape}, xy {xy.shape}")
    rng = np.random.default_rng(cfg.seed)
    n = cfg.particles
    steps = max(1, int(np.ceil((t[-1] - t[0]) / cfg.step_s)))
    tk = np.minimum(t[0] + np.arange(steps + 1) * cfg.step_s, t[-1])
    odo = np.stack([np.interp(tk, t, xy[:, 0]), np.interp(tk, t, xy[:, 1])], axis=1)
    disp = np.diff(odo, axis=0)  # (steps, 2)
    floors = np.asarray(floor_at(tk), np.float64) if floor_at is not None else np.full(tk.size, np.nan)

    fx_t = fx_pos = fx_sig = None
    if fixes is not None and len(fixes[0]):
        ok = np.isfinite(fixes[1]).all(axis=1)
        fx_t, fx_pos = np.asarray(fixes[0])[ok], np.asarray(fixes[1])[ok, :2]
        fx_sig = fix_sigma_m(np.asarray(fixes[2])[ok]) * cfg.fix_sigma_scale

    # ---- the start
    if start_xy is not None:
        pos = np.asarray(start_xy, np.float64)[None, :2] + cfg.start_sigma_m * rng.standard_normal((n, 2))
    elif fx_t is not None and fx_t.size:
        assert fx_pos is not None and fx_sig is not None
        pos = fx_pos[0] + fx_sig[0] * rng.standard_normal((n, 2))
    else:
        raise ValidationError("the map-aware path needs a start: a start position or a location fix")
    if heading_offset_rad is not None:
        theta = heading_offset_rad + np.radians(cfg.start_heading_sigma_deg) * rng.standard_normal(n)
    else:
        theta = rng.uniform(-np.pi, np.pi, n)
    heard = beacons is not None and beacons.t.size > 0
    walls_only = (fx_t is None or not fx_t.size) and not heard and cfg.walls_only_scale is not None
    heading_walk, step_rel = cfg.heading_walk_deg_per_sqrt_s, cfg.step_sigma_rel
    if walls_only:
        assert cfg.walls_only_scale is not None
        log_s, scale_walk = np.full(n, np.log(cfg.walls_only_scale)), 0.0
        heading_walk, step_rel = cfg.walls_only_heading_walk_deg_per_sqrt_s, cfg.walls_only_step_sigma_rel
    else:
        log_s = np.log(cfg.scale_prior) + cfg.scale_log_sigma * rng.standard_normal(n)
        scale_walk = cfg.scale_walk_per_sqrt_s
    logw = np.zeros(n)

    hist = np.empty((steps + 1, n, 2), np.float32)
    parents = np.empty((steps + 1, n), np.int32)
    hist[0] = pos
    parents[0] = np.arange(n)
    sq_dt = np.sqrt(cfg.step_s)
    walls = resamples = refereed = 0
    # the referee: the map-less path from the start (the odometry turned by the start heading) and how far
    # the walker can have drifted from it by each step (MapConfig.referee_rel)
    referee = None
    if start_xy is not None and heading_offset_rad is not None and cfg.referee_rel is not None:
        c0, s0 = np.cos(heading_offset_rad), np.sin(heading_offset_rad)
        referee = (odo - odo[0]) @ np.array([[c0, s0], [-s0, c0]]) + np.asarray(start_xy, np.float64)[:2]
        walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(disp, axis=1))])
        reach = np.maximum(cfg.referee_m, cfg.referee_rel * walked)
    # per step, what the filter saw (the lost test and the diagnostics read them): the effective sample
    # size (share of n) before resampling, the share of the weight the walls took, the cloud's mean and spread
    ess_k = np.ones(steps + 1)
    kill_k = np.zeros(steps + 1)
    mean_k = np.empty((steps + 1, 2))
    spread_k = np.zeros(steps + 1)
    mean_k[0] = pos.mean(axis=0)
    fi = 0
    bi = 0
    ll_wall = np.log(cfg.wall_penalty)

    def plan_of(k: int) -> Walls | None:
        f = floors[k]
        key = None if not np.isfinite(f) else int(round(f))
        return plans.get(key) or (next(iter(plans.values())) if len(plans) == 1 and key is None else plans.get(None))

    for k in range(steps):
        # resample from the previous step's weights where they degenerated
        w = np.exp(logw - logw.max())
        w /= w.sum()
        idx = np.arange(n)
        ess_k[k] = 1.0 / np.sum(w * w) / n
        if ess_k[k] < cfg.resample_ess:
            idx = _systematic(w, rng)
            pos, theta, log_s = pos[idx], theta[idx], log_s[idx]
            logw = np.zeros(n)
            resamples += 1
        parents[k + 1] = idx
        theta = theta + np.radians(heading_walk) * sq_dt * rng.standard_normal(n)
        log_s = log_s + scale_walk * sq_dt * rng.standard_normal(n)
        d = disp[k]
        c, s = np.cos(theta), np.sin(theta)
        sc = np.exp(log_s)
        move = np.stack([sc * (c * d[0] - s * d[1]), sc * (s * d[0] + c * d[1])], axis=1)
        move += (step_rel * float(np.hypot(*d)) + cfg.step_sigma_m) * rng.standard_normal((n, 2))
        new = pos + move
        plan = plan_of(k + 1)
        if plan is not None:
            bad = ~plan.inside(new) | ~plan.inside(pos + 0.5 * move)
            walls += int(bad.sum())
            wk = np.exp(logw - logw.max())
            kill_k[k + 1] = float(wk @ bad) / float(wk.sum())
            logw = logw + ll_wall * bad
        if referee is not None:
            far = np.sum((new - referee[k + 1]) ** 2, axis=1) > reach[k + 1] ** 2
            refereed += int(far.sum())
            logw = logw + ll_wall * far
        pos = new
        # the observations of (tk[k], tk[k + 1]]
        if fx_t is not None:
            assert fx_pos is not None and fx_sig is not None
            while fi < fx_t.size and fx_t[fi] <= tk[k + 1]:
                if fx_t[fi] > tk[k] or k == 0:
                    r = np.linalg.norm(pos - fx_pos[fi], axis=1) / fx_sig[fi]
                    logw = logw + _student_t_loglik(r, cfg.fix_dof)
                fi += 1
        if beacons is not None:
            while bi < beacons.t.size and beacons.t[bi] <= tk[k + 1]:
                b = beacons.pos[bi]
                between = abs((floors[k + 1] if np.isfinite(floors[k + 1]) else b[2]) - b[2])
                dz = between * beacons.model.floor_height_m
                dist = np.sqrt(np.sum((pos - b[:2]) ** 2, axis=1) + dz * dz)
                logw = logw + beacons.model.loglik(beacons.rssi_dbm[bi], dist, between)
                bi += 1
        hist[k + 1] = pos
        wk = np.exp(logw - logw.max())
        wk /= wk.sum()
        mean_k[k + 1] = wk @ pos
        spread_k[k + 1] = np.sqrt(max(0.0, float(wk @ np.sum((pos - mean_k[k + 1]) ** 2, axis=1)) / 2.0))
        if progress is not None:
            progress(k + 1, steps)

    # ---- genealogy smoothing: each final particle's ancestry, weighted by the final weights
    w = np.exp(logw - logw.max())
    w /= w.sum()
    idx = np.arange(n)
    mean = np.empty((steps + 1, 2))
    spread = np.empty(steps + 1)
    for k in range(steps, -1, -1):
        p = hist[k][idx].astype(np.float64)
        mean[k] = w @ p
        spread[k] = np.sqrt(max(0.0, float(w @ np.sum((p - mean[k]) ** 2, axis=1)) / 2.0))
        idx = parents[k][idx]
    out = np.stack([np.interp(t, tk, mean[:, 0]), np.interp(t, tk, mean[:, 1])], axis=1)
    info = {
        "method": "map-aware particle filter",
        "particles": n,
        "steps": steps,
        "resamples": resamples,
        "wall_share": round(walls / (steps * n), 4),
        "referee_share": round(refereed / (steps * n), 4) if referee is not None else None,
        # the share of the weight the walls took per step, on average: near 0 where the walk fits the plan
        "wall_kill_mean": round(float(kill_k[1:].mean()), 4),
        "fixes_used": int(fi) if fx_t is not None else 0,
        "beacon_readings_used": int(bi),
        "scale_median": round(float(np.exp(np.median(log_s))), 4),
        "scale": "fixed (walls only)" if walls_only else "a state",
        "heading_offset_deg": round(float(np.degrees(np.angle(np.sum(w * np.exp(1j * theta))))), 2),
        # how far the walls turned the given start heading by the end (None: no heading was given)
        "heading_turned_deg": None
        if heading_offset_rad is None
        else round(float(np.degrees(np.angle(np.sum(w * np.exp(1j * (theta - heading_offset_rad)))))), 2),
        "seconds": round(time.perf_counter() - t0_wall, 3),
        "config": dataclasses.asdict(cfg),
    }
    ess_k[steps] = 1.0 / np.sum(w * w) / n
    diag = {
        "t": tk,
        "odometry": odo,
        "ess": ess_k,
        "wall_kill": kill_k,
        "filter_xy": mean_k,
        "filter_spread_m": spread_k,
    }
    diag["lineages_left"] = np.asarray(np.unique(idx).size)  # the final cloud's distinct ancestors at the start
    first_plan = plan_of(0)
    if start_xy is not None and first_plan is not None:  # whether the plan has walkable space within the start's σ
        ring = np.exp(1j * np.linspace(0, 2 * np.pi, 16, endpoint=False))
        near = np.concatenate([[0], 0.5 * ring, ring]) * cfg.start_sigma_m
        pts = np.asarray(start_xy, np.float64)[:2] + np.stack([near.real, near.imag], axis=1)
        diag["start_walkable"] = np.asarray(bool(first_plan.inside(pts).any()))
    if referee is not None:
        diag["referee"] = referee
    diag["path_xy"] = mean  # the smoothed path at the steps (the lineages' mean)
    if fx_t is not None and fx_t.size:  # the fixes weighed in, where the walker was when each was taken
        assert fx_pos is not None and fx_sig is not None
        diag["fix_t"], diag["fix_xy"], diag["fix_sigma_m"] = fx_t - cfg.fix_lag_s, fx_pos, fx_sig
    return MapResult(out, np.interp(t, tk, spread), np.interp(t, tk, floors), info, diag)
