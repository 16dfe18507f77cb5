"""The fused path as data arrives (the live receiver): :class:`IncrementalFuser`, the smoother of
:mod:`wearnav.fuse` as a fixed-lag smoother whose cost per update is bounded by its window.

Decisions: docs/decisions/0020-fused-path-smoother.md, docs/decisions/0022-live-tracking.md."""

from __future__ import annotations

import dataclasses

import numpy as np

from wearnav.errors import ValidationError
from wearnav.fixcheck import repeated_fixes
from wearnav.fuse.config import DOWNWEIGHT, FuseConfig, FuseResult, fix_sigma_m
from wearnav.fuse.smoother import Prior, Problem, build_problem, node_sigma, smooth, solve


def _init_from(prob: Problem, old: Problem, x_old: np.ndarray) -> np.ndarray:
    """Starting values for ``prob`` from a solution of ``old`` that covers its start."""
    x = np.zeros(prob.n_params)
    mid_new, mid_old = 0.5 * (prob.tn[0] + prob.tn[-1]), 0.5 * (old.tn[0] + old.tn[-1])
    p0 = old.path(x_old)
    p0 = np.interp(prob.tn[0], old.tn, p0.real) + 1j * np.interp(prob.tn[0], old.tn, p0.imag)
    x[:5] = [x_old[0] + x_old[2] * (mid_new - mid_old), x_old[1], x_old[2], p0.real, p0.imag]
    b = old.bias(x_old)
    bk = np.interp(prob.knots, old.knots, b.real) + 1j * np.interp(prob.knots, old.knots, b.imag)
    x[prob.n_global : prob.n_global + 2 * len(prob.knots)] = np.stack([bk.real, bk.imag], 1).ravel()
    return x


def _marginal_at_end(prob: Problem, sol) -> Prior:
    """The Gaussian (Laplace) marginal of :meth:`Problem.end_state` under ``prob``'s solution:
    the prior that carries everything before ``prob``'s end into the next window."""
    x = sol.x
    j = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
    cov = np.linalg.inv(j.T @ j + 1e-9 * np.eye(len(x)))  # unobserved directions get a huge variance
    f0, g = prob.end_state(x), np.empty((Prior.size, len(x)))
    for i in range(len(x)):  # the end state's gradient by finite differences (it is cheap)
        dx = np.zeros(len(x))
        dx[i] = 1e-6 * max(1.0, abs(x[i]))
        g[:, i] = (prob.end_state(x + dx) - f0) / dx[i]
    cov_f = g @ cov @ g.T
    cov_f = 0.5 * (cov_f + cov_f.T) + 1e-9 * np.eye(Prior.size)
    info = np.linalg.inv(cov_f)
    return Prior(f0, np.linalg.cholesky(0.5 * (info + info.T)).T)


class _Rows:
    """A growable (n, width) float array: amortised O(1) appends, views without copying."""

    def __init__(self, width: int):
        self._a = np.empty((256, width))
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def extend(self, rows) -> None:
        rows = np.asarray(rows, np.float64).reshape(-1, self._a.shape[1])
        while self._n + len(rows) > len(self._a):
            self._a = np.concatenate([self._a, np.empty_like(self._a)])
        self._a[self._n : self._n + len(rows)] = rows
        self._n += len(rows)

    def append(self, row) -> None:
        self.extend([row])

    def view(self) -> np.ndarray:
        return self._a[: self._n]


class IncrementalFuser:
    """The smoother as a fixed-lag smoother, updated as data arrives (the live receiver): append
    odometry positions and fixes, ask for the path as often as wanted.

    Each :meth:`result` solves only the last ``lag_s`` (+ up to ``step_s``) seconds: the same
    problem as :func:`smooth` over that window, with the walk before it replaced by a Gaussian prior
    on the window's start state (position, heading, fix bias, scale, drift). Whenever the window
    exceeds ``lag_s + step_s``, its oldest ``step_s`` seconds are frozen (the path there is kept as
    last solved) and marginalised: the smoother is solved over that slice alone under the previous
    prior, so the new prior holds exactly the data before the new window start (no fix is counted
    twice), to first order (a Laplace approximation at the slice's solution). The cost of an update
    is therefore bounded by the window, however long the session. Until the first solution (two
    fixes that spread) the walk so far is fused by :func:`smooth`, with its fallbacks."""

    def __init__(self, cfg: FuseConfig = FuseConfig(), lag_s: float = 300.0, step_s: float = 30.0, dense: bool = True):
        if step_s < cfg.node_s or lag_s < step_s:
            raise ValidationError(f"the fixed lag needs lag_s ≥ step_s ≥ node_s; got {lag_s}, {step_s}")
        self.cfg, self.lag_s, self.step_s = cfg, float(lag_s), float(step_s)
        self.dense = dense  # the window's steps solved densely (smoother.solve's dense)
        self._odo = _Rows(3)  # t (s), x, y (m)
        self._fix = _Rows(4)  # t (s), east, north, accuracy (m)
        self._start: float | None = None  # the window's first node, s (None: not started)
        self._prior: Prior | None = None
        self._last: tuple[Problem, np.ndarray] | None = None  # the latest window and its solution
        self._frozen = _Rows(3)  # the frozen path: x, y (m), σ (m) at the odometry times before the window
        self.marginalised = 0  # slices frozen so far

    def add_odometry(self, t_s: float, xy_m) -> None:
        t = self._odo.view()[:, 0]
        if t.size and t_s <= t[-1]:
            raise ValidationError(f"odometry times must increase: {t_s} after {t[-1]}")
        xy = np.asarray(xy_m, np.float64)
        self._odo.append([float(t_s), xy[0], xy[1]])

    def add_fix(self, t_s: float, east_m: float, north_m: float, accuracy_m: float = np.nan) -> None:
        self._fix.append([float(t_s), float(east_m), float(north_m), float(accuracy_m)])

    @property
    def t(self) -> np.ndarray:
        """The odometry times so far (s)."""
        return self._odo.view()[:, 0]

    def _arrays(self, t0: float):
        """The odometry from the sample at or before ``t0`` on, and the fresh fixes inside it."""
        odo = self._odo.view()
        i = max(0, int(np.searchsorted(odo[:, 0], t0, side="right")) - 1)
        t, xy = odo[i:, 0], odo[i:, 1:]
        f = self._fix.view()
        f = f[np.isfinite(f[:, 0]) & (f[:, 0] >= t0) & (f[:, 0] <= t[-1]) & np.all(np.isfinite(f[:, 1:3]), axis=1)]
        f = f[np.argsort(f[:, 0], kind="stable")]
        f = f[~repeated_fixes(f[:, 1:3])]
        return t, xy, f[:, 0], f[:, 1] + 1j * f[:, 2], fix_sigma_m(f[:, 3])

    def result(self) -> FuseResult:
        """The fused path at every odometry time so far (frozen part, then the window)."""
        odo = self._odo.view()
        if len(odo) < 2:
            raise ValidationError("the fixed-lag smoother needs at least two odometry positions")
        t_all = odo[:, 0]
        if self._last is None:  # not started: the whole walk by the batch smoother
            f = self._fix.view()
            res = smooth(t_all, odo[:, 1:], f[:, 0], f[:, 1:3], f[:, 3], self.cfg)
            if res.method != "smooth":
                return res
            self._start = float(t_all[0])
            t, xy, ft, fz, sig = self._arrays(self._start)
            prob = build_problem(t, xy, ft, fz, sig, self._start, float(t_all[-1]), self.cfg)
            self._last = (prob, np.asarray(res.info["x"]))
        assert self._start is not None  # set with _last
        t_end = float(t_all[-1])
        while t_end - self._start > self.lag_s + self.step_s:
            self._advance()
        t, xy, ft, fz, sig = self._arrays(self._start)
        prob = build_problem(t, xy, ft, fz, sig, self._start, t_end, self.cfg, self._prior)
        sol = solve(prob, _init_from(prob, *self._last), dense=self.dense)
        self._last = (prob, sol.x)
        pn = prob.path(sol.x)
        r = np.abs(prob.fix_residual(sol.x))
        down = int(np.sum(1.0 / (1.0 + (r / self.cfg.robust_scale) ** 2) < DOWNWEIGHT))
        k = slice(len(self._frozen), None)  # the odometry times from the window's start on
        win = np.stack([np.interp(t_all[k], prob.tn, pn.real), np.interp(t_all[k], prob.tn, pn.imag)], axis=1)
        sig_w = np.interp(t_all[k], prob.tn, node_sigma(prob, sol.x, sol.jac, pn))
        frozen = self._frozen.view()
        xy_out = np.concatenate([frozen[:, :2], win])
        sig_out = np.concatenate([frozen[:, 2], sig_w])
        info = {
            "fixes_window": int(len(prob.ft)),
            "fixes_down_weighted_window": down,
            "window_start_s": self._start,
            "lag_s": self.lag_s,
            "slices_marginalised": self.marginalised,
            "heading_offset_deg": float(np.degrees(sol.x[0])),
            "scale": float(np.exp(sol.x[1])),
            "heading_drift_deg_per_min": float(np.degrees(sol.x[2]) * 60.0),
            "nodes": int(len(prob.tn)),
            "solver_evaluations": int(sol.nfev),
            "config": dataclasses.asdict(self.cfg),
        }
        return FuseResult(xy_out, sig_out, "smooth-fixed-lag", info, [])

    def _advance(self) -> None:
        """Freeze the window's oldest ``step_s`` seconds (as last solved) and marginalise them."""
        assert self._start is not None and self._last is not None  # result() started the window
        new_start = self._start + self.step_s
        prob_w, x_w = self._last
        t_all = self.t
        tk = t_all[len(self._frozen) : int(np.searchsorted(t_all, new_start, side="left"))]
        pw = prob_w.path(x_w)
        self._frozen.extend(
            np.stack(
                [np.interp(tk, prob_w.tn, pw.real), np.interp(tk, prob_w.tn, pw.imag), np.full(tk.size, np.nan)], axis=1
            )
        )
        t, xy, ft, fz, sig = self._arrays(self._start)
        piece = build_problem(t, xy, ft, fz, sig, self._start, new_start, self.cfg, self._prior)
        sol = solve(piece, _init_from(piece, prob_w, x_w), dense=self.dense)
        self._prior = _marginal_at_end(piece, sol)
        self._start = new_start
        self.marginalised += 1


__all__ = ["IncrementalFuser"]
