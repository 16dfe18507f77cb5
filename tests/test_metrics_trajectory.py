"""ATE / RTE / CDF / ADE against hand computations and against the evo package."""

import numpy as np
import pytest
from evo.core import metrics as evo_metrics
from evo.core.trajectory import PoseTrajectory3D

from wearnav.errors import ValidationError
from wearnav.metrics import ade, ate, ecdf, position_errors, rte


def _evo_traj(t, pos):
    xyz = np.column_stack([pos, np.zeros(len(pos))])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (len(pos), 1))
    return PoseTrajectory3D(positions_xyz=xyz, orientations_quat_wxyz=quat, timestamps=t)


def _random_walks(seed, n=400, rate=5.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    true = np.cumsum(rng.normal(0, 0.3, (n, 2)), axis=0)
    est = true + np.cumsum(rng.normal(0, 0.05, (n, 2)), axis=0)
    est -= est[0] - true[0]
    return t, est, true


def test_ate_hand_computed():
    t = [0.0, 1.0, 2.0]
    true = [[0, 0], [1, 0], [2, 0]]
    est = [[0, 0], [1, 3], [2, 4]]  # errors 0, 3, 4 -> RMS sqrt(25/3)
    assert ate(t, est, true) == pytest.approx(np.sqrt(25 / 3))


def test_rte_hand_computed_and_short_sequence_scaling():
    t = np.arange(5.0)
    true = np.column_stack([t, np.zeros(5)])
    est = np.column_stack([t, 0.5 * t])  # lateral drift 0.5 m/s
    # Δ = 2 s: every pair's displacement error is 1 m
    assert rte(t, est, true, delta=2.0) == pytest.approx(1.0)
    # sequence of 4 s shorter than Δ = 60 s: whole-length error 2 m scaled by 60/4
    assert rte(t, est, true, delta=60.0) == pytest.approx(2.0 * 60 / 4)


@pytest.mark.parametrize("seed", range(5))
def test_ate_matches_evo_ape(seed):
    t, est, true = _random_walks(seed)
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((_evo_traj(t, true), _evo_traj(t, est)))
    assert ate(t, est, true) == pytest.approx(ape.get_statistic(evo_metrics.StatisticsType.rmse), rel=1e-9)
    np.testing.assert_allclose(np.sort(position_errors(t, est, true)), np.sort(ape.error), rtol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_rte_matches_evo_rpe_all_pairs(seed):
    rate, delta = 5.0, 12.0
    t, est, true = _random_walks(seed, rate=rate)
    rpe = evo_metrics.RPE(
        evo_metrics.PoseRelation.translation_part,
        delta=int(delta * rate),
        delta_unit=evo_metrics.Unit.frames,
        all_pairs=True,
    )
    rpe.process_data((_evo_traj(t, true), _evo_traj(t, est)))
    ref = rpe.get_statistic(evo_metrics.StatisticsType.rmse)
    assert rte(t, est, true, delta=delta) == pytest.approx(ref, rel=1e-9)


def test_perfect_estimate_scores_zero_and_an_offset_does_not():
    t, _, true = _random_walks(0)
    assert ate(t, true, true) == 0.0 and rte(t, true, true, 10.0) == 0.0
    shifted = true + [1.0, 0.0]
    assert ate(t, shifted, true) == pytest.approx(1.0)
    assert rte(t, shifted, true, 10.0) == pytest.approx(0.0, abs=1e-12)  # a constant offset has no drift


def test_cdf_and_ade():
    e, p = ecdf([3.0, 1.0, 2.0, 2.0])  # a tie is one step of twice the height
    np.testing.assert_allclose(e, [1, 2, 3])
    np.testing.assert_allclose(p, [0.25, 0.75, 1.0])
    assert ade([[0, 0], [3, 4]], [[0, 1], [0, 0]]) == pytest.approx((1 + 5) / 2)


def test_bad_input_is_a_validation_error():
    with pytest.raises(ValidationError):
        ate([0, 1], [[0, 0]], [[0, 0], [1, 1]])
    with pytest.raises(ValidationError):
        rte([0, 1, 2], [[0, 0]] * 3, [[0, 0]] * 3, delta=0)
    with pytest.raises(ValidationError):
        ecdf([])
    with pytest.raises(ValidationError):
        ecdf([1.0, np.nan])
