"""Say one thing everywhere (issue 58 §7): each fact a user reads in several places comes from one
place in the code, and the help and the docs are generated from it or tested against it here.

- A shipped model's default speed: its own record (:func:`wearnav.pretrained.shipped_speeds`, the
  ``speed`` of its ``held_out.json``); `track --help` is generated from it, `wearnav models` prints
  it, and every "the shipped X model's default: `S`" of the README and docs/design.md must agree.
- The frames a model works in: :func:`wearnav.pretrained.frame_words`, which both `wearnav models`
  and `track` (console and ``track.json`` ``odometry.frame``) print. Before, `models` said "the
  phone's heading frame" and `track` "frame: common", each half of it.
- The devices a model read: `track --model pdr` on any export says "pdr on the phone" (before: "pdr
  on phone, watch, earbuds; used phone", or "used phone, watch, earbuds" where PDR reads one).
- Which frame each length is in: ``track.json`` ``odometry`` {``length_m``, ``end_xy_m``} (the CSV's
  x, y) beside ``path`` {``length_m``} (east, north where placed); before, ``end_xy_m`` of the one
  stood beside ``length_m`` of the other at the top level.
- The registry's names without torch: ``wearnav.models.catalogue`` is the registry's table, tested
  equal to it; `wearnav models` and a misspelt ``--model`` read it (before: 3.5-9.5 s each, the
  model families imported first; now about half a second).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from conftest import run_cli
from wearnav import pretrained
from wearnav.cli import app
from wearnav.importers.sensorlogger_export import write_export
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.train.odometry import SPEED_SOURCES

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"
# "the shipped phone model's default: `snapped`" (backticks optional), wherever it is said
SAID_SPEED = re.compile(rf"shipped ([\w-]+) model's default: `?({'|'.join(SPEED_SOURCES)})\b`?")
# a misspelt --model is refused before the recording is read or torch imported: ~0.5 s here;
# the bound is generous for a loaded CI machine (before: 3.5-9.5 s)
REFUSE_S = 2.0

needs_shipped = pytest.mark.skipif(
    not pretrained.installed("odometry"), reason="no shipped odometry model installed (wearnav pretrain --install)"
)


def _help(*args: str) -> str:
    res = CliRunner().invoke(app, [*args, "--help"], terminal_width=1000)
    assert res.exit_code == 0, res.output
    return " ".join(res.output.split())


def _models_output() -> str:
    res = CliRunner().invoke(app, ["models"], terminal_width=1000)
    assert res.exit_code == 0, res.output
    return res.output


@needs_shipped
def test_every_statement_of_a_shipped_models_default_speed_is_its_record():
    recorded = pretrained.shipped_speeds()
    assert recorded[pretrained.PHONE] in SPEED_SOURCES
    texts = {
        "README.md": (REPO / "README.md").read_text(),
        "docs/design.md": (REPO / "docs" / "design.md").read_text(),
        "track --help": _help("track"),
    }
    said = {where: SAID_SPEED.findall(text) for where, text in texts.items()}
    assert said["track --help"] == list(recorded.items())  # generated: every shipped odometry model, once
    assert (pretrained.PHONE, recorded[pretrained.PHONE]) in said["README.md"]
    for where, pairs in said.items():
        for name, speed in pairs:
            assert name in recorded, f"{where}: no shipped odometry model {name!r}"
            assert speed == recorded[name], (
                f"{where} says {name}'s default speed is {speed}; it records {recorded[name]}"
            )
    out = _models_output()
    for name, speed in recorded.items():
        block = out.split(f"\n{name} ", 1)[1].split("\n\n")[0]
        assert f"(`--speed {speed}`, the default)" in block.split("\nactivity")[0], block


@pytest.fixture(scope="module")
def walks(tmp_path_factory):
    """20-s simulated Sensor Logger exports: the phone alone, and phone + watch + earbuds."""
    root = tmp_path_factory.mktemp("walks")
    phone = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=20, devices=("phone",)), seed=0)
    multi = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=20), seed=3)
    return {
        "phone": write_export(phone, root / "phone" / "2023-11-14_22-13-20", platform="ios"),
        "multi": write_export(multi, root / "multi" / "2023-11-14_22-13-20", platform="ios"),
    }


def _track(monkeypatch, capsys, src, out, *args):
    code, stdout, err = run_cli(monkeypatch, capsys, "track", src, "--out", out, *args)
    assert code == 0, err
    return stdout.splitlines()[0], json.loads((out / "track.json").read_text())


@needs_shipped
def test_models_and_track_say_the_same_frame(walks, monkeypatch, capsys, tmp_path):
    """The frame line of `wearnav models` for the shipped phone model is what `track` prints and
    keeps in track.json for it (the heading frame of the windows, the common frame of the path)."""
    out = _models_output()
    block = out.split(f"\n{pretrained.PHONE} ", 1)[1].split(f"\n{pretrained.MULTI} ", 1)[0]
    (said,) = re.findall(r"^\s+frame: (.+)$", block, flags=re.M)
    line, summary = _track(monkeypatch, capsys, walks["phone"], tmp_path / "t", "--model", pretrained.PHONE)
    assert summary["odometry"]["frame"] == said
    assert "heading frame" in said and "common frame" in said  # both halves, in one phrase
    assert line.endswith(f"; frame: {said}")
    assert "frame" not in summary  # said once, under odometry


@pytest.mark.parametrize("walk", ["phone", "multi"])
def test_pdr_says_the_one_device_it_read(walk, walks, monkeypatch, capsys, tmp_path):
    line, summary = _track(monkeypatch, capsys, walks[walk], tmp_path / "t", "--model", "pdr")
    assert line.startswith("model: pdr on the phone;"), line
    assert summary["devices_used"] == ["phone"]
    assert summary["devices_in_recording"] == (["phone"] if walk == "phone" else ["phone", "watch", "earbuds"])


def test_track_json_says_which_frame_each_length_is_in(walks, monkeypatch, capsys, tmp_path):
    _, summary = _track(monkeypatch, capsys, walks["multi"], tmp_path / "t", "--model", "pdr")
    traj = pd.read_csv(tmp_path / "t" / "trajectory.csv")
    xy, en = traj[["x", "y"]].to_numpy(), traj[["east", "north"]].to_numpy()
    assert not {"end_xy_m", "length_m", "odometry_length_m", "frame", "frame_reference"} & set(summary)
    odo, path = summary["odometry"], summary["path"]
    np.testing.assert_allclose(odo["end_xy_m"], xy[-1], atol=1e-3)
    assert odo["length_m"] == pytest.approx(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum(), abs=0.02)
    assert path["length_m"] == pytest.approx(np.linalg.norm(np.diff(en, axis=0), axis=1).sum(), abs=0.02)
    assert "east, north" in path["frame"] and "own frame" in odo["frame"] + " own frame"
    doc = (SRC / "wearnav" / "track/run.py").read_text()
    for field in ("``odometry``", "``end_xy_m``", "``path``"):
        assert field in doc  # the docstring's field list names them


# ---- the cheap checks first ------------------------------------------------------------------

FRESH = """
import sys, time
t0 = time.perf_counter()
from wearnav.cli import main
sys.argv = ["wearnav"] + sys.argv[1:]
code = 0
try:
    main()
except SystemExit as e:
    code = e.code or 0
print("\\nRESULT", code, "torch" in sys.modules, round(time.perf_counter() - t0, 3))
"""


def _fresh(*args) -> tuple[int, bool, float, str, str]:
    """`wearnav ARGS` in a new interpreter: (exit code, torch imported, seconds, stdout, stderr)."""
    env = {**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", FRESH, *map(str, args)], env=env, capture_output=True, text=True)
    wall_s = time.perf_counter() - t0
    code, torch_imported, _ = p.stdout.rsplit("\nRESULT", 1)[1].split()
    return int(code), torch_imported == "True", wall_s, p.stdout, p.stderr


@needs_shipped
def test_a_misspelt_model_is_refused_quickly_naming_the_close_names(walks, tmp_path):
    """`wearnav track EXPORT --model phnoe`: one error line suggesting 'phone', before the export is
    read or torch imported, within :data:`REFUSE_S` of starting Python."""
    code, torch_imported, wall_s, _, err = _fresh("track", walks["multi"], "--model", "phnoe", "--out", tmp_path / "t")
    print(f"misspelt --model refused in {wall_s:.2f} s")
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: phnoe: "), err
    assert err.rstrip().endswith("did you mean 'phone'?"), err
    assert not torch_imported and wall_s < REFUSE_S
    code, _, _, _, err = _fresh("track", walks["multi"], "--model", "ronnin", "--out", tmp_path / "t")
    assert code == 2 and "did you mean 'ronin'" in err  # a registered model to train first is named too


def test_models_lists_without_torch():
    code, torch_imported, wall_s, out, err = _fresh("models")
    print(f"wearnav models in {wall_s:.2f} s")
    assert code == 0, err
    assert not torch_imported and wall_s < REFUSE_S
    assert "suitein++" in out and "pdr" in out


def test_the_catalogue_is_the_registrys_table():
    """``wearnav/models/catalogue.json`` equals what the registry builds now; if not, run
    ``python -m wearnav.models.catalogue`` (a model added, renamed or resized)."""
    from wearnav.models import catalogue

    assert [dict(e.__dict__) for e in catalogue.read()] == catalogue.generate(), (
        "wearnav/models/catalogue.json differs from the registry: python -m wearnav.models.catalogue"
    )


def test_a_model_cards_limits_read_the_recipes_speed_loss_and_frame():
    """The card's known limits say the recipe's speed, loss and heading frame (they were typed in:
    'the phone model's default' `snapped`, 'Trained with the MSE loss (the phone model: the polar loss)')."""
    import dataclasses

    from wearnav.pretrained.cards import limits
    from wearnav.pretrained.recipe import Recipe

    shipped = " ".join(limits(pretrained.MULTI, Recipe()))
    assert f"`--speed {Recipe().multi_speed}` for it (the phone model: `--speed {Recipe().speed}`)" in shipped
    other = dataclasses.replace(
        Recipe(), speed="cadence", multi_speed="snapped", vel_loss="mse", multi_vel_loss="polar"
    )
    text = " ".join(limits(pretrained.MULTI, other))
    assert "`--speed snapped` for it (the phone model: `--speed cadence`)" in text
    assert "Trained with the polar loss (the phone model: the MSE loss)" in text
    assert "within 30° of where the phone points" in text  # the snapped limit follows the speed
    assert "within 30° of where the phone points" not in " ".join(limits(pretrained.PHONE, other))
