"""fuse.placement (issue 36): the particle filter fed with fixes, beacons and the barometer."""

import numpy as np
import pytest

from conftest import make_stream
from wearnav.errors import ValidationError
from wearnav.fuse.beacons import PathLoss
from wearnav.fuse.floors import FloorLevels
from wearnav.fuse.particles import MapConfig
from wearnav.fuse.placement import SiteModels, fit_site_models, floors_over_time, place
from wearnav.recording import BeaconReadings, Fixes, Pressure, Recording, Trajectory

MODEL = PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=3.0)
BEACONS = {"b1": [10.0, 5.0, 0], "b2": [30.0, -5.0, 0], "b3": [50.0, 5.0, 0]}


def straight_walk(seed=0, with_beacons=True):
    """60 m east at 1 m/s; fixes only in the first 5 s; readings of three beacons along the way; the
    odometry 25° off and 10 % short."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 60.0, 0.1)
    true = np.stack([t, np.zeros_like(t)], 1)
    a = np.radians(25.0)
    odo = 0.9 * true @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    ft = np.arange(0.0, 5.0, 1.0)
    fixes = Fixes(ft, true[(ft * 10).astype(int)] + rng.normal(0, 1.0, (ft.size, 2)), np.full(ft.size, 3.0))
    bt, names, rssi = [], [], []
    for name, (bx, by, _) in BEACONS.items():
        for tk in np.arange(0.0, 60.0, 0.5):
            d = float(np.hypot(tk - bx, by))
            if d < 20:
                bt.append(tk)
                names.append(name)
                rssi.append(float(MODEL.expected_rssi(d)) + rng.normal(0, 3.0))
    order = np.argsort(bt, kind="stable")
    rec = Recording(
        "walk",
        {"phone": make_stream(600, rate=10.0)},
        truth=Trajectory(t[::50], true[::50]),
        fixes=fixes,
        beacons=BeaconReadings(np.array(bt)[order], np.array(names)[order], np.array(rssi)[order])
        if with_beacons
        else None,
        meta={"beacons": BEACONS},
    )
    return rec, t, odo, true


def test_beacons_pull_a_turned_short_path_back():
    rec, t, odo, true = straight_walk()
    cfg = MapConfig(particles=500, scale_log_sigma=0.2, start_heading_sigma_deg=30)
    without, _ = place(rec, t, odo, SiteModels(), cfg=cfg)
    with_b, _ = place(rec, t, odo, SiteModels(path_loss=MODEL), cfg=cfg)
    e0 = np.linalg.norm(without.xy - true, axis=1)
    e1 = np.linalg.norm(with_b.xy - true, axis=1)
    assert with_b.info["beacon_readings_used"] > 100 and without.info["beacon_readings_used"] == 0
    assert np.median(e1) < 0.5 * np.median(e0)
    assert e1[-1] < 5.0 < e0[-1]


def test_place_needs_fixes_or_a_start():
    rec, t, odo, _ = straight_walk(with_beacons=False)
    rec.fixes = None
    with pytest.raises(ValidationError, match="--start"):
        place(rec, t, odo)
    res, check = place(rec, t, odo, start=(0.0, 0.0, 0.0), cfg=MapConfig(particles=100))
    assert check is None and res.info["start"] == "given"


def test_site_models_fit_and_round_trip():
    rec, *_ = straight_walk()
    rec.truth = Trajectory(np.arange(0.0, 60.0, 1.0), np.stack([np.arange(0.0, 60.0), np.zeros(60)], 1))
    site = fit_site_models([rec])
    assert site.path_loss is not None and site.levels is None  # no barometer: no floor levels
    assert site.path_loss.n == pytest.approx(2.0, abs=0.3)
    back = SiteModels.from_dict(site.to_dict())
    assert back.path_loss is not None and back.path_loss.p0_dbm == pytest.approx(site.path_loss.p0_dbm)


def test_floors_over_time_follows_the_barometer():
    rec, *_ = straight_walk(with_beacons=False)
    t = np.arange(0.0, 60.0, 0.5)
    rec.pressure = Pressure(t, np.where(t < 30, 977.0, 977.0 + 0.33))  # one floor down at 30 s
    levels = FloorLevels(levels_hpa={0: 0.0, -1: 0.33}, step_hpa=0.33)
    floor_at, info = floors_over_time(rec, SiteModels(levels=levels))
    assert floor_at is not None and info["start_floor"] == 0
    assert floor_at(np.array([10.0, 50.0])).tolist() == [0.0, -1.0]


def test_fixes_that_lag_are_read_at_the_walkers_time():
    """MapConfig.fix_lag_s (issue 36; the smoother's FuseConfig.fix_lag_s): fixes stamped 4 s after
    the walker was there pull a filter that reads them on time 4 m behind along the walk; read at
    their lag, the path lies on the truth."""
    rec, t, odo, true = straight_walk(seed=1, with_beacons=False)
    rng = np.random.default_rng(2)
    ft = np.arange(4.0, 60.0, 1.0)
    rec.fixes = Fixes(ft, true[((ft - 4.0) * 10).astype(int)] + rng.normal(0, 1.0, (ft.size, 2)), np.full(ft.size, 3.0))
    cfg = MapConfig(particles=300, scale_log_sigma=0.2, start_heading_sigma_deg=30)
    errors = {}
    for lag in (0.0, 4.0):
        res, _ = place(rec, t, odo, cfg=MapConfig(**{**cfg.__dict__, "fix_lag_s": lag}))
        errors[lag] = np.linalg.norm(res.xy - true, axis=1)[100:]  # after the first 10 s
        assert res.info["config"]["fix_lag_s"] == lag
    assert np.median(errors[4.0]) < 1.5 < 2.5 < np.median(errors[0.0])
    with pytest.raises(ValidationError, match="fix_lag_s"):
        MapConfig(fix_lag_s=-1.0)
