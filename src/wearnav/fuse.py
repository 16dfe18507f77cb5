"""Fusing an odometry path with every location fix of a walk (issue 25): the path a user gets.

The odometry (a learned model or PDR, integrated from (0, 0) in an arbitrary horizontal frame)
has a good shape but an unknown heading, a scale that is often off (learned paths run ~17 %
short on unseen buildings) and a heading that drifts slowly. The phone's fixes have the right
frame but are biased for minutes at a time indoors. The smoother estimates, by robust nonlinear
least squares (:func:`scipy.optimize.least_squares`, a 2-D Cauchy loss per fix):

``heading_offset``  θ (rad), the rotation from the odometry frame to east/north;
``scale``           s, on every odometry displacement, with a log-normal prior (``scale_prior``,
                    ``scale_prior_log_sigma``);
``heading_drift``   ω (rad/s) about the walk's middle time, with a zero-mean prior; where the
                    recording's world frame is north-referenced (:func:`known_heading_deg`), the
                    heading at the start has a prior too (``heading_prior_deg`` ± ``heading_prior_sigma_deg``):
                    on IPIN's training walks the fixes alone turned the path 10–170° off on a third of them;
``heading walk``    h(t) (rad), a random walk at knots every ``bias_knot_s`` seconds (σ
                    ``heading_walk_deg_per_sqrt_min`` per √min), linear in between, h = 0 at the start;
``odometry walk``   e(t) (m), the odometry's position error, a random walk at the same knots
                    (σ ``odometry_walk_m_per_sqrt_s`` per √s), e = 0 at the start;
``origin``          o (m), where the path starts;
``fix bias``        b(t) (m), the fixes' slowly varying error: a Gauss–Markov process (stationary
                    σ ``bias_sigma_m``, correlation ``bias_correlation_s``) at the same knots.

so that, with d_j the odometry displacement between 1-s nodes (``node_s``) at time t_j,

    p_i = o + s Σ_{j<i} R(θ + ω (t_j − t_mid) + h(t_j)) d_j + e(t_i),
    fix k:  z_k ≈ p(t_k − fix_lag_s) + b(t_k) + n_k,

n_k ~ N(0, σ_k² I), σ_k = reported accuracy / 1.515 (the accuracy is a 68 % radius, as
:mod:`wearnav.simulate.fixes` models it; NaN accuracy takes the median of the others; fixes wider
than ``wide_m`` are dropped, below). Where the fixes and the path disagree, the
priors share the difference between the fix bias b (bounded, minutes long) and the odometry's
errors (h and e, growing with time): a trial that let every 1-s position follow its fixes with
a free scale came out worse than a rigid fit on unseen walks (issue 25), so the path moves only
through these few slow unknowns, and the scale has a tight prior (the fixes indoors move less
than the walker: their path-length ratio on IPIN's walks is 0.67, and a loose scale shrinks the
path with them). The defaults were chosen on IPIN 2023's training walks (PDR and Suite-IN++)
and the simulator, never on the benchmark's held-out routes (:mod:`wearnav.bench.user_protocol`).
The Jacobian is by finite differences over a sparsity pattern; a one-hour walk (3600 fixes)
takes about 3 s on one core.

Before any fit, every fix is classified by :func:`wearnav.fixcheck.check_fixes` (issue 18 §5): a
NaN position, a time outside the walk, an accuracy wider than ``wide_m``, a stale repeat of the
previous fix (a phone re-reporting its last fix says nothing new) or a jump no walker could make
(a cached first fix hundreds of metres away) is dropped, with its reason, in all three
anchorings; the rest are marked used, or down-weighted where the robust loss gives them less than a
fifth of a weight (smoother), or unused (first-fix anchoring, after its first minute).
:attr:`FuseResult.fixes` holds the status, reason and weight of every fix given; ``info`` the
counts (``fix_status``, ``fixes_dropped`` by reason, ``fixes_dropped_index``). Fallbacks, each said
in the result's ``warnings``: no kept fix inside the walk → the path is returned unmoved (from
(0, 0)); one fix, or fixes that do not spread (all identical) → translation onto them only; most
fixes down-weighted (they disagree with the odometry and each other) → the first-fix anchoring of
:func:`first_fix_anchor`.

:class:`wearnav.fuse_live.IncrementalFuser` is the same estimate as a fixed-lag smoother for the live receiver:
each update solves only the last ``lag_s`` seconds, the walk before them marginalised into a
Gaussian prior on the window's start state, so its cost does not grow with the session (a
1-hour synthetic walk, 50-Hz odometry, 1-Hz fixes, an update every 10 s, 300-s window, one core:
median 71 ms / p95 97 ms per update, 73 ms in the walk's first tenth and 75 ms in its last,
where re-solving the whole hour takes 3.3 s; the final path within 0.14 m median / 0.90 m p95
of the batch smoother's). It is scipy rather than GTSAM's IncrementalFixedLagSmoother because the model's
global unknowns (scale, heading offset, drift) and its heading random walk act on every later
position through a cumulative sum, which in GTSAM needs Python-side custom factors (slow, a second
copy of the model to keep equal); here batch and fixed-lag share one residual function.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from wearnav.errors import FormatError, ValidationError
from wearnav.fixcheck import (DOWN_WEIGHTED, NO_POSITION, OUTSIDE, REPEAT, UNUSED, USED, WIDE, FixCheck,
                              check_fixes)
from wearnav.recording import ANDROID_ENU_FRAME
from wearnav.textio import read_json

log = logging.getLogger(__name__)

RADIUS_68 = 1.515  # 68 % radius of a unit circular Gaussian (accuracy = RADIUS_68 · σ per axis)
RAYLEIGH_MEDIAN = float(np.sqrt(2 * np.log(2)))  # its median radius
MIN_SIGMA_M = 0.5  # no fix is trusted to better than this per axis (phones report 1–3 m at best)
ANCHOR_S = 60.0  # first-fix anchoring: fixes of the first minute (today's `track`)
MIN_SPREAD_M = 5.0  # below this weighted RMS spread the heading is not observable from fixes
DOWNWEIGHT = 0.2  # a fix whose robust weight falls below this (|r| > 2 c) counts as down-weighted
DISAGREE_SHARE = 0.5  # more than this share down-weighted: the fixes disagree, fall back
# The fix-error model measured on IPIN 2023's training walks (1-Hz fixes at the surveyed points):
# the error per axis is the reported accuracy / RADIUS_68 (median ratio 0.98) and almost all of it
# is correlated, falling to 0.83 / 0.57 / 0.32 / 0.08 at lags of 6 / 15 / 25 / 74 s (about 20 s).
# Opt-in: on those walks it helped Suite-IN++ (median 4.63 → 4.37 m) and not PDR (4.44 → 4.56 m).
MEASURED_FIX_BIAS = {"bias_share": 0.9, "bias_correlation_s": 20.0, "bias_knot_s": 10.0}
CALIBRATION_JSON = "fuse_calibration.json"  # in a run folder: the model's odometry_walk_sigma and sigma_scale_of


@dataclasses.dataclass(frozen=True)
class FuseConfig:
    """Every constant of the smoother (saved with its result)."""

    node_s: float = 1.0  # spacing of the path's nodes, s
    scale_prior: float = 1.0  # prior median of the odometry's scale
    scale_prior_log_sigma: float = 0.05  # σ of log(scale): ±5 % at 1 σ (looser let indoor fixes, which
    # move less than the walker, shrink the path: IPIN training walks, PDR, docs in the module)
    drift_sigma_rad_s: float = np.radians(10.0) / 600.0  # heading drift prior: 10° per 10 min at 1 σ
    bias_sigma_m: float = 3.0  # stationary σ per axis of the fixes' slowly varying error
    bias_correlation_s: float = 120.0  # its correlation time (GNSS errors wander over minutes)
    bias_knot_s: float = 30.0  # knot spacing of the bias, s
    robust_scale: float = 2.0  # Cauchy loss scale on the normalised fix residual (|r|/σ)
    wide_m: float = 100.0  # fixes reporting a wider accuracy are dropped (wearnav.fixcheck)
    fix_lag_s: float = 0.0  # a fix stamped t describes where the walker was at t − fix_lag_s
    heading_walk_deg_per_sqrt_min: float = 5.0  # random-walk heading error between bias knots (0: off)
    odometry_walk_m_per_sqrt_s: float = 0.3  # random-walk position error of the odometry at the knots (0: off)
    heading_prior_deg: float | None = None  # the odometry frame's known yaw to east/north (a north-referenced
    # orientation: 0), None: unknown (the fixes alone give the heading offset)
    heading_prior_sigma_deg: float = 15.0  # its 1-σ (magnetic disturbance indoors, declination, the model's bias)
    sigma_scale: float = 1.0  # each point's σ is the model's times this (calibrated where the model is used:
    # sigma_scale_of; the fit itself does not change)
    bias_share: float = 0.0  # 0: the bias has σ bias_sigma_m and each fix its full σ. In (0, 1): that share of
    # each fix's error variance is the bias (σ √share · the fixes' median σ), the rest white (module docs)

    def __post_init__(self):
        if not 0.0 <= self.bias_share < 1.0:
            raise ValidationError(f"bias_share must be in [0, 1); got {self.bias_share}")
        if not self.sigma_scale > 0:
            raise ValidationError(f"sigma_scale must be positive; got {self.sigma_scale}")


@dataclasses.dataclass
class FuseResult:
    """The fused path and what the fit found. ``xy`` (N, 2) m east/north at the input times;
    ``sigma_m`` (N,) its 1-σ per-axis uncertainty (m, NaN unknown) from the fit's covariance
    (:func:`node_sigma`) times ``sigma_scale``: the model's alone is right where the fixes' and the
    odometry's errors follow the model and too small on IPIN 2023's indoor walks (their fix errors
    are more correlated), so the scale is calibrated where the model is used (:func:`sigma_scale_of`).
    ``fixes``: the status, reason and weight of every fix given (:class:`wearnav.fixcheck.FixCheck`)."""

    xy: np.ndarray
    sigma_m: np.ndarray
    method: str
    info: dict
    warnings: list[str]
    fixes: FixCheck | None = None


def fix_sigma_m(accuracy: np.ndarray) -> np.ndarray:
    """Per-axis σ (m) of each fix from its reported accuracy (a 68 % radius); NaN or non-positive
    accuracy takes the median of the others (1.0 m if none is known)."""
    acc = np.asarray(accuracy, np.float64)
    ok = np.isfinite(acc) & (acc > 0)
    fill = float(np.median(acc[ok])) if ok.any() else RADIUS_68
    return np.maximum(np.where(ok, acc, fill) / RADIUS_68, MIN_SIGMA_M)


def rigid_fit(p: np.ndarray, q: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Weighted 2-D Procrustes (rotation + translation, Umeyama 1991) mapping points ``p`` (n, 2)
    onto ``q`` (n, 2) with weights ``w`` (n,): returns yaw (rad), offset (2,) and the weighted RMS
    spread of ``p`` about its centre (m)."""
    pm, qm = np.average(p, axis=0, weights=w), np.average(q, axis=0, weights=w)
    pc, qc = p - pm, q - qm
    cross = np.sum(w * (pc[:, 0] * qc[:, 1] - pc[:, 1] * qc[:, 0]))
    dot = np.sum(w * np.sum(pc * qc, axis=1))
    yaw = float(np.arctan2(cross, dot))
    offset = qm - _rot(yaw) @ pm
    return yaw, offset, float(np.sqrt(np.average(np.sum(pc ** 2, axis=1), weights=w)))


def _rot(yaw: float) -> np.ndarray:
    return np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])


def _kept(t: np.ndarray, fix_t, fix_pos, fix_accuracy, wide_m: float):
    """The fixes' check (:func:`wearnav.fixcheck.check_fixes`), the indices of the kept ones in
    time order, and their times, positions (M, 2) and accuracies; the record of the counts."""
    check = check_fixes(t[0], t[-1], fix_t, fix_pos, fix_accuracy, wide_m)
    ft = np.asarray(fix_t, np.float64)
    k = np.flatnonzero(check.kept)
    k = k[np.argsort(ft[k], kind="stable")]
    fp = np.asarray(fix_pos, np.float64)[k, :2] if k.size else np.empty((0, 2))
    acc = np.asarray(fix_accuracy, np.float64)
    inside = int(np.sum(check.reason != NO_POSITION) - np.sum(check.reason == OUTSIDE))
    facts = {"fixes": inside, "fixes_outside_span": int(len(ft) - inside),
             "fixes_nan_accuracy": int(np.sum(~(np.isfinite(acc[k]) & (acc[k] > 0)))),
             "fixes_wide": int(np.sum(check.reason == WIDE)),
             "fixes_repeated": int(np.sum(check.reason == REPEAT))}
    return check, k, ft[k], fp, acc[k], facts


def first_fix_anchor(t: np.ndarray, xy: np.ndarray, fix_t, fix_pos, fix_accuracy,
                     cfg: FuseConfig = FuseConfig()) -> FuseResult:
    """Today's anchoring: a rigid fit over the kept fixes (bad ones dropped first) of the first
    ``ANCHOR_S`` seconds after the first kept fix (more while the path spreads less than
    ``MIN_SPREAD_M`` over them)."""
    return _anchored(t, xy, fix_t, fix_pos, fix_accuracy, ANCHOR_S, cfg)


def rigid_anchor(t: np.ndarray, xy: np.ndarray, fix_t, fix_pos, fix_accuracy,
                 cfg: FuseConfig = FuseConfig()) -> FuseResult:
    """One rotation + translation fitted to every kept fix of the walk, weighted by 1/σ²."""
    return _anchored(t, xy, fix_t, fix_pos, fix_accuracy, None, cfg)


def _anchored(t, xy, fix_t, fix_pos, fix_accuracy, first_s: float | None, cfg: FuseConfig) -> FuseResult:
    t, xy = np.asarray(t, np.float64), np.asarray(xy, np.float64)
    check, k, ft, fp, acc, facts = _kept(t, fix_t, fix_pos, fix_accuracy, cfg.wide_m)
    res = _rigid(t, xy, ft, fp, acc, first_s)
    return _with_fixes(res, check, k, facts)


def _with_fixes(res: FuseResult, check: FixCheck, k: np.ndarray, facts: dict,
                weight: np.ndarray | None = None) -> FuseResult:
    """``res`` with the per-fix statuses of the kept fixes ``k`` (the first ``fixes_used`` used by
    a rigid fit; by their robust ``weight`` for the smoother) and the counts in its info."""
    if weight is not None:
        down = weight < DOWNWEIGHT
        check.mark(k[~down], USED, weight=weight[~down])
        check.mark(k[down], DOWN_WEIGHTED, f"robust weight below {DOWNWEIGHT:g}", weight[down])
    elif k.size:
        n = res.info.get("fixes_used", len(k))
        check.mark(k[:n], USED, weight=1.0)
        if n < len(k):
            check.mark(k[n:], UNUSED, f"after the first {res.info['span_s']:.0f} s of good fixes")
    res.info.update({**facts, **check.info()})
    if res.method == "none" and (dropped := res.info["fixes_dropped"]):
        res.warnings[0] += f" (every fix dropped: {', '.join(f'{n} {r}' for r, n in dropped.items())})"
    res.warnings[:0] = check.warnings
    res.fixes = check
    return res


def _rigid(t, xy, ft, fp, acc, first_s: float | None) -> FuseResult:
    """The rigid fit over kept fixes (times ``ft`` increasing, ``fp`` (M, 2), ``acc`` (M,))."""
    method = "first-fixes" if first_s is not None else "rigid"
    nan = np.full(len(t), np.nan)
    if ft.size == 0:
        return FuseResult(xy.copy(), nan, "none", {"fixes_used": 0},
                          ["no location fix inside the walk: the path starts at (0, 0) in the odometry's own frame"])
    w = 1.0 / fix_sigma_m(acc) ** 2
    p = np.stack([np.interp(ft, t, xy[:, k]) for k in range(2)], axis=1)
    n = len(ft) if first_s is None else min(len(ft), max(2, int(np.sum(ft <= ft[0] + first_s))))
    while True:
        yaw, offset, spread = rigid_fit(p[:n], fp[:n], w[:n])
        if spread >= MIN_SPREAD_M or n >= len(ft):
            break
        n += 1
    warn = []
    if len(ft) < 2 or spread < 1e-6:
        yaw = 0.0
        offset = np.average(fp, axis=0, weights=w) - np.average(p, axis=0, weights=w)
        warn.append(f"{len(ft)} location fix(es) under a path that does not move: heading unknown, "
                    "the path is only shifted onto them")
    out = xy @ _rot(yaw).T + offset
    resid = p[:n] @ _rot(yaw).T + offset - fp[:n]
    rms = float(np.sqrt(np.average(np.sum(resid ** 2, axis=1), weights=w[:n])))
    return FuseResult(out, nan, method,
                      {"fixes_used": int(n),
                       "heading_offset_deg": float(np.degrees(yaw)), "offset_m": [float(v) for v in offset],
                       "scale": 1.0, "path_spread_m": spread,
                       "span_s": float(ft[n - 1] - ft[0]), "rms_residual_m": rms,
                       # the angular error of a rotation fitted to n points at that spread
                       "yaw_std_deg": float(np.degrees(rms / max(spread, 1e-9) / np.sqrt(n)))},
                      warn)


class Problem:
    """The smoother's residuals over nodes ``tn`` with displacements ``d`` (complex) and fixes."""

    def __init__(self, tn, d, ft, fz, sigma, cfg: FuseConfig, prior: "Prior | None" = None):
        self.tn, self.d, self.cfg, self.prior = tn, d, cfg, prior
        self.bias_sigma_m = cfg.bias_sigma_m
        self.tau = tn[:-1] - 0.5 * (tn[0] + tn[-1])  # time of each displacement about the middle
        self.ft, self.fz, self.sigma = ft, fz, sigma
        n_knots = max(2, int(np.ceil((tn[-1] - tn[0]) / cfg.bias_knot_s)) + 1)
        self.knots = np.linspace(tn[0], tn[-1], n_knots)
        self.a = np.exp(-np.diff(self.knots) / cfg.bias_correlation_s)  # Gauss–Markov step factor
        # fix k's position between nodes, and its bias between knots (linear weights)
        self.i_n, self.w_n = _lin(tn, ft - cfg.fix_lag_s)
        self.i_b, self.w_b = _lin(self.knots, ft)
        self.walk = cfg.heading_walk_deg_per_sqrt_min > 0
        self.slack = cfg.odometry_walk_m_per_sqrt_s > 0
        self.i_h, self.w_h = _lin(self.knots, tn[:-1])  # each displacement's heading between knots
        self.i_s, self.w_s = _lin(self.knots, tn)  # each node's slack between knots
        nk = len(self.knots)
        self.h0 = self.n_global + 2 * nk  # first heading knot
        self.s0 = self.h0 + (nk if self.walk else 0)  # first slack knot (x, y pairs)
        self.n_params = self.s0 + (2 * nk if self.slack else 0)

    n_global = 5  # θ, log s, ω, o_x, o_y

    def heading(self, x: np.ndarray) -> np.ndarray:
        """The heading correction (rad) of each displacement."""
        h = x[0] + x[2] * self.tau
        if self.walk:
            hk = x[self.h0:self.s0]
            h = h + hk[self.i_h] * (1 - self.w_h) + hk[self.i_h + 1] * self.w_h
        return h

    def slack_xy(self, x: np.ndarray) -> np.ndarray:
        """The odometry's position error at the knots (complex, m)."""
        e = x[self.s0:self.s0 + 2 * len(self.knots)].reshape(-1, 2)
        return e[:, 0] + 1j * e[:, 1]

    def path(self, x: np.ndarray) -> np.ndarray:
        """Node positions (complex, m) for parameters ``x``."""
        step = np.exp(x[1]) * np.exp(1j * self.heading(x)) * self.d
        p = (x[3] + 1j * x[4]) + np.concatenate([[0.0], np.cumsum(step)])
        if self.slack:
            e = self.slack_xy(x)
            p = p + e[self.i_s] * (1 - self.w_s) + e[self.i_s + 1] * self.w_s
        return p

    def bias(self, x: np.ndarray) -> np.ndarray:
        b = x[self.n_global:self.n_global + 2 * len(self.knots)].reshape(-1, 2)
        return b[:, 0] + 1j * b[:, 1]

    def fix_residual(self, x: np.ndarray) -> np.ndarray:
        """(p(t_k) + b(t_k) − z_k) / σ_k, complex."""
        p, b = self.path(x), self.bias(x)
        pk = p[self.i_n] * (1 - self.w_n) + p[self.i_n + 1] * self.w_n
        bk = b[self.i_b] * (1 - self.w_b) + b[self.i_b + 1] * self.w_b
        return (pk + bk - self.fz) / self.sigma

    def residuals(self, x: np.ndarray) -> np.ndarray:
        cfg, c = self.cfg, self.cfg.robust_scale
        r = self.fix_residual(x)
        s2 = np.abs(r) ** 2
        # 2-D Cauchy: each fix contributes ρ(|r|²) = c² log(1 + |r|²/c²) (its x and y together)
        scale = np.sqrt(c ** 2 * np.log1p(s2 / c ** 2) / np.maximum(s2, 1e-300))
        scale = np.where(s2 > 1e-12, scale, 1.0)
        rf = r * scale
        b = self.bias(x)
        sb = self.bias_sigma_m
        prior_b = np.concatenate([[b[0] / sb], (b[1:] - self.a * b[:-1]) / (sb * np.sqrt(1 - self.a ** 2))])
        globals_prior = [(x[1] - np.log(cfg.scale_prior)) / cfg.scale_prior_log_sigma, x[2] / cfg.drift_sigma_rad_s]
        if self.prior is not None:  # the marginal of the frozen past replaces the priors at the start
            prior_b[0] = 0.0
            globals_prior = [0.0, 0.0]
        out = [rf.real, rf.imag, prior_b.real, prior_b.imag, globals_prior]
        if self.walk:  # h_0 = 0 (θ holds the offset), then a random walk between knots
            hk = x[self.h0:self.s0]
            sd = np.radians(cfg.heading_walk_deg_per_sqrt_min) * np.sqrt(np.diff(self.knots) / 60.0)
            out.append(np.concatenate([[hk[0] / 1e-3], np.diff(hk) / sd]))
        if self.slack:  # e_0 = 0 (the origin holds the start), then a random walk
            e = self.slack_xy(x)
            sd = cfg.odometry_walk_m_per_sqrt_s * np.sqrt(np.diff(self.knots))
            r = np.concatenate([[e[0] / 1e-3], np.diff(e) / sd])
            out += [r.real, r.imag]
        if cfg.heading_prior_deg is not None and self.prior is None:  # the heading at the walk's start (θ + ω τ_0)
            d = np.angle(np.exp(1j * (x[0] + x[2] * self.tau[0] - np.radians(cfg.heading_prior_deg))))
            out.append([d / np.radians(cfg.heading_prior_sigma_deg)])
        if self.prior is not None:
            out.append(self.prior.sqrt_info @ (self.start_state(x) - self.prior.mean))
        return np.concatenate(out)

    def start_state(self, x: np.ndarray) -> np.ndarray:
        """The state the frozen past's prior constrains, at the first node: position (2), heading
        (rad), fix bias (2), log scale, drift (rad/s)."""
        b0 = x[self.n_global:self.n_global + 2]
        return np.array([x[3], x[4], x[0] + x[2] * self.tau[0], b0[0], b0[1], x[1], x[2]])

    def end_state(self, x: np.ndarray) -> np.ndarray:
        """The same state at the last node (what a later window's prior is built from)."""
        p, b = self.path(x)[-1], self.bias(x)[-1]
        h = x[0] + x[2] * (self.tn[-1] - 0.5 * (self.tn[0] + self.tn[-1])) + (x[self.s0 - 1] if self.walk else 0.0)
        return np.array([p.real, p.imag, h, b.real, b.imag, x[1], x[2]])

    def sparsity(self):
        """Which parameters each residual depends on (for a sparse finite-difference Jacobian)."""
        from scipy.sparse import lil_matrix

        nk, nf = len(self.knots), len(self.ft)
        heading = self.cfg.heading_prior_deg is not None
        n_rows = 2 * nf + 2 * nk + 2 + (nk if self.walk else 0) + (2 * nk if self.slack else 0) + int(heading)
        m = lil_matrix((n_rows, self.n_params), dtype=int)
        if heading:
            m[n_rows - 1, [0, 2]] = 1
        m[:2 * nf, self.h0:self.s0] = 1  # a fix depends on every heading knot (before it)
        if self.slack:  # and on the slack knots around its nodes
            i_n = np.clip(self.i_n, 0, len(self.tn) - 2)
            for dn in (0, 1):
                ks = self.i_s[i_n + dn]
                for dk in (0, 1):
                    for ax in range(2):
                        for half in range(2):
                            m[half * nf + np.arange(nf), self.s0 + 2 * (ks + dk) + ax] = 1
        row = 2 * nf + 2 * nk + 2
        if self.walk:
            for k in range(nk):
                m[row + k, self.h0 + max(k - 1, 0):self.h0 + k + 1] = 1
            row += nk
        if self.slack:
            for k in range(2 * nk):
                kk = k % nk
                m[row + k, self.s0 + 2 * max(kk - 1, 0):self.s0 + 2 * kk + 2] = 1
        for half in range(2):
            rows = half * nf + np.arange(nf)
            m[rows, :self.n_global] = 1
            for dk in (0, 1):
                for ax in range(2):
                    m[rows, self.n_global + 2 * (self.i_b + dk) + ax] = 1
            for k in range(nk):
                for ax in range(2):
                    m[2 * nf + half * nk + k, self.n_global + 2 * k + ax] = 1
                    if k:
                        m[2 * nf + half * nk + k, self.n_global + 2 * (k - 1) + ax] = 1
        m[2 * nf + 2 * nk, 1] = 1
        m[2 * nf + 2 * nk + 1, 2] = 1
        if self.prior is not None:
            from scipy.sparse import vstack

            p = lil_matrix((Prior.size, self.n_params), dtype=int)
            p[:, :self.n_global + 2] = 1
            m = vstack([m, p]).tolil()
        return m


def _lin(grid: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index i and weight w with t = grid[i] (1 − w) + grid[i+1] w (clipped to the grid)."""
    i = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, len(grid) - 2)
    w = np.clip((t - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    return i, w


def smooth(t: np.ndarray, xy: np.ndarray, fix_t, fix_pos, fix_accuracy, cfg: FuseConfig = FuseConfig(),
           x0: np.ndarray | None = None) -> FuseResult:
    """The smoothed path (module docstring) of odometry ``xy`` (N, 2) m at times ``t`` (N,) s,
    given fixes at ``fix_t`` (M,) s, ``fix_pos`` (M, 2) m east/north, ``fix_accuracy`` (M,) m."""
    t, xy = np.asarray(t, np.float64), np.asarray(xy, np.float64)
    if t.ndim != 1 or xy.shape != (t.size, 2) or t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValidationError(f"the odometry path needs increasing times and (N, 2) positions; got {xy.shape}")
    check, kept, ft, fz, acc, facts = _kept(t, fix_t, fix_pos, fix_accuracy, cfg.wide_m)
    sigma = fix_sigma_m(acc)
    rigid = _rigid(t, xy, ft, fz, acc, None)
    if len(ft) < 2 or rigid.info.get("path_spread_m", 0.0) < 1e-6 or rigid.warnings:
        return _with_fixes(rigid, check, kept, facts)
    prob = build_problem(t, xy, ft, fz[:, 0] + 1j * fz[:, 1], sigma, t[0], t[-1], cfg)
    tn = prob.tn
    if x0 is None or len(x0) != prob.n_params:
        yaw = rigid.info["heading_offset_deg"]
        o = _rot(np.radians(yaw)) @ xy[0] + np.asarray(rigid.info["offset_m"])
        x0 = np.concatenate([[np.radians(yaw), np.log(cfg.scale_prior), 0.0, o[0], o[1]],
                             np.zeros(prob.n_params - prob.n_global)])
    sol = solve(prob, x0)
    x = sol.x
    r = np.abs(prob.fix_residual(x))
    weight = 1.0 / (1.0 + (r / cfg.robust_scale) ** 2)  # the Cauchy loss's IRLS weight
    down = int(np.sum(weight < DOWNWEIGHT))
    # the path at the input times, and its σ from the fit's covariance
    pnode = prob.path(x)
    out = np.stack([np.interp(t, tn, pnode.real), np.interp(t, tn, pnode.imag)], axis=1)
    sig_node = node_sigma(prob, x, sol.jac, pnode)
    info = {"fixes_used": int(len(ft) - down), "fixes_down_weighted": down,
            "heading_offset_deg": float(np.degrees(x[0])), "scale": float(np.exp(x[1])),
            "heading_drift_deg_per_min": float(np.degrees(x[2]) * 60.0),
            "origin_m": [float(x[3]), float(x[4])],
            "fix_bias_rms_m": float(np.sqrt(np.mean(np.abs(prob.bias(x)) ** 2))),
            "fix_bias_sigma_m": prob.bias_sigma_m,
            "nodes": int(len(tn)), "solver_evaluations": int(sol.nfev),
            "config": dataclasses.asdict(cfg), "x": [float(v) for v in x]}
    if down > DISAGREE_SHARE * len(ft):
        first = _with_fixes(_rigid(t, xy, ft, fz, acc, ANCHOR_S), check, kept, facts)
        first.info["smoother"] = info
        first.warnings.append(f"{down} of {len(ft)} location fixes disagree with the path and with each other: "
                              "fell back to anchoring on the first minute's fixes")
        return first
    return _with_fixes(FuseResult(out, np.interp(t, tn, sig_node), "smooth", info, []), check, kept, facts, weight)


def node_sigma(prob: Problem, x: np.ndarray, jac, pnode: np.ndarray, every: int = 10) -> np.ndarray:
    """Per-axis 1-σ (m) of each node from the fit's covariance ((JᵀJ)⁺ of the solver's Jacobian)
    of every unknown that moves the path: the globals (θ, log s, ω, o), the heading walk and the
    odometry walk, with their correlations. The globals alone overstate it several-fold where the
    knots trade off against them (a heading offset and the heading walk), and leave out the drift
    between fixes. The path's Jacobian is by forward differences, at every ``every``-th node
    (linear in between)."""
    try:
        j = jac.toarray() if hasattr(jac, "toarray") else np.asarray(jac)
        cov = np.linalg.pinv(j.T @ j)
    except (np.linalg.LinAlgError, ValueError):
        return np.full(len(pnode), np.nan)
    cols = np.r_[np.arange(prob.n_global), np.arange(prob.h0, prob.n_params)]  # not the fix bias
    at = np.unique(np.r_[np.arange(0, len(pnode), every), len(pnode) - 1])
    jp = np.empty((2, at.size, cols.size))
    for c, k in enumerate(cols):
        h = 1e-6 * max(1.0, abs(float(x[k])))
        xk = x.copy()
        xk[k] += h
        d = (prob.path(xk)[at] - pnode[at]) / h
        jp[0, :, c], jp[1, :, c] = d.real, d.imag
    var = np.einsum("anc,cd,and->n", jp, cov[np.ix_(cols, cols)], jp) / 2.0
    return prob.cfg.sigma_scale * np.interp(np.arange(len(pnode)), at, np.sqrt(np.maximum(var, 0.0)))


def odometry_walk_sigma(walks) -> dict:
    """Calibrate ``odometry_walk_m_per_sqrt_s`` on walks with truth (a model's validation walks).

    ``walks`` yields (t (N,) s, odometry xy (N, 2) m, truth_t (M,) s, truth_xy (M, 2) m). Each path
    is fitted to its truth points by rotation, scale and translation (the unknowns the smoother
    estimates otherwise); the residual's increments between consecutive truth points, over √Δt,
    give the random walk's σ per axis, robustly: their median / √(2 ln 2) (the median length of a
    2-D Gaussian with σ per axis is σ √(2 ln 2))."""
    rates, n = [], 0
    for t, xy, tt, tp in walks:
        k = (tt >= t[0]) & (tt <= t[-1])
        if k.sum() < 3:
            continue
        p = np.stack([np.interp(tt[k], t, xy[:, j]) for j in range(2)], axis=1)
        zp = (p[:, 0] + 1j * p[:, 1]) - np.mean(p[:, 0] + 1j * p[:, 1])
        zq = (tp[k, 0] + 1j * tp[k, 1]) - np.mean(tp[k, 0] + 1j * tp[k, 1])
        a = np.sum(np.conj(zp) * zq) / max(float(np.sum(np.abs(zp) ** 2)), 1e-12)  # scale · e^{iθ}
        dt = np.diff(tt[k])
        rates.append(np.abs(np.diff(a * zp - zq))[dt > 0] / np.sqrt(dt[dt > 0]))
        n += 1
    if n == 0:
        return {"odometry_walk_m_per_sqrt_s": None, "walks": 0}
    sigma = float(np.median(np.concatenate(rates)) / RAYLEIGH_MEDIAN)
    return {"odometry_walk_m_per_sqrt_s": round(sigma, 4), "walks": n}


def sigma_scale_of(error_over_sigma) -> dict:
    """Calibrate ``sigma_scale`` on walks with truth: ``error_over_sigma`` holds, at their truth
    points, the smoothed path's error over its σ (run with ``sigma_scale`` 1). Where σ is right
    their median is :data:`RAYLEIGH_MEDIAN`; the scale is their median over it, so that the 68 %
    radius (:data:`RADIUS_68` σ) holds about 68 % of the errors."""
    z = np.asarray(error_over_sigma, np.float64)
    z = z[np.isfinite(z)]
    if z.size == 0:
        return {"sigma_scale": None, "sigma_points": 0}
    return {"sigma_scale": round(float(np.median(z)) / RAYLEIGH_MEDIAN, 3), "sigma_points": int(z.size)}


def calibrated(cfg: FuseConfig, cal: dict | None) -> FuseConfig:
    """``cfg`` with a calibration's odometry random walk and σ scale (``CALIBRATION_JSON``'s
    ``odometry_walk_m_per_sqrt_s``, ``sigma_scale``) where they are given and positive."""
    found = {}
    for key in ("odometry_walk_m_per_sqrt_s", "sigma_scale"):
        try:
            v = float((cal or {}).get(key))
        except (TypeError, ValueError):
            continue
        if np.isfinite(v) and v > 0:
            found[key] = v
    return dataclasses.replace(cfg, **found)


ANCHORS = {"first-fixes": first_fix_anchor, "rigid": rigid_anchor, "smooth": smooth}


def fuse(t, xy, fix_t, fix_pos, fix_accuracy, anchor: str = "smooth", cfg: FuseConfig = FuseConfig()) -> FuseResult:
    """The path of odometry ``xy`` placed on the fixes by ``anchor`` (first-fixes | rigid | smooth)."""
    if anchor not in ANCHORS:
        raise ValidationError(f"unknown anchoring {anchor!r}; one of {', '.join(ANCHORS)}")
    return ANCHORS[anchor](t, xy, fix_t, fix_pos, fix_accuracy, cfg)


def known_heading_deg(meta: dict, reference: str | None = "phone") -> float | None:
    """The yaw (deg) from a recording's world frame to east/north where its importer documents it,
    else None. ``reference``: the device whose frame the odometry ran in (``frame.reference`` of
    :func:`wearnav.preprocess.align`; None or "phone" for the phone's own). Android's rotation vector
    (ILC2, IPIN 2023: :data:`wearnav.recording.ANDROID_ENU_FRAME`) is east, magnetic north, up: 0.
    Unknown: the simulator (its orientation has an arbitrary yaw, as a game rotation vector has) and
    Sensor Logger (its docs give an x-north reference frame, unverified on a real walk with truth)."""
    if reference in (None, "phone") and meta.get("quat_frame") == ANDROID_ENU_FRAME:
        return 0.0
    return None


def config_for(run, meta: dict | None = None, reference: str | None = "phone") -> tuple[FuseConfig, dict | None]:
    """The smoother's config for a model's run folder (or a checkpoint inside it) and a recording's
    ``meta``: the defaults, with the odometry's random walk and the σ scale from ``CALIBRATION_JSON``
    where the run has one (:func:`calibrated`), and a prior on the heading offset where the recording's world frame is north-referenced
    (:func:`known_heading_deg`; on IPIN 2023's training walks it cut the p95 error of PDR from 25.8
    to 17.9 m and of a learned model from another building from 21.8 to 19.2 m). Returns the config
    and the calibration read (None: none)."""
    cfg, cal = FuseConfig(), None
    p = Path(run) if run is not None else None
    folder = (p.parent.parent if p.is_file() else p) if p is not None else None
    f = folder / CALIBRATION_JSON if folder is not None else None
    if f is not None and f.is_file():
        try:
            c = read_json(f)
            if calibrated(cfg, c) != cfg:
                cfg, cal = calibrated(cfg, c), c
            else:
                log.warning("%s: no usable calibration in it, the smoother's defaults are used", f)
        except (FormatError, AttributeError):
            log.warning("%s: unreadable calibration, the smoother's defaults are used", f)
    heading = known_heading_deg(meta or {}, reference)
    if heading is not None:
        cfg = dataclasses.replace(cfg, heading_prior_deg=heading)
    return cfg, cal


@dataclasses.dataclass(frozen=True)
class Prior:
    """A Gaussian on :meth:`Problem.start_state`: ``mean`` (7,), ``sqrt_info`` (7, 7) with
    sqrt_infoᵀ sqrt_info the inverse covariance."""

    mean: np.ndarray
    sqrt_info: np.ndarray
    size = 7


def _nodes(t0: float, t1: float, node_s: float) -> np.ndarray:
    tn = np.arange(t0, t1, node_s)
    return np.append(tn, t1) if t1 - tn[-1] > 1e-9 else tn


def build_problem(t, xy, ft, fz, sigma, t0, t1, cfg, prior=None) -> Problem:
    """The smoother's problem over [t0, t1] s (the odometry interpolated onto its nodes, the fixes
    inside it)."""
    tn = _nodes(t0, t1, cfg.node_s)
    pn = np.stack([np.interp(tn, t, xy[:, k]) for k in range(2)], axis=1)
    k = (ft >= t0) & (ft <= t1)
    sigma = sigma[k]
    share = cfg.bias_share
    prob = Problem(tn, np.diff(pn[:, 0] + 1j * pn[:, 1]), ft[k], fz[k],
                    np.maximum(sigma * np.sqrt(1.0 - share), MIN_SIGMA_M) if share > 0 else sigma, cfg, prior)
    if share > 0 and sigma.size:
        prob.bias_sigma_m = float(np.sqrt(share) * np.median(sigma))
    return prob


def solve(prob: Problem, x0: np.ndarray):
    return least_squares(prob.residuals, x0, jac_sparsity=prob.sparsity(), method="trf", x_scale="jac",
                         ftol=1e-6, xtol=1e-6)
