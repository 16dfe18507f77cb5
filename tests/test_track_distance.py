"""`wearnav track` says when the odometry walks far less than the fixes move or the activity model's
walking time says (issue 56 §6): a path made of the fixes alone is not shown as an inertial path
without a word; a normal walk gets no such line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wearnav.core.rotations import from_wxyz
from wearnav.dataset import DatasetWriter
from wearnav.errors import WearnavWarning
from wearnav.recording import Recording
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.track import track
from wearnav.train.odometry import TrainConfig, fit, prepare_run

FIXES_LINE = "the odometry walked far less than the fixes moved"
ACTIVITY_LINE = "the odometry walked far less than the activity model says"


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """A 90 s simulated walk (phone in the hand, fixes) and a PDR run, as `wearnav train pdr` leaves
    it; and a PDR run whose steps are 0.05 m long (an odometry that hardly moves while the IMU walks)."""
    root = tmp_path_factory.mktemp("distance")
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=90), seed=3)
    with DatasetWriter(root / "ds", {"made_by": "test_track_distance"}) as w:
        w.add(rec, split="train")
        w.add(dataclasses.replace(rec, name="walk_val"), split="val")
    runs = {}
    for name, args in (("pdr", {}), ("short", {"step_length": 0.05})):
        cfg = TrainConfig(model="pdr", data=str(root / "ds"), devices=("phone",), model_args=args)
        runs[name] = prepare_run(cfg, root / name)
        fit(cfg, runs[name], progress=False)
    rec.save(root / "walk.h5")
    return root, rec, runs


def still_imu(rec: Recording) -> Recording:
    """The recording with every device's motion scaled to 2 % in the world frame (its acceleration
    turned to the world by its orientation, scaled about its mean there, gravity, and turned back):
    the phone barely moves, while its fixes still walk."""
    devices = {}
    for name, s in rec.devices.items():
        assert s.quat is not None
        rot = from_wxyz(s.quat)
        world = rot.apply(s.acc)
        g = world.mean(axis=0)
        devices[name] = dataclasses.replace(s, acc=rot.inv().apply(g + 0.02 * (world - g)))
    return dataclasses.replace(rec, devices=devices)


def test_a_normal_walk_has_no_distance_warning(walk, tmp_path):
    from wearnav.track.trust import DISTANCE_FACTOR, fixes_length_m

    root, rec, runs = walk
    fix_m = fixes_length_m(rec, rec.t_start, rec.t_end)
    assert fix_m is not None and fix_m > 60  # the fixes move as the walker does
    summary = track(root / "walk.h5", runs["pdr"], tmp_path / "out")
    assert summary["odometry"]["length_m"] > fix_m / DISTANCE_FACTOR
    assert not [w for w in summary["warnings"] if FIXES_LINE in w or ACTIVITY_LINE in w]


def test_an_imu_that_hardly_walks_under_moving_fixes_is_said(walk, tmp_path):
    """The IMU scaled to 2 % of its motion: PDR counts no steps while the fixes move ~60 m; the
    track says so in track.json and on the console."""
    root, rec, runs = walk
    still_imu(rec).save(tmp_path / "still.h5")
    with pytest.warns(WearnavWarning, match=FIXES_LINE):
        summary = track(tmp_path / "still.h5", runs["pdr"], tmp_path / "out")
    assert summary["odometry"]["length_m"] < 10.0
    (line,) = [w for w in summary["warnings"] if FIXES_LINE in w]
    assert line.startswith(f"{rec.name}: ")


def test_an_odometry_shorter_than_the_walking_time_is_said(walk, tmp_path):
    """A PDR with 5 cm steps on the normal walk: the activity model finds a minute of walking, the
    fixes move far: both lines."""
    root, rec, runs = walk
    with pytest.warns(WearnavWarning):
        summary = track(root / "walk.h5", runs["short"], tmp_path / "out")
    assert np.isfinite(summary["odometry"]["length_m"]) and summary["odometry"]["length_m"] < 10.0
    assert [w for w in summary["warnings"] if FIXES_LINE in w]
    assert [w for w in summary["warnings"] if ACTIVITY_LINE in w]
