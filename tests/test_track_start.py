"""`wearnav track --start X,Y,HEADING_DEG` places the path where no floor plan is used (issue 56 §4):
the odometry turned so that its first metres run along HEADING_DEG (degrees counter-clockwise
from +x, as the map-aware path reads it) and moved so that it starts at X, Y; ``track.json``
``anchoring.method`` says "start". Before, the pose went only to the particle filter, so without a
plan the path kept its odometry frame from (0, 0) and trajectory.csv had no east/north.

The walk: 30 s simulated, phone in hand (seed 0, whose route runs straight for its first metres:
checked on its truth, which only the check reads). ``--model pdr``: the placement, not the model,
is what is tested.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from wearnav.fuse.particles import START_DIR_M
from wearnav.importers.sensorlogger_export import write_export
from wearnav.simulate import WalkConfig, simulate_recording

START = (12.5, -7.0, 135.0)  # X, Y (m), heading of travel (deg counter-clockwise from +x)
# "the first few metres": the stretch whose direction a start heading gives, for the map-aware path too
FIRST_M = START_DIR_M
HEADING_TOL_DEG = 3.0


@pytest.fixture(scope="module")
def walk():
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=30, devices=("phone",)), seed=0)
    assert rec.fixes is not None and len(rec.fixes) and not rec.plans
    return rec


def _direction_deg(xy: np.ndarray, metres: float) -> float:
    """The direction (deg, counter-clockwise from +x) from the path's first point to where it has
    run ``metres`` along itself."""
    along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
    v = xy[int(np.searchsorted(along, metres))] - xy[0]
    return float(np.degrees(np.arctan2(v[1], v[0])))


def _angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def test_the_walk_runs_straight_at_first(walk):
    """The precondition of the heading checks below: the truth's first 3 m and 6 m point the same way."""
    xy = walk.truth.pos[:, :2]
    assert _angle_diff_deg(_direction_deg(xy, FIRST_M), _direction_deg(xy, 2 * FIRST_M)) < 6.0


def _check_placed_from_start(monkeypatch, capsys, src, out, *extra):
    code, _, err = run_cli(
        monkeypatch, capsys, "track", src, "--model", "pdr", "--out", out, "--start", ",".join(map(str, START)), *extra
    )
    assert code == 0, err
    summary = json.loads((out / "track.json").read_text())
    table = pd.read_csv(out / "trajectory.csv")
    assert {"east", "north"} <= set(table.columns), "the path is not placed"
    xy = table[["east", "north"]].to_numpy()
    heading = _direction_deg(xy, FIRST_M)
    print(f"first point {xy[0].round(3)}, first {FIRST_M:g} m towards {heading:.1f}° (given {START[2]:g}°)")
    assert np.allclose(xy[0], START[:2], atol=1e-3)
    assert _angle_diff_deg(heading, START[2]) < HEADING_TOL_DEG
    assert summary["anchoring"]["method"] == "start"
    assert summary["anchoring"]["start"] == list(START)
    assert summary["map"]["used"] is False
    return summary


def test_start_places_the_path_with_map_none(walk, monkeypatch, capsys, tmp_path):
    """A Sensor Logger export with fixes, `--map none --start`: the start wins over the fixes (which
    are checked and kept in fixes.csv, marked unused), as a map-aware path would start there too."""
    src = write_export(walk, tmp_path / "2023-11-14_22-13-20", platform="android")
    summary = _check_placed_from_start(monkeypatch, capsys, src, tmp_path / "out", "--map", "none")
    fixes = pd.read_csv(tmp_path / "out" / "fixes.csv")
    assert len(fixes) and set(fixes["status"]) <= {"unused", "dropped"}
    assert summary["anchoring"]["fix_status"]["used"] == 0


def test_start_places_a_recording_without_plan_or_fixes(walk, monkeypatch, capsys, tmp_path):
    """A recording with neither a floor plan nor fixes (default --map auto): placed from the start,
    where it used to stay at (0, 0) in the odometry's own frame."""
    src = dataclasses.replace(walk, fixes=None).save(tmp_path / "walk.h5")
    summary = _check_placed_from_start(monkeypatch, capsys, src, tmp_path / "out")
    assert summary["map"]["plans"] == [] and not (tmp_path / "out" / "fixes.csv").exists()
    assert not any("no location fixes" in w for w in summary["warnings"])
