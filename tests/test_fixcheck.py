"""wearnav.fixcheck: cached, wide, stale and jumping fixes are dropped before anchoring, with a
reason each; fixes that only scatter (white noise, a bias wandering over minutes) keep every one."""

import glob

import numpy as np
import pytest

from wearnav import fixcheck
from wearnav.fixcheck import DROPPED, JUMP, NO_POSITION, OUTSIDE, REPEAT, WIDE, check_fixes, jumps


def walk_fixes(duration_s=600.0, sigma_m=3.0, bias_m=0.0, seed=0):
    """1-Hz fixes of a 1.3 m/s walk with turns: times (M,), fixes (M, 2) m, accuracy (M,) m and
    the truth at the fix times. ``bias_m``: the stationary σ of a bias wandering over ~2 minutes."""
    rng = np.random.default_rng(seed)
    ft = np.arange(0.0, duration_s, 1.0)
    heading = np.cumsum(np.where(rng.random(ft.size) < 0.02, rng.choice([-1, 1], ft.size) * np.pi / 2, 0.0))
    truth = np.cumsum(1.3 * np.stack([np.cos(heading), np.sin(heading)], 1), axis=0)
    a = np.exp(-1.0 / 120.0)
    bias = np.zeros((ft.size, 2))
    for k in range(1, ft.size):
        bias[k] = a * bias[k - 1] + np.sqrt(1 - a**2) * bias_m * rng.standard_normal(2)
    z = truth + bias + rng.normal(0, sigma_m, (ft.size, 2))
    return ft, z, np.full(ft.size, 1.515 * sigma_m), truth


@pytest.mark.parametrize("bias_m", [0.0, 8.0])
def test_fixes_that_only_scatter_are_all_kept(bias_m):
    """10 minutes of 1-Hz fixes, 3 m white noise per axis (accuracy 4.5 m), with or without an 8-m
    bias wandering over 2 minutes: no fix is dropped."""
    ft, z, acc, _ = walk_fixes(bias_m=bias_m)
    check = check_fixes(ft[0], ft[-1], ft, z, acc, wide_m=100.0)
    assert check.counts() == {"used": ft.size, "down-weighted": 0, "unused": 0, "dropped": 0}
    assert not check.warnings


def test_fast_fixes_claiming_too_little_are_kept():
    """10-Hz fixes scattering 2 m per axis while claiming 1.5 m (a 68 % radius of 1 m per axis):
    consecutive fixes differ by more than their claims allow, but not by twice their accuracy
    floored at 3 m (JUMP_MARGIN, JUMP_MIN_ACCURACY_M): none is dropped."""
    ft, _, _, truth = walk_fixes(sigma_m=0.0)
    t = np.arange(0.0, ft[-1], 0.1)
    z = np.stack([np.interp(t, ft, truth[:, k]) for k in range(2)], 1)
    z += np.random.default_rng(0).normal(0, 2.0, z.shape)
    check = check_fixes(t[0], t[-1], t, z, np.full(t.size, 1.5), wide_m=100.0)
    assert check.counts()["dropped"] == 0 and not check.warnings


def test_cached_wide_stale_outside_and_invalid_fixes_are_dropped_with_a_reason():
    """The first fix cached 400 m away claiming 5 m, the second 1500 m wide (and 700 m off), the
    third a NaN position, the fourth a repeat of the fifth's position before it, one glitch 80 m
    off mid-walk claiming 4 m, and two fixes outside the walk: each dropped for its reason, the
    rest kept."""
    ft, z, acc, _ = walk_fixes(duration_s=300.0)
    z[0] += [400.0, -50.0]
    acc[0] = 5.0
    z[1] += [500.0, 500.0]
    acc[1] = 1500.0
    z[2] = np.nan
    z[5] = z[4]
    z[150] += [0.0, 80.0]
    acc[150] = 4.0
    ft = np.concatenate([[-20.0], ft, [400.0]])
    z = np.concatenate([[z[0]], z, [z[-1]]])
    acc = np.concatenate([[5.0], acc, [5.0]])
    check = check_fixes(0.0, 299.0, ft, z, acc, wide_m=100.0)
    assert check.dropped() == {NO_POSITION: [3], OUTSIDE: [0, ft.size - 1], WIDE: [2], REPEAT: [6], JUMP: [1, 151]}
    assert check.counts()["used"] == ft.size - 7 and check.counts()["dropped"] == 7
    assert set(check.status) == {"used", DROPPED}
    assert np.all(check.weight[check.status == DROPPED] == 0) and np.all(check.weight[check.kept] == 1)
    info = check.info()
    assert info["fixes_dropped"] == {NO_POSITION: 1, OUTSIDE: 2, WIDE: 1, REPEAT: 1, JUMP: 2}
    assert info["fix_status"]["dropped"] == 7


def test_a_cached_run_of_fixes_is_judged_against_the_later_fixes():
    """The first 20 fixes (20 s) sit at a cached place 300 m away, jittering by 2 m: the run is
    consistent within itself, but the walk's majority after it is not: all 20 are jumps, none of
    the others. The same run at the end of a walk is dropped too."""
    ft, z, acc, _ = walk_fixes(duration_s=200.0, seed=2)
    rng = np.random.default_rng(5)
    bad = z.copy()
    bad[:20] = z[25] + [300.0, 0.0] + rng.normal(0, 2.0, (20, 2))
    assert np.flatnonzero(jumps(ft, bad, acc)).tolist() == list(range(20))
    bad = z.copy()
    bad[-20:] = z[-25] + [0.0, -300.0] + rng.normal(0, 2.0, (20, 2))
    assert np.flatnonzero(jumps(ft, bad, acc)).tolist() == list(range(ft.size - 20, ft.size))


def test_two_fixes_that_disagree_trust_the_later():
    """Two fixes 400 m apart a second apart: the earlier is the cached one."""
    assert jumps(np.array([0.0, 1.0]), np.array([[400.0, 0.0], [0.0, 0.0]]), np.array([5.0, 5.0])).tolist() == [
        True,
        False,
    ]


def test_fixes_that_jump_everywhere_drop_none_and_warn():
    """Fixes anywhere in ±500 m each second (most imply > 10 m/s from any other): they disagree
    with each other, not with a few outliers; none is dropped as a jump, and a warning says so."""
    rng = np.random.default_rng(3)
    ft = np.arange(0.0, 300.0, 1.0)
    check = check_fixes(0.0, 299.0, ft, rng.uniform(-500, 500, (ft.size, 2)), np.full(ft.size, 3.0), 100.0)
    assert check.counts()["dropped"] == 0
    assert len(check.warnings) == 1 and "disagree with each other" in check.warnings[0]


def test_only_wide_fixes_are_all_dropped_and_said():
    ft = np.arange(0.0, 60.0, 1.0)
    check = check_fixes(0.0, 59.0, ft, np.zeros((ft.size, 2)) + ft[:, None], np.full(ft.size, 800.0), 100.0)
    assert check.counts()["dropped"] == ft.size and check.dropped() == {WIDE: list(range(ft.size))}
    assert "wider than 100 m" in check.warnings[0]


def test_nan_accuracy_takes_the_median_and_no_fix_at_all_is_empty():
    np.testing.assert_allclose(fixcheck.filled_accuracy(np.array([np.nan, 4.0, -1.0, 6.0])), [5.0, 4.0, 5.0, 6.0])
    empty = check_fixes(0.0, 10.0, np.empty(0), np.empty((0, 2)), np.empty(0), 100.0)
    assert empty.counts() == {"used": 0, "down-weighted": 0, "unused": 0, "dropped": 0}


@pytest.mark.real_data
def test_real_ipin_walks_drop_their_cached_start_and_hardly_anything_else(shared_data):
    """IPIN 2023's 42 training walks (indoor/outdoor phone fixes, accuracy 4–192 m): the fixes
    dropped as jumps are exactly the first two of TrainingTrial24 repetition 01 (2.6 km and 1.5 km
    from the walk, claiming 61 m and 39 m: cached positions); as wide, the three of Trial23
    repetition 03 over 100 m."""
    from wearnav.importers import ipin2023

    found = {}
    logs = sorted(glob.glob(str(shared_data / "ipin2023_track3" / "01 Logfiles" / "*" / "*.txt.xz")))
    assert len(logs) == 42
    for log in logs:
        for rec in ipin2023.read(log):
            fx = rec.fixes
            check = check_fixes(fx.t[0], fx.t[-1], fx.t, fx.pos[:, :2], fx.accuracy, 100.0)
            for reason in (JUMP, WIDE):
                if check.dropped().get(reason):
                    found[(rec.name.split("T3_")[-1], reason)] = check.dropped()[reason]
            assert not check.warnings
    assert found.pop(("TrainingTrial24_repetition01", JUMP)) == [0, 1]
    assert set(found) == {("TrainingTrial23_repetition03", WIDE)} and len(found[next(iter(found))]) == 3
