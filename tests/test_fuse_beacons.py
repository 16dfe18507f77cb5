"""The path-loss model of wearnav.fuse.beacons: its fit recovers known parameters, its
log-likelihood broadcasts and matches scipy's densities, and the truth interpolation it fits on."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from conftest import make_stream
from wearnav.errors import ValidationError
from wearnav.fuse.beacons import PathLoss, RangeSamples, fit_path_loss, range_samples, truth_at
from wearnav.recording import BeaconReadings, Recording, Trajectory

TRUE = {"p0_dbm": -62.0, "n": 2.2, "floor_loss_db": 5.0, "offsets": {"phone A": 3.0, "phone B": -3.0}}


def synthetic_samples(n=6000, noise="gauss", seed=0, floor_height_m=3.0) -> RangeSamples:
    rng = np.random.default_rng(seed)
    horizontal = rng.uniform(0.0, 40.0, n)
    floors = rng.integers(0, 3, n).astype(float)
    device = rng.choice(["phone A", "phone B"], n).astype(object)
    d = np.maximum(np.hypot(horizontal, floors * floor_height_m), 1.0)
    mean = (
        TRUE["p0_dbm"]
        + np.array([TRUE["offsets"][x] for x in device])
        - 10 * TRUE["n"] * np.log10(d)
        - TRUE["floor_loss_db"] * floors
    )
    eps = 4.0 * (rng.standard_normal(n) if noise == "gauss" else rng.standard_t(3.0, n))
    return RangeSamples(
        rssi_dbm=mean + eps,
        horizontal_m=horizontal,
        floors=floors,
        beacon=np.full(n, "B1", dtype=object),
        device=device,
        recording=np.full(n, "synthetic", dtype=object),
    )


def test_fit_recovers_known_parameters():
    m = fit_path_loss(synthetic_samples(), floor_height_m=3.0)
    assert m.p0_dbm == pytest.approx(TRUE["p0_dbm"], abs=0.5)
    assert m.n == pytest.approx(TRUE["n"], abs=0.05)
    assert m.floor_loss_db == pytest.approx(TRUE["floor_loss_db"], abs=0.3)
    assert m.offset_db == pytest.approx(TRUE["offsets"], abs=0.3)
    assert m.nu is None and m.sigma_db == pytest.approx(4.0, abs=0.15)
    assert m.fit["noise"] == "gaussian" and m.fit["readings"] == 6000


def test_heavy_tails_choose_student_t():
    m = fit_path_loss(synthetic_samples(noise="t"), floor_height_m=3.0)
    assert m.fit["noise"] == "student-t" and m.nu == pytest.approx(3.0, abs=0.6)
    assert m.sigma_db == pytest.approx(4.0, abs=0.3)
    assert m.n == pytest.approx(TRUE["n"], abs=0.1)
    assert fit_path_loss(synthetic_samples(noise="t"), noise="gauss").nu is None


def test_loglik_broadcasts_and_matches_the_densities():
    g = PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=5.0, floor_loss_db=4.0)
    dist = np.array([0.2, 1.0, 10.0, 30.0])
    ll = g.loglik(-75.0, dist)  # one reading against N particles
    assert ll.shape == (4,)
    mean = -60.0 - 20.0 * np.log10(np.maximum(dist, 1.0))
    np.testing.assert_allclose(ll, stats.norm.logpdf(-75.0, mean, 5.0))
    assert ll[0] == ll[1]  # clipped at d_min
    assert g.loglik(np.array([[-70.0], [-80.0]]), dist).shape == (2, 4)
    np.testing.assert_allclose(g.loglik(-75.0, dist, floors=1), stats.norm.logpdf(-75.0, mean - 4.0, 5.0))
    t = PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=5.0, nu=3.0)
    np.testing.assert_allclose(t.loglik(-75.0, dist), stats.t.logpdf(-75.0, 3.0, mean, 5.0))


def test_device_offset_and_range_inversion():
    m = PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=5.0, offset_db={"A": 4.0})
    assert m.expected_rssi(10.0) == pytest.approx(-80.0)
    a = m.for_device("A")
    assert a.expected_rssi(10.0) == pytest.approx(-76.0)
    assert m.for_device("unknown phone").expected_rssi(10.0) == pytest.approx(-80.0)
    np.testing.assert_allclose(a.range_m(a.expected_rssi([2.0, 10.0, 40.0], 1), 1), [2.0, 10.0, 40.0])
    assert m.distance_m(4.0, floors=-1) == pytest.approx(np.hypot(4.0, m.floor_height_m))


def test_json_round_trip_and_bad_values():
    m = fit_path_loss(synthetic_samples(n=500))
    back = PathLoss.from_dict(json.loads(json.dumps(m.to_dict())))
    assert back == m
    with pytest.raises(ValidationError, match="unknown fields"):
        PathLoss.from_dict({**m.to_dict(), "gain": 1.0})
    with pytest.raises(ValidationError, match="sigma_db"):
        PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=0.0)


def test_truth_at_interpolates_on_one_floor_only():
    truth = Trajectory(
        t=[0.0, 10.0, 20.0, 100.0], pos=[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 0.0]], floor=[0, 0, -1, -1]
    )
    pos, floor, ok = truth_at(truth, np.array([-1.0, -3.0, 5.0, 11.0, 15.0, 19.0, 50.0, 101.5]), margin_s=2.0)
    np.testing.assert_array_equal(ok, [True, False, True, True, False, True, False, True])
    np.testing.assert_allclose(pos[ok], [[0, 0], [5, 0], [10, 0], [10, 10], [0, 0]])
    np.testing.assert_array_equal(floor[ok], [0, 0, 0, -1, -1])
    # the 80-s gap is too long to interpolate across (TRUTH_MAX_SPAN_S)


def test_fit_from_recordings_pairs_readings_with_truth():
    """A walk along a corridor past one beacon: the fit through range_samples finds the model."""
    rng = np.random.default_rng(1)
    t_truth = np.arange(0.0, 201.0, 10.0)
    truth = Trajectory(t_truth, np.column_stack([t_truth * 0.5 - 50.0, np.zeros_like(t_truth)]), floor=np.zeros(21))
    t = np.sort(rng.uniform(0.0, 200.0, 4000))
    t = t[np.r_[True, np.diff(t) > 0]]
    x = t * 0.5 - 50.0
    names = np.where(rng.random(t.size) < 0.5, "B1", "B2").astype(object)
    where = {"B1": [0.0, 5.0, 0], "B2": [20.0, -8.0, -1]}
    bx = np.array([where[b] for b in names])
    d = np.hypot(np.hypot(x - bx[:, 0], bx[:, 1]), np.abs(bx[:, 2]) * 3.0)
    rssi = -60.0 - 25.0 * np.log10(np.maximum(d, 1.0)) - 6.0 * np.abs(bx[:, 2]) + 3.0 * rng.standard_normal(t.size)
    rec = Recording(
        name="corridor",
        devices={"phone": make_stream(n=20001, rate=100.0)},
        truth=truth,
        beacons=BeaconReadings(t, names, np.clip(rssi, -129, -1)),
        meta={"beacons": where, "device": "phone A"},
    )
    s = range_samples(rec)
    assert s is not None and len(s) == t.size
    m = fit_path_loss([rec], floor_height_m=3.0)
    assert m.p0_dbm == pytest.approx(-60.0, abs=1.0) and m.n == pytest.approx(2.5, abs=0.1)
    assert m.floor_loss_db == pytest.approx(6.0, abs=0.5) and m.offset_db == {"phone A": 0.0}
    with pytest.raises(ValidationError, match="no beacon readings"):
        fit_path_loss([Recording(name="none", devices={"phone": make_stream()})])
