"""The floor from the barometer (wearnav.fuse.floors) on synthetic pressure traces: one step up
with weather drift and a door's spike, a sustained ventilation offset, the level fit and the start
floor without truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import make_stream
from wearnav.errors import ValidationError
from wearnav.fuse.beacons import PathLoss
from wearnav.fuse.floors import (
    FloorLevels,
    fit_floor_levels,
    floor_track,
    hpa_per_m,
    start_floor,
)
from wearnav.recording import BeaconReadings, Fixes, Pressure, Recording, Trajectory

RATE_HZ = 10.0
VENUE = FloorLevels({0: 0.0, -1: 0.37, -2: 0.66}, step_hpa=0.33)


def trace(duration_s, moves, drift_hpa_h=1.0, noise=0.02, seed=0, base=977.0):
    """Pressure (10 Hz) of a walk: ``moves`` = [(start_s, length_s, change_hpa)], each a linear ramp
    (a stair), plus linear weather drift and white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1 / RATE_HZ)
    p = base + drift_hpa_h * t / 3600 + noise * rng.standard_normal(t.size)
    for start, length, change in moves:
        p += change * np.clip((t - start) / length, 0.0, 1.0)
    return t, p


def test_hpa_per_m_is_the_hydrostatic_gradient():
    assert hpa_per_m(1013.25, 15.0) == pytest.approx(1.225 * 9.80665 / 100, rel=1e-3)


def test_one_floor_up_with_weather_drift_and_a_door():
    t, p = trace(900.0, [(400.0, 15.0, -0.35)], drift_hpa_h=2.0)
    p[(t > 150) & (t < 153)] += 0.3  # a door: a spike of almost a floor, for 3 s
    p[(t > 600) & (t < 604)] -= 0.3
    t_out = np.arange(0.0, 900.0, 1.0)
    got = floor_track(Pressure(t, p), 0, t_out)  # one step per floor, any floor
    settled = np.abs(t_out - 407.5) > 15.0
    np.testing.assert_array_equal(got[settled], np.where(t_out[settled] < 400, 0, 1))
    # Without the drift compensation the 0.5 hPa of weather over the walk would read as a floor.
    t2, p2 = trace(1800.0, [], drift_hpa_h=1.5)
    assert set(floor_track(Pressure(t2, p2), 0, t2)) == {0}


def test_a_sustained_small_offset_is_not_a_floor():
    """Ventilation: +0.1 hPa for a minute (under a third of a floor) changes nothing."""
    t, p = trace(300.0, [(100.0, 2.0, 0.1), (160.0, 2.0, -0.1)], drift_hpa_h=0.0)
    assert set(floor_track(Pressure(t, p), -1, t, VENUE)) == {-1}


def test_uneven_floors_down_and_back_with_measured_levels():
    t, p = trace(600.0, [(100.0, 20.0, 0.37), (200.0, 20.0, 0.29), (350.0, 40.0, -0.66)])
    t_out = np.array([50.0, 150.0, 300.0, 500.0, 590.0])
    np.testing.assert_array_equal(floor_track(Pressure(t, p), 0, t_out, VENUE), [0, -1, -2, 0, 0])
    with pytest.raises(ValidationError, match="not one of the floors"):
        floor_track(Pressure(t, p), 1, t_out, VENUE)


def test_floor_levels():
    lv = FloorLevels({0: 0.0, -2: 0.66}, step_hpa=0.33)
    assert lv.floors == [-2, -1, 0]
    assert lv.level(-1) == pytest.approx(0.33)  # between the measured floors
    assert lv.level(1) == pytest.approx(-0.33) and lv.level(-3) == pytest.approx(0.99)
    assert FloorLevels().floors is None and FloorLevels(step_hpa=0.4).level(-2) == pytest.approx(0.8)
    assert FloorLevels.from_dict(json.loads(json.dumps(VENUE.to_dict()))) == VENUE
    assert VENUE.height_m(-2, 977.0) == pytest.approx(-0.66 / hpa_per_m(977.0))


def walk(name, floors_at, moves, seed, base):
    t, p = trace(300.0, moves, drift_hpa_h=0.0, seed=seed, base=base)  # the fit ignores drift within a walk
    t_truth = np.arange(10.0, 300.0, 20.0)
    return Recording(
        name=name,
        devices={"phone": make_stream(n=3000, rate=10.0)},
        truth=Trajectory(t_truth, np.zeros((t_truth.size, 2)), floor=[floors_at(x) for x in t_truth]),
        pressure=Pressure(t, p),
    )


def test_fit_floor_levels_recovers_each_floors_pressure():
    recs = [
        walk("down1", lambda x: 0 if x < 100 else -1, [(90.0, 8.0, 0.37)], 1, 976.0),
        walk("down2", lambda x: 0 if x < 100 else -2, [(92.0, 15.0, 0.66)], 2, 981.0),  # another day
        walk("flat", lambda x: -2, [], 3, 990.0),
    ]
    lv = fit_floor_levels(recs)
    assert lv.levels_hpa[0] == 0.0
    assert lv.levels_hpa[-1] == pytest.approx(0.37, abs=0.02) and lv.levels_hpa[-2] == pytest.approx(0.66, abs=0.02)
    assert lv.step_hpa == pytest.approx(0.33, abs=0.02) and lv.fit["walks"] == ["down1", "down2"]
    with pytest.raises(ValidationError, match="no walk over floor 0"):
        fit_floor_levels(recs[2:])


def test_start_floor_without_truth():
    # Two floors down in a building of three: only the top floor can be the start.
    t, p = trace(400.0, [(100.0, 20.0, 0.37), (200.0, 20.0, 0.29)])
    assert start_floor(Pressure(t, p), VENUE) == (0, {"candidates": [0], "by": "barometer"})
    # One floor: sharp fixes say above ground.
    t, p = trace(300.0, [])
    fixes = Fixes(np.arange(0.0, 300.0, 1.0), np.zeros((300, 2)), np.full(300, 4.0))
    assert start_floor(Pressure(t, p), VENUE, fixes=fixes)[0] == 0
    # Blurry fixes say nothing; a beacon on floor -2 heard loud says floor -2.
    blurry = Fixes(fixes.t, fixes.pos, np.full(300, 20.0))
    model = PathLoss(p0_dbm=-60.0, n=2.0, sigma_db=5.0, floor_loss_db=8.0)
    tb = np.arange(1.0, 300.0, 2.0)
    loud = BeaconReadings(tb, np.full(tb.size, "B"), np.full(tb.size, -68.0))
    got, info = start_floor(Pressure(t, p), VENUE, loud, {"B": [0.0, 0.0, -2]}, model, blurry)
    assert (got, info["by"]) == (-2, "beacons") and info["loglik"][-2] > info["loglik"][0]
    # Nothing to go on: the candidate nearest 0.
    assert start_floor(Pressure(t, p), VENUE)[1]["by"] == "default"
