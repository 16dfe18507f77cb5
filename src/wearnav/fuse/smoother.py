"""The smoother of :mod:`wearnav.fuse` estimates, by robust nonlinear least squares (:func:`scipy.optimize.least_squares`, a 2-D Cauchy loss per fix):

``heading_offset``  θ (rad), the rotation from the odometry frame to east/north;
``scale``           s, on every odometry displacement, with a log-normal prior (``scale_prior``,
                    ``scale_prior_log_sigma``);
``heading_drift``   ω (rad/s) about the walk's middle time, with a zero-mean prior; where the
                    recording's world frame is north-referenced
                    (:func:`wearnav.fuse.calibrate.known_heading_deg`), the heading at the start has a prior too (``heading_prior_deg`` ± ``heading_prior_sigma_deg``):
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
The Jacobian is analytic (:meth:`Problem.jacobian`: the globals and the heading knots move every
later position through cumulative sums; the Cauchy scaling is differentiated with its residual).
It made a solve 3.6–3.9× faster than the sparse finite-difference Jacobian it replaced, on the same
paths (Decision: docs/decisions/0020-fused-path-smoother.md).

Decisions: docs/decisions/0021-smoother-tried-simulator-confidence.md,
docs/decisions/0023-smoother-point-sigma.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from wearnav.errors import ValidationError
from wearnav.fuse.anchor import _kept, _rigid, _rot, _with_fixes
from wearnav.fuse.config import ANCHOR_S, DISAGREE_SHARE, DOWNWEIGHT, MIN_SIGMA_M, FuseConfig, FuseResult, fix_sigma_m


@dataclasses.dataclass(frozen=True)
class _JacStructure:
    """What :meth:`Problem.jacobian` does not recompute (:meth:`Problem._jac_structure`)."""

    bias_sigma_m: float  # the fix bias's σ it was built with
    fix: np.ndarray  # the fix of each fix entry (its rows: fix, then n_fixes + fix)
    heading_at: np.ndarray  # (8, n) places in the heading knots' cumulative sums, for their entries
    heading_w: np.ndarray  # (8, n) their weights (with the fix's 1 / σ)
    fixed: np.ndarray  # d r / d x (complex) of the entries where r is linear (origin, fix bias, odometry walk)
    prior_values: np.ndarray  # the priors' rows
    order: np.ndarray  # every entry (fix x rows, fix y rows, priors) sorted by row and column
    first: np.ndarray  # the first sorted entry of each place
    indices: np.ndarray  # the CSR matrix's column indices
    indptr: np.ndarray  # its row pointers
    shape: tuple[int, int]


class Problem:
    """The smoother's residuals over nodes ``tn`` with displacements ``d`` (complex) and fixes."""

    def __init__(self, tn, d, ft, fz, sigma, cfg: FuseConfig, prior: Prior | None = None):
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
        self._js: _JacStructure | None = None  # the Jacobian's pattern (jacobian)

    n_global = 5  # θ, log s, ω, o_x, o_y

    def heading(self, x: np.ndarray) -> np.ndarray:
        """The heading correction (rad) of each displacement."""
        h = x[0] + x[2] * self.tau
        if self.walk:
            hk = x[self.h0 : self.s0]
            h = h + hk[self.i_h] * (1 - self.w_h) + hk[self.i_h + 1] * self.w_h
        return h

    def slack_xy(self, x: np.ndarray) -> np.ndarray:
        """The odometry's position error at the knots (complex, m)."""
        e = x[self.s0 : self.s0 + 2 * len(self.knots)].reshape(-1, 2)
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
        b = x[self.n_global : self.n_global + 2 * len(self.knots)].reshape(-1, 2)
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
        scale = np.sqrt(c**2 * np.log1p(s2 / c**2) / np.maximum(s2, 1e-300))
        scale = np.where(s2 > 1e-12, scale, 1.0)
        rf = r * scale
        b = self.bias(x)
        sb = self.bias_sigma_m
        prior_b = np.concatenate([[b[0] / sb], (b[1:] - self.a * b[:-1]) / (sb * np.sqrt(1 - self.a**2))])
        globals_prior = [(x[1] - np.log(cfg.scale_prior)) / cfg.scale_prior_log_sigma, x[2] / cfg.drift_sigma_rad_s]
        if self.prior is not None:  # the marginal of the frozen past replaces the priors at the start
            prior_b[0] = 0.0
            globals_prior = [0.0, 0.0]
        out: list[ArrayLike] = [rf.real, rf.imag, prior_b.real, prior_b.imag, globals_prior]
        if self.walk:  # h_0 = 0 (θ holds the offset), then a random walk between knots
            hk = x[self.h0 : self.s0]
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

    def jacobian(self, x: np.ndarray) -> csr_matrix:
        """d :meth:`residuals` / d ``x`` (sparse, the same rows), analytic: a fix's position moves with
        the globals and the heading knots through cumulative sums over the displacements, and the
        2-D Cauchy loss's scaling is differentiated with its residual (each fix's 2 × 2 block). What
        does not depend on ``x`` (the pattern, the linear weights, the priors' rows) is built once."""
        js = self._jac_structure()
        step = np.exp(x[1]) * np.exp(1j * self.heading(x)) * self.d
        cum = np.zeros((2, len(self.tn)), complex)  # Σ_{j<i} step_j and Σ_{j<i} τ_j step_j at each node
        np.cumsum(np.stack([step, self.tau * step]), axis=1, out=cum[:, 1:])
        i0, w = self.i_n, self.w_n
        at_fix = (cum[:, i0] * (1 - w) + cum[:, i0 + 1] * w) / self.sigma
        parts = [np.stack([1j * at_fix[0], at_fix[0], 1j * at_fix[1]], 1).ravel()]  # d r / d (θ, log s, ω)
        if self.walk:  # d r / d h_m: the turned displacements after knot m, weighted by the knots' hats
            cu = np.zeros((2, len(self.tn)), complex)
            np.cumsum(np.stack([1j * step * (1 - self.w_h), 1j * step * self.w_h]), axis=1, out=cu[:, 1:])
            parts.append(np.einsum("ij,ij->j", cu.ravel()[js.heading_at], js.heading_w))
        parts.append(js.fixed)  # the origin, the fix bias and the odometry walk (linear)
        d = np.concatenate(parts)
        # the Cauchy scaling rf = r f(|r|²), f² = g = c² log(1 + |r|²/c²) / |r|²: d rf / d r = f I + (g' / f) r rᵀ
        # with g' = d g / d |r|² (its series where |r|² / c² is small, its limit 1 / −½c² below 1e-12)
        r = self.fix_residual(x)
        c2 = self.cfg.robust_scale**2
        s2 = np.abs(r) ** 2
        on = s2 > 1e-12  # as in residuals: below it the scale is 1
        u = np.where(on, s2 / c2, 1.0)
        f = np.where(on, np.sqrt(np.log1p(u) / u), 1.0)
        gp = np.where(u < 1e-3, -0.5 + u * (2 / 3 - u * (0.75 - 0.8 * u)), (u / (1 + u) - np.log1p(u)) / u**2)
        a = np.where(on, gp / c2, 0.0) / f
        k = js.fix
        m00, m01, m11 = (f + a * r.real**2)[k], (a * r.real * r.imag)[k], (f + a * r.imag**2)[k]
        v = np.concatenate([m00 * d.real + m01 * d.imag, m01 * d.real + m11 * d.imag, js.prior_values])
        data = np.add.reduceat(v[js.order], js.first)  # summed where two entries share a place
        return csr_matrix((data, js.indices, js.indptr), shape=js.shape)

    def _jac_structure(self) -> _JacStructure:
        """The Jacobian's pattern and its parts that do not depend on the parameters (built on the
        first call, again if the fix bias's σ changes: :func:`build_problem` sets it)."""
        js = self._js
        if js is not None and js.bias_sigma_m == self.bias_sigma_m:
            return js
        cfg, nf, nk, ng = self.cfg, len(self.ft), len(self.knots), self.n_global
        i0, w, inv = self.i_n, self.w_n, 1.0 / self.sigma
        fixes = np.arange(nf)
        # the fixes' entries, in the order jacobian computes them: (fix, column, d r / d x where linear)
        ks, cs = [np.repeat(fixes, 3)], [np.tile(np.arange(3), nf)]
        heading_at, heading_w = np.zeros((8, 0), int), np.zeros((8, 0))
        if self.walk:  # G(i, m) = d p_i / d h_m from the cumulative sums of the two hats' parts
            n_t = len(self.tn)
            lo = np.searchsorted(self.i_h, np.arange(nk), side="left")  # displacements between knots m, m + 1
            hi = np.searchsorted(self.i_h, np.arange(nk), side="right")
            lo_v, hi_v = np.r_[0, lo[:-1]], np.r_[0, hi[:-1]]  # those between knots m − 1 and m
            n_m = self.i_h[i0] + 2  # fix k depends on the knots 0 … i_h(node i_n) + 1
            k = np.repeat(fixes, n_m)
            m = np.arange(k.size) - np.repeat(np.cumsum(n_m) - n_m, n_m)
            ks.append(k)
            cs.append(self.h0 + m)
            at, wt = [], []
            for node, wn in ((i0[k], (1 - w[k]) * inv[k]), (i0[k] + 1, w[k] * inv[k])):
                at += [np.clip(node, lo[m], hi[m]), lo[m], n_t + np.clip(node, lo_v[m], hi_v[m]), n_t + lo_v[m]]
                wt += [wn, -wn, wn, -wn]
            heading_at, heading_w = np.array(at), np.array(wt)
        ks.append(np.repeat(fixes, 2))  # the origin
        cs.append(np.tile([3, 4], nf))
        fixed = [np.stack([inv, 1j * inv], 1).ravel()]
        ks.append(np.repeat(fixes, 4))  # the fix bias (x, y at two knots)
        cs.append((ng + 2 * self.i_b[:, None] + np.arange(4)).ravel())
        wb = np.stack([1 - self.w_b, 1 - self.w_b, self.w_b, self.w_b], 1)
        fixed.append((wb * np.array([1, 1j, 1, 1j]) * inv[:, None]).ravel())
        if self.slack:  # the odometry walk at the knots around the fix's two nodes
            for node, wn in ((i0, 1 - w), (i0 + 1, w)):
                kn, wk = self.i_s[node], self.w_s[node]
                ks.append(np.repeat(fixes, 4))
                cs.append((self.s0 + 2 * kn[:, None] + np.arange(4)).ravel())
                wt4 = np.stack([1 - wk, 1 - wk, wk, wk], 1) * (wn * inv)[:, None]
                fixed.append((wt4 * np.array([1, 1j, 1, 1j])).ravel())
        fix, col = np.concatenate(ks), np.concatenate(cs)
        rows, cols, vals = [fix, nf + fix], [col, col], []
        # the priors' rows (linear in x: their values are constants)
        row = 2 * nf
        sb = self.bias_sigma_m
        q = 1.0 / (sb * np.sqrt(1 - self.a**2))
        kb = np.arange(1, nk)
        for ax in range(2):  # the fix bias's Gauss–Markov prior (x rows, then y rows)
            first = np.arange(1 if self.prior is not None else 0, 1)  # the frozen past's prior holds b_0
            rows.append(row + ax * nk + np.r_[first, kb, kb])
            cols.append(ng + ax + 2 * np.r_[first, kb, kb - 1])
            vals.append(np.r_[[1.0 / sb] * len(first), q, -self.a * q])
        row += 2 * nk
        if self.prior is None:
            rows.append(np.array([row, row + 1]))
            cols.append(np.array([1, 2]))
            vals.append(np.array([1.0 / cfg.scale_prior_log_sigma, 1.0 / cfg.drift_sigma_rad_s]))
        row += 2
        kw = np.arange(1, nk)
        if self.walk:  # h_0 / 1e-3, then the walk's steps
            sd = np.radians(cfg.heading_walk_deg_per_sqrt_min) * np.sqrt(np.diff(self.knots) / 60.0)
            rows.append(row + np.r_[0, kw, kw])
            cols.append(self.h0 + np.r_[0, kw, kw - 1])
            vals.append(np.r_[1e3, 1 / sd, -1 / sd])
            row += nk
        if self.slack:  # e_0 / 1e-3, then the walk's steps (x rows, then y rows)
            sd = cfg.odometry_walk_m_per_sqrt_s * np.sqrt(np.diff(self.knots))
            for ax in range(2):
                rows.append(row + ax * nk + np.r_[0, kw, kw])
                cols.append(self.s0 + ax + 2 * np.r_[0, kw, kw - 1])
                vals.append(np.r_[1e3, 1 / sd, -1 / sd])
            row += 2 * nk
        if cfg.heading_prior_deg is not None and self.prior is None:  # θ + ω τ_0 (the wrap's derivative is 1)
            s = np.radians(cfg.heading_prior_sigma_deg)
            rows.append(np.array([row, row]))
            cols.append(np.array([0, 2]))
            vals.append(np.array([1.0 / s, self.tau[0] / s]))
            row += 1
        if self.prior is not None:  # sqrt_info @ d start_state / d x (it reads x[0:7] alone)
            ds_dx = np.zeros((Prior.size, ng + 2))
            ds_dx[[0, 1, 2, 2, 3, 4, 5, 6], [3, 4, 0, 2, 5, 6, 1, 2]] = [1, 1, 1, self.tau[0], 1, 1, 1, 1]
            rows.append(np.repeat(row + np.arange(Prior.size), ng + 2))
            cols.append(np.tile(np.arange(ng + 2), Prior.size))
            vals.append((self.prior.sqrt_info @ ds_dx).ravel())
            row += Prior.size
        # the CSR layout: entries sorted by (row, column), those at one place summed
        key = np.concatenate(rows).astype(np.int64) * self.n_params + np.concatenate(cols)
        order = np.argsort(key, kind="stable")
        places, first = np.unique(key[order], return_index=True)
        indptr = np.searchsorted(places, np.arange(row + 1) * self.n_params)
        js = _JacStructure(
            sb,
            fix,
            heading_at,
            heading_w,
            np.concatenate(fixed),
            np.concatenate(vals),
            order,
            first,
            (places % self.n_params).astype(np.int32),
            indptr.astype(np.int32),
            (row, self.n_params),
        )
        self._js = js
        return js

    def start_state(self, x: np.ndarray) -> np.ndarray:
        """The state the frozen past's prior constrains, at the first node: position (2), heading
        (rad), fix bias (2), log scale, drift (rad/s)."""
        b0 = x[self.n_global : self.n_global + 2]
        return np.array([x[3], x[4], x[0] + x[2] * self.tau[0], b0[0], b0[1], x[1], x[2]])

    def end_state(self, x: np.ndarray) -> np.ndarray:
        """The same state at the last node (what a later window's prior is built from)."""
        p, b = self.path(x)[-1], self.bias(x)[-1]
        h = x[0] + x[2] * (self.tn[-1] - 0.5 * (self.tn[0] + self.tn[-1])) + (x[self.s0 - 1] if self.walk else 0.0)
        return np.array([p.real, p.imag, h, b.real, b.imag, x[1], x[2]])

    def sparsity(self):
        """Which parameters each residual depends on (for a sparse finite-difference Jacobian: the
        solve's before :meth:`jacobian`, kept as the tests' reference)."""
        from scipy.sparse import lil_matrix

        nk, nf = len(self.knots), len(self.ft)
        heading = self.cfg.heading_prior_deg is not None and self.prior is None  # as in residuals
        n_rows = 2 * nf + 2 * nk + 2 + (nk if self.walk else 0) + (2 * nk if self.slack else 0) + int(heading)
        m = lil_matrix((n_rows, self.n_params), dtype=int)
        if heading:
            m[n_rows - 1, [0, 2]] = 1
        m[: 2 * nf, self.h0 : self.s0] = 1  # a fix depends on every heading knot (before it)
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
                m[row + k, self.h0 + max(k - 1, 0) : self.h0 + k + 1] = 1
            row += nk
        if self.slack:
            for k in range(2 * nk):
                kk = k % nk
                m[row + k, self.s0 + 2 * max(kk - 1, 0) : self.s0 + 2 * kk + 2] = 1
        for half in range(2):
            rows = half * nf + np.arange(nf)
            m[rows, : self.n_global] = 1
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
            p[:, : self.n_global + 2] = 1
            m = vstack([m, p]).tolil()
        return m


def _lin(grid: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index i and weight w with t = grid[i] (1 − w) + grid[i+1] w (clipped to the grid)."""
    i = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, len(grid) - 2)
    w = np.clip((t - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    return i, w


def smooth(
    t: np.ndarray,
    xy: np.ndarray,
    fix_t,
    fix_pos,
    fix_accuracy,
    cfg: FuseConfig = FuseConfig(),
    x0: np.ndarray | None = None,
) -> FuseResult:
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
        x0 = np.concatenate(
            [[np.radians(yaw), np.log(cfg.scale_prior), 0.0, o[0], o[1]], np.zeros(prob.n_params - prob.n_global)]
        )
    sol = solve(prob, x0)
    x = sol.x
    r = np.abs(prob.fix_residual(x))
    weight = 1.0 / (1.0 + (r / cfg.robust_scale) ** 2)  # the Cauchy loss's IRLS weight
    down = int(np.sum(weight < DOWNWEIGHT))
    # the path at the input times, and its σ from the fit's covariance
    pnode = prob.path(x)
    out = np.stack([np.interp(t, tn, pnode.real), np.interp(t, tn, pnode.imag)], axis=1)
    sig_node = node_sigma(prob, x, sol.jac, pnode)
    info = {
        "fixes_used": int(len(ft) - down),
        "fixes_down_weighted": down,
        "heading_offset_deg": float(np.degrees(x[0])),
        "scale": float(np.exp(x[1])),
        "heading_drift_deg_per_min": float(np.degrees(x[2]) * 60.0),
        "origin_m": [float(x[3]), float(x[4])],
        "fix_bias_rms_m": float(np.sqrt(np.mean(np.abs(prob.bias(x)) ** 2))),
        "fix_bias_sigma_m": prob.bias_sigma_m,
        "nodes": int(len(tn)),
        "solver_evaluations": int(sol.nfev),
        "config": dataclasses.asdict(cfg),
        "x": [float(v) for v in x],
    }
    if down > DISAGREE_SHARE * len(ft):
        first = _with_fixes(_rigid(t, xy, ft, fz, acc, ANCHOR_S), check, kept, facts)
        first.info["smoother"] = info
        first.warnings.append(
            f"{down} of {len(ft)} location fixes disagree with the path and with each other: "
            "fell back to anchoring on the first minute's fixes"
        )
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
    prob = Problem(
        tn,
        np.diff(pn[:, 0] + 1j * pn[:, 1]),
        ft[k],
        fz[k],
        np.maximum(sigma * np.sqrt(1.0 - share), MIN_SIGMA_M) if share > 0 else sigma,
        cfg,
        prior,
    )
    if share > 0 and sigma.size:
        prob.bias_sigma_m = float(np.sqrt(share) * np.median(sigma))
    return prob


def solve(prob: Problem, x0: np.ndarray, dense: bool = False):
    """``prob``'s least-squares solution from ``x0``. ``dense``: the trust-region steps solved
    exactly on the dense Jacobian instead of by LSMR on the sparse one: the same minimum to the
    solver's tolerances (the live smoother's path on a 6-min walk within 1.74 mm at every update:
    tests/test_fuse_smoother.py), half the CPU for a window of the live fixed-lag smoother's size
    (issue 61); the batch smoother keeps LSMR (a whole walk's Jacobian can be large)."""
    steps: dict = (
        {"jac": lambda x: prob.jacobian(x).toarray(), "tr_solver": "exact"} if dense else {"jac": prob.jacobian}
    )
    return least_squares(prob.residuals, x0, method="trf", x_scale="jac", ftol=1e-6, xtol=1e-6, **steps)
