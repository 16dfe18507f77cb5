"""A file of `wearnav export` and the model it came from give `wearnav track` the same path
(issue 56 §2): the export's header carries every default that `track` takes from the run
(:func:`wearnav.pretrained.track_defaults`: where the speed comes from, the smoother's
calibration), and `track` reads them from the header as it reads them from the run.

Before the fix an exported shipped model ran at its own speed (``speed: model``) where the model
by name took the recipe's (``snapped`` / ``cadence``): on a 40-s simulated Sensor Logger walk the
placed paths differed by 0.7–0.8 m. Each shipped odometry model is exported once per format
(module fixture: an ONNX export costs ~11 s here, a TorchScript one 0.3 s).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from wearnav import pretrained
from wearnav.export.header import FORMATS, read_header
from wearnav.export.write import export_model, load_run
from wearnav.importers.sensorlogger_export import write_export
from wearnav.simulate import WalkConfig, simulate_recording

ODOMETRY = [s.name for s in pretrained.installed("odometry")]
PLACED = ["east", "north"]
TOLERANCE_M = 1e-3  # the "agree within 1 mm"


# the multi-device model's ONNX export is the slowest case (~11 s): `make check` leaves it out
CASES = [
    pytest.param(
        name, fmt, id=f"{name}-{fmt}", marks=[pytest.mark.slow] if (name, fmt) == (pretrained.MULTI, "onnx") else []
    )
    for name in ODOMETRY
    for fmt in FORMATS
]


@pytest.fixture(scope="module")
def walk_export(tmp_path_factory):
    """A 40-s simulated Sensor Logger export (phone, watch, earbuds, GPS fixes)."""
    rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=40), seed=3)
    return write_export(rec, tmp_path_factory.mktemp("walk") / "2023-11-14_22-13-20", platform="ios")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """exported(name, fmt) → the shipped model ``name`` as a file of `wearnav export`, made once."""
    pytest.importorskip("onnxruntime")
    root = tmp_path_factory.mktemp("exported")
    made: dict = {}

    def make(name: str, fmt: str):
        if (name, fmt) not in made:
            made[name, fmt] = root / f"{name}{FORMATS[fmt]}"
            export_model(*load_run(pretrained.get(name).path), fmt, made[name, fmt])
        return made[name, fmt]

    return make


def _track(monkeypatch, capsys, walk, model, out):
    """`wearnav track WALK --model MODEL --out OUT`: the default command line."""
    code, _, err = run_cli(monkeypatch, capsys, "track", walk, "--model", model, "--out", out)
    assert code == 0, err
    return json.loads((out / "track.json").read_text()), pd.read_csv(out / "trajectory.csv")


@pytest.mark.skipif(not ODOMETRY, reason="no shipped odometry model installed (wearnav pretrain --install)")
@pytest.mark.parametrize("name, fmt", CASES)
def test_an_export_of_a_shipped_model_gives_the_models_path(
    name, fmt, walk_export, exported, monkeypatch, capsys, tmp_path
):
    """`track` by the shipped model's name and by its export: the same speed source, the same
    smoother calibration, and the placed path (trajectory.csv east/north) within 1 mm."""
    f = exported(name, fmt)
    assert read_header(f)["track_defaults"] == pretrained.track_defaults(pretrained.get(name).path)
    a, ta = _track(monkeypatch, capsys, walk_export, name, tmp_path / "by_name")
    b, tb = _track(monkeypatch, capsys, walk_export, f, tmp_path / "by_file")
    assert b["speed"] == a["speed"] == pretrained.recorded_speed(pretrained.get(name).path)
    assert b["anchoring"]["odometry_calibration"] == a["anchoring"]["odometry_calibration"]
    assert len(ta) == len(tb) > 100 and set(PLACED) <= set(ta.columns) & set(tb.columns)
    diff_m = float(np.abs(ta[PLACED].to_numpy() - tb[PLACED].to_numpy()).max())
    print(f"{name} by name vs {fmt}: speed {a['speed']} / {b['speed']}, placed path max |Δ| {diff_m * 1e3:.3f} mm")
    assert diff_m <= TOLERANCE_M
