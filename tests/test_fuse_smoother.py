"""wearnav.fuse.smoother: the analytic Jacobian is the derivative of the residuals (every block the
problem can have: heading walk, odometry walk, heading prior, the frozen past's prior; outliers
under the Cauchy loss, a fix with no residual), and solving with it gives the path the
finite-difference Jacobian gave."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from test_fuse import fixes_of, odometry_of, walk
from wearnav import fuse
from wearnav.fuse import live as fuse_live
from wearnav.fuse import smoother
from wearnav.fuse.smoother import Prior, Problem, build_problem


def _problem(cfg=fuse.FuseConfig(), duration_s=300.0, prior=False, seed=0, t0=0.0):
    t, truth = walk(duration_s, seed=seed)
    rng = np.random.default_rng(seed + 10)
    xy = odometry_of(truth) + np.cumsum(rng.normal(0, 0.1 * np.sqrt(0.5), (t.size, 2)), axis=0)
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.2, seed=seed + 1)
    pr = None
    if prior:
        a = rng.normal(size=(Prior.size, Prior.size))
        pr = Prior(rng.normal(size=Prior.size) * 10, np.triu(a) + 3 * np.eye(Prior.size))
    sigma = fuse.fix_sigma_m(acc)
    return build_problem(t, xy, ft, z[:, 0] + 1j * z[:, 1], sigma, t0 + t[0], t[-1], cfg, pr)


def _random_x(prob: Problem, seed: int) -> np.ndarray:
    """Parameters near a solution's size: an angle, a scale near 1, a drift, an origin, metres of
    bias and odometry walk, a few degrees of heading walk."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 1.0, prob.n_params)
    x[0], x[1], x[2] = rng.uniform(-np.pi, np.pi), rng.normal(0.2, 0.05), rng.normal(0, 1e-3)
    x[3:5] = rng.normal(100.0, 5.0, 2)
    x[prob.h0 : prob.s0] *= 0.05
    return x


def _central_difference(prob: Problem, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences, each step h times the unknown's size (the drift's: 1 / the longest τ,
    as it turns the path by ω τ)."""
    size = np.ones(len(x))
    size[2] = 1.0 / np.abs(prob.tau).max()
    j = np.empty((len(prob.residuals(x)), len(x)))
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = h * max(size[i], abs(x[i]))
        j[:, i] = (prob.residuals(x + e) - prob.residuals(x - e)) / (2 * e[i])
    return j


CONFIGS = {
    "default": fuse.FuseConfig(),
    "no walks": fuse.FuseConfig(heading_walk_deg_per_sqrt_min=0.0, odometry_walk_m_per_sqrt_s=0.0),
    "heading walk only": fuse.FuseConfig(odometry_walk_m_per_sqrt_s=0.0),
    "odometry walk only": fuse.FuseConfig(heading_walk_deg_per_sqrt_min=0.0),
    "heading prior": fuse.FuseConfig(heading_prior_deg=10.0),
    "bias share, lag, short knots": fuse.FuseConfig(**fuse.MEASURED_FIX_BIAS, fix_lag_s=0.7),
}


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("prior", [False, True])
def test_jacobian_is_the_derivative_of_the_residuals(name, prior):
    """Against central differences at random parameters (fixes with 20 % outliers and a start
    between nodes: many fixes are far out on the Cauchy loss), to 1e-6 of the Jacobian's largest
    entry in each column (the differences' own error is about 1e-8 of it)."""
    prob = _problem(CONFIGS[name], prior=prior, t0=0.25)
    assert (prob.prior is not None) == prior
    for seed in range(3):
        x = _random_x(prob, seed)
        j = prob.jacobian(x)
        assert j.format == "csr" and j.shape == (len(prob.residuals(x)), prob.n_params)
        ref = _central_difference(prob, x)
        scale = np.maximum(np.abs(ref).max(axis=0), 1e-12)
        assert (np.abs(j.toarray() - ref).max(axis=0) / scale).max() < 1e-6
        r = np.abs(prob.fix_residual(x))
        assert np.sum(r > 3 * prob.cfg.robust_scale) > 10  # the Cauchy scaling is far from 1 there
        pattern = prob.sparsity().tocsr()  # the finite-difference solve's pattern covers every entry
        assert pattern.shape == j.shape and np.all(pattern.toarray()[j.toarray() != 0])


def test_jacobian_where_fixes_have_no_residual_and_where_there_are_none():
    """A fix exactly on the path (|r| = 0, the Cauchy scale's limit 1) and one at 1e-7 σ; and a
    window without fixes (the live smoother's, between fixes)."""
    prob = _problem(duration_s=120.0)
    x = _random_x(prob, 5)
    r = prob.fix_residual(x)
    prob.fz = prob.fz + r * prob.sigma  # every residual 0
    prob.fz[1] -= 1e-7 * prob.sigma[1]
    prob.fz[2] -= (1e-3 + 1e-3j) * prob.sigma[2]  # either side of where the scale's derivative
    prob.fz[3] -= (0.044 + 0.044j) * prob.sigma[3]  # changes from its series (|r|² / c² < 1e-3)
    prob.fz[4] -= (0.046 - 0.046j) * prob.sigma[4]  # to its closed form
    ref = _central_difference(prob, x)
    assert np.abs(prob.fix_residual(x)[0]) == 0.0
    np.testing.assert_allclose(prob.jacobian(x).toarray(), ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())
    t = np.arange(0.0, 40.0, 0.5)
    none = build_problem(
        t, np.stack([t, 0 * t], 1), np.array([]), np.array([], complex), np.array([]), 0.0, t[-1], prob.cfg
    )
    x = _random_x(none, 6)
    np.testing.assert_allclose(none.jacobian(x).toarray(), _central_difference(none, x), atol=1e-6)


def _solve_by_differences(prob: Problem, x0: np.ndarray, dense: bool = False):
    """The solve as it was before the analytic Jacobian (a sparse finite-difference one, LSMR
    steps; ``dense`` ignored: the reference for the live smoother's dense steps too)."""
    return least_squares(
        prob.residuals, x0, jac_sparsity=prob.sparsity(), method="trf", x_scale="jac", ftol=1e-6, xtol=1e-6
    )


def _walk_inputs(duration_s, seed):
    t, truth = walk(duration_s, seed=seed)
    rng = np.random.default_rng(seed + 10)
    xy = odometry_of(truth) + np.cumsum(rng.normal(0, 0.1 * np.sqrt(0.5), (t.size, 2)), axis=0)
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.05, seed=seed + 1)
    return t, xy, ft, z, acc


SOLVED = ["default", "no walks", "heading prior", "bias share, lag, short knots"]


@pytest.mark.parametrize("name", SOLVED)
@pytest.mark.parametrize("seed", [0, 3])
def test_smooth_gives_the_path_of_the_finite_difference_jacobian(name, seed, monkeypatch):
    """On a simulated 2-min walk (the live smoother's window size; 5 % outliers, an odometry
    random walk), the smoothed path with the analytic Jacobian is within 1 mm of the one with the
    finite-difference Jacobian (measured: 0.01–0.25 mm; the finite-difference solve with another
    difference step moves its own path 0.7–7 mm)."""
    t, xy, ft, z, acc = _walk_inputs(120.0, seed=seed)
    new = fuse.smooth(t, xy, ft, z, acc, CONFIGS[name])
    monkeypatch.setattr(smoother, "solve", _solve_by_differences)
    old = fuse.smooth(t, xy, ft, z, acc, CONFIGS[name])
    assert new.method == old.method == "smooth"
    assert np.abs(new.xy - old.xy).max() < 1e-3


@pytest.mark.parametrize("name", SOLVED)
def test_smooth_on_a_longer_walk_ends_as_low_as_the_finite_difference_one(name, monkeypatch):
    """On a 10-min walk the solve stops (ftol 1e-6) where the cost is flat to 1e-6: the paths with
    the analytic and the finite-difference Jacobian end 2–141 mm apart (12 walks measured), about
    as far as the finite-difference solve's from itself with another difference step (4–127 mm).
    The analytic solve's cost is no higher than the finite-difference one's by more than ftol."""
    t, xy, ft, z, acc = _walk_inputs(600.0, seed=3)
    cost = {}

    def recording(solver, key):
        def run(prob, x0):
            sol = solver(prob, x0)
            cost[key] = sol.cost
            return sol

        return run

    monkeypatch.setattr(smoother, "solve", recording(smoother.solve, "analytic"))
    new = fuse.smooth(t, xy, ft, z, acc, CONFIGS[name])
    monkeypatch.setattr(smoother, "solve", recording(_solve_by_differences, "differences"))
    old = fuse.smooth(t, xy, ft, z, acc, CONFIGS[name])
    assert new.method == old.method == "smooth"
    assert cost["analytic"] <= cost["differences"] * (1 + 1e-6)


def test_fixed_lag_gives_the_path_of_the_finite_difference_jacobian(monkeypatch):
    """The live smoother (a 120-s window updated every 20 s, each window under the frozen past's
    prior) on a 6-min walk: every update's path within 1 mm of the finite-difference one's."""
    t, xy, ft, z, acc = _walk_inputs(360.0, seed=5)

    def run(dense: bool = False):
        inc, fi, out = fuse_live.IncrementalFuser(lag_s=120.0, step_s=30.0, dense=dense), 0, []
        for k in range(t.size):
            inc.add_odometry(t[k], xy[k])
            while fi < ft.size and ft[fi] <= t[k]:
                inc.add_fix(ft[fi], *z[fi], acc[fi])
                fi += 1
            if k % 40 == 39:
                out.append(inc.result())
        return out

    new, dense = run(), run(dense=True)
    monkeypatch.setattr(fuse_live, "solve", _solve_by_differences)
    monkeypatch.setattr(smoother, "solve", _solve_by_differences)
    old = run()
    assert new[-1].method == "smooth-fixed-lag" and new[-1].info["slices_marginalised"] >= 6
    for a, b in zip(new, old, strict=True):
        assert a.method == b.method and np.abs(a.xy - b.xy).max() < 1e-3
    # the live default's dense steps (issue 61): the same minimum to the solver's tolerances
    # (ftol = xtol = 1e-6 either way; measured 1.74 mm at most, marginalised windows included)
    for a, b in zip(dense, new, strict=True):
        assert a.method == b.method and np.abs(a.xy - b.xy).max() < 2e-3


def test_fixed_lag_windows_with_a_heading_prior_solve():
    """The live smoother's windows carry the frozen past's prior and, where the frame is
    north-referenced, a heading prior: the finite-difference sparsity had a row too many there
    (the heading prior, which the frozen past's prior replaces)."""
    t, truth = walk(240.0, seed=4)
    xy = odometry_of(truth, yaw_deg=0.0)
    ft, z, acc, _ = fixes_of(t, truth, outliers=0.05)
    inc = fuse_live.IncrementalFuser(fuse.FuseConfig(heading_prior_deg=0.0), lag_s=60.0, step_s=30.0)
    fi = 0
    for k in range(t.size):
        inc.add_odometry(t[k], xy[k])
        while fi < ft.size and ft[fi] <= t[k]:
            inc.add_fix(ft[fi], *z[fi], acc[fi])
            fi += 1
        if k % 40 == 39:
            res = inc.result()
    assert res.method == "smooth-fixed-lag" and res.info["slices_marginalised"] >= 4
    assert np.median(np.linalg.norm(res.xy - truth, axis=1)) < 3.0


def test_jacobian_follows_a_changed_fix_bias_sigma():
    """build_problem sets the fix bias's σ after the problem is made: the Jacobian's cached
    prior rows follow it."""
    prob = _problem(duration_s=120.0)
    x = _random_x(prob, 7)
    prob.jacobian(x)
    prob.bias_sigma_m *= 3.0
    np.testing.assert_allclose(prob.jacobian(x).toarray(), _central_difference(prob, x), atol=1e-6)
