"""`wearnav export` (issue 18 §4): ONNX and TorchScript files against PyTorch, and `track` /
`classify` running them.

Run folders are made as `wearnav train` leaves them (config.yaml by ``prepare_run``) with random
weights in ``checkpoints/best.ckpt`` (batch-norm statistics drawn too, so their folding into the
convolutions is exercised): parity needs no training. Models: Suite-IN++ (per-device branches and
masked fusion), RoNIN (the first present device), RoNIN* (the devices' channels side by side) and
the HAR classifier.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import shutil
import sys

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import run_cli
from wearnav import runs
from wearnav.dataset import DatasetWriter
from wearnav.errors import ConfigError
from wearnav.export.header import FORMATS, read_header
from wearnav.export.write import PARITY_TOL, export_model, load_run, make_header
from wearnav.fuse import CALIBRATION_JSON
from wearnav.importers.sensorlogger_export import write_export
from wearnav.models import registry
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.track import track
from wearnav.train import classify, odometry
from wearnav.train.common import CHECKPOINTS, LAST
from wearnav.train.resolve import resolve_model

# Small versions of the models (export and parity do not depend on the widths).
SMALL = {
    "suitein++": {"widths": (8, 8, 8, 8, 8, 8), "gru_hidden": 8, "loc_dim": 8, "loc_hidden": 8},
    "ronin": {"blocks": (1, 1, 1, 1)},
    "ronin*": {"blocks": (1, 1, 1, 1)},
}
DEVICES = ("phone", "watch", "earbuds")
# The runs' window (2 s at 25 Hz; the default is 100): Suite-IN++'s GRU is unrolled over every time
# step by the ONNX export, whose cost grows with it; parity does not depend on the length.
WINDOW = 50
# masks of the parity batch: phone only, all, one device missing (each), watch only
MASKS = [[1, 0, 0], [1, 1, 1], [0, 1, 1], [1, 0, 1], [1, 1, 0], [0, 1, 0]]


def _random_weights(model: torch.nn.Module, path, seed: int = 0) -> None:
    """Save ``model`` with seeded random batch-norm statistics as a Lightning checkpoint."""
    g = torch.Generator().manual_seed(seed)
    state = model.state_dict()
    for k, v in state.items():
        if k.endswith("running_mean"):
            state[k] = torch.randn(v.shape, generator=g) * 0.5
        elif k.endswith("running_var"):
            state[k] = torch.rand(v.shape, generator=g) + 0.5
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"state_dict": {f"model.{k}": v for k, v in state.items()}}, path)


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=40), seed=3)
    with DatasetWriter(root / "ds", {"made_by": "test_export"}) as w:
        w.add(rec, split="train")
        w.add(dataclasses.replace(rec, name="walk_val"), split="val")
    return root, rec


@pytest.fixture(scope="module")
def run_of(walk):
    root, _ = walk
    made = {}

    def make(name: str):
        if name not in made:
            cfg = odometry.TrainConfig(
                model=name, data=str(root / "ds"), model_args=SMALL.get(name, {}), stride=20, window=WINDOW
            )
            run = odometry.prepare_run(cfg, root / f"run_{name}")
            torch.manual_seed(0)
            _random_weights(odometry.build_model(cfg), run / CHECKPOINTS / odometry.BEST)
            made[name] = run
        return made[name]

    return make


@pytest.fixture(scope="module")
def exported(run_of, tmp_path_factory):
    """exported(name, fmt) → (file, what export_model returned): each model exported once per format."""
    root = tmp_path_factory.mktemp("files")
    made = {}

    def make(name: str, fmt: str):
        if (name, fmt) not in made:
            out = root / f"{name.replace('*', '_star')}{FORMATS[fmt]}"
            made[name, fmt] = out, export_model(*load_run(run_of(name)), fmt, out)
        return made[name, fmt]

    return make


def _inputs(batch_masks, window: int = WINDOW, seed: int = 7):
    g = torch.Generator().manual_seed(seed)
    mask = torch.tensor(batch_masks, dtype=torch.float32)
    x = torch.randn(len(mask), len(DEVICES), window, 6, generator=g)
    x[..., 2] += 9.81  # gravity on the world z axis, as the models see it
    return x, mask


@pytest.mark.parametrize("name", ["suitein++", "ronin", "ronin*"])
@pytest.mark.parametrize("fmt", ["onnx", "torchscript"])
def test_export_matches_pytorch_with_absent_devices(run_of, exported, name, fmt):
    """The exported file, read back through `--model`'s one reading (resolve_model), gives the
    PyTorch run's velocities within PARITY_TOL m/s for every mask, at batch 1, 6 and 132 (the
    traced batch is 2), and its header rebuilds the run's config."""
    run = run_of(name)
    model, cfg = odometry.load_model(run)
    out, written = exported(name, fmt)
    model_x, cfg_x = resolve_model(out, "odometry")
    assert cfg_x == cfg
    diffs = []
    # a batch; a phone-only sample; earbuds alone; 132 windows (Suite-IN++ runs > 64 in chunks)
    for masks in (MASKS, [[1, 0, 0]], [[0, 0, 1]], MASKS * 22):
        x, mask = _inputs(masks)
        with torch.no_grad():
            ref = model(x, mask)
        assert ref.abs().max() > 1e-3  # random weights give non-trivial outputs
        diffs.append(float((model_x.predict(x, mask) - ref).abs().max()))
    print(f"{name} {fmt}: max |Δv| {max(diffs):.2e} m/s (export's own check {written['max_abs_diff']:.2e})")
    assert max(diffs) < PARITY_TOL
    header = read_header(out)
    assert (header["task"], header["model"], header["devices"]) == ("odometry", name, list(DEVICES))
    assert (header["window"], header["rate_hz"], header["stride"]) == (WINDOW, 25.0, 20)


def test_track_runs_the_onnx_export_like_the_run(walk, run_of, exported, tmp_path):
    """`wearnav track` on a Sensor Logger export with the run folder and with its ONNX file: the
    same path up to trajectory.csv's 0.1 mm resolution (velocities agree to ~1e-7 m/s, so over
    40 s the paths differ by ~1e-6 m: at most one rounding step, and at few samples)."""
    _, rec = walk
    run = run_of("suitein++")
    onnx_file, _ = exported("suitein++", "onnx")
    folder = write_export(rec, tmp_path / "2023-11-14_22-13-20", platform="ios")
    a = track(folder, run, tmp_path / "a")
    b = track(folder, onnx_file, tmp_path / "b")
    ta, tb = (pd.read_csv(tmp_path / d / "trajectory.csv") for d in "ab")
    assert len(ta) == len(tb) > 100 and a["odometry"]["length_m"] > 1.0
    diff = np.abs(ta[["x", "y"]].to_numpy() - tb[["x", "y"]].to_numpy())
    print(
        f"track: path {a['odometry']['length_m']} m, max |Δxy| {diff.max():.2e} m, share of coordinates differing "
        f"{np.mean(diff > 0):.3f}"
    )
    assert diff.max() <= 1e-4 + 1e-9 and np.mean(diff > 0) < 0.01
    assert b["model"] == "suitein++" and b["window"] == a["window"] and b["stride"] == a["stride"]
    assert (a["runtime"], b["runtime"]) == ("pytorch", "onnxruntime")
    assert b["warnings"] == a["warnings"]  # the file's header carries the run's training record


@pytest.mark.parametrize("fmt", ["onnx", "torchscript"])
def test_track_places_the_path_the_same_from_the_run_and_its_export(walk, run_of, fmt, tmp_path):
    """An export carries the smoother's calibration (fuse_calibration.json) in its header, and
    `track` places the path with it: the anchored path from the file is the run's within 1 mm
    (issue 38: without it the placed path moved by up to 18.6 m on a real walk)."""
    if fmt == "onnx":
        pytest.importorskip("onnxruntime")
    _, rec = walk
    run = tmp_path / "run"
    shutil.copytree(run_of("ronin"), run)  # the cheapest network to export: the header is what is tested
    cal = {"odometry_walk_m_per_sqrt_s": 0.9, "sigma_scale": 2.5}  # far from the smoother's defaults
    (run / CALIBRATION_JSON).write_text(json.dumps(cal))
    out = tmp_path / f"m{FORMATS[fmt]}"
    export_model(*load_run(run), fmt, out)
    assert read_header(out)["fuse_calibration"] == cal
    folder = write_export(rec, tmp_path / "2023-11-14_22-13-20", platform="ios")
    a = track(folder, run, tmp_path / "a")
    b = track(folder, out, tmp_path / "b")
    assert a["anchoring"]["method"] == b["anchoring"]["method"] == "smooth"
    assert a["anchoring"]["odometry_calibration"] == b["anchoring"]["odometry_calibration"] == cal
    ta, tb = (pd.read_csv(tmp_path / d / "trajectory.csv") for d in "ab")
    placed = ["east", "north"]
    assert len(ta) == len(tb) > 100
    diff = float(np.abs(ta[placed].to_numpy() - tb[placed].to_numpy()).max())
    print(f"{fmt}: placed path max |Δ| {diff:.2e} m")
    assert diff <= 1e-3


def test_export_command_writes_a_checked_file(run_of, monkeypatch, capsys, tmp_path):
    run = run_of("ronin*")
    code, out, err = run_cli(monkeypatch, capsys, "export", run, "--format", "torchscript", "--out", tmp_path / "r.pt")
    assert code == 0, err
    written = json.loads(out)
    assert written["model"] == "ronin*" and written["task"] == "odometry" and written["bytes"] > 10_000
    assert 0 <= written["max_abs_diff"] < written["tolerance"] == PARITY_TOL


def test_pdr_is_refused_with_one_line(walk, monkeypatch, capsys, tmp_path):
    root, _ = walk
    cfg = odometry.TrainConfig(model="pdr", data=str(root / "ds"))
    run = odometry.prepare_run(cfg, tmp_path / "pdr")
    odometry.fit(cfg, run, progress=False)
    code, _, err = run_cli(monkeypatch, capsys, "export", run, "--format", "onnx", "--out", tmp_path / "p.onnx")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "not a learned network" in err and "--model pdr" in err
    assert not (tmp_path / "p.onnx").exists()


def test_without_onnxruntime_one_line_names_the_extra(run_of, exported, monkeypatch, capsys, tmp_path):
    run = run_of("ronin")
    out, _ = exported("ronin", "onnx")
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # `import onnxruntime` now raises ImportError
    for args in (
        ("track", "x.zip", "--model", out, "--out", tmp_path / "t"),
        ("export", run, "--format", "onnx", "--out", tmp_path / "s.onnx"),
    ):
        code, _, err = run_cli(monkeypatch, capsys, *args)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert "wearnav[onnx]" in err


def test_wrong_suffix_and_wrong_task_are_refused(run_of, exported, monkeypatch, capsys, tmp_path):
    run = run_of("ronin")
    code, _, err = run_cli(monkeypatch, capsys, "export", run, "--format", "onnx", "--out", tmp_path / "r.pt")
    assert code == 2 and "ends in .onnx" in err and not (tmp_path / "r.pt").exists()
    pt, _ = exported("ronin", "torchscript")
    (tmp_path / "x.h5").touch()  # an input that exists: the model is refused before it is read
    code, _, err = run_cli(monkeypatch, capsys, "classify", tmp_path / "x.h5", "--model", pt, "--out", tmp_path / "c")
    assert code == 2 and "is an odometry model (ronin) exported" in err and "wearnav track" in err


@pytest.mark.slow
def test_classifier_export_gives_the_runs_logits_and_labels(walk, tmp_path, monkeypatch, capsys):
    """A classifier run (random weights) exported to both formats: logits within PARITY_TOL, the
    file resolves to the run's config and class names, and `wearnav classify` with the ONNX file
    writes the run's intervals and warnings."""
    root, _ = walk
    cfg = classify.ClassifyConfig(model="har-cnn-bilstm", data=str(root / "ds"), model_args={"hidden": 8})
    run = tmp_path / "har"
    runs.write_config(run, classify.run_record(cfg))
    classes = ["walk", "stand", "sit"]
    runs.write_json(run / classify.TRAINING, {"classes": classes})
    torch.manual_seed(0)
    model = registry.build(cfg.model, n_devices=1, window=cfg.window, n_classes=3, **cfg.model_args)
    _random_weights(model, run / CHECKPOINTS / LAST)
    model, _, _ = classify.load_model(run)
    x, mask = _inputs([[1]] * 5, window=cfg.window)
    x = x[:, :1]
    with torch.no_grad():
        ref = model(x, mask)
    for fmt, name in (("onnx", "h.onnx"), ("torchscript", "h.pt")):
        export_model(*load_run(run), fmt, tmp_path / name)
        exported, cfg_x, classes_x = resolve_model(tmp_path / name, "classify")
        diff = float((exported(x, mask) - ref).abs().max())
        print(f"har-cnn-bilstm {fmt}: max |Δlogit| {diff:.2e}")
        assert diff < PARITY_TOL and cfg_x == cfg and classes_x == classes
    for model_arg, out in ((run, "a"), (tmp_path / "h.onnx", "b")):
        code, _, err = run_cli(
            monkeypatch, capsys, "classify", root / "ds", "--model", model_arg, "--out", tmp_path / out
        )
        assert code == 0, err
    a, b = (pd.read_csv(tmp_path / d / "walk_intervals.csv") for d in "ab")
    cols = ["start_s", "end_s", "label", "windows"]
    assert len(a) >= 1 and a[cols].equals(b[cols])
    assert np.abs(a["mean_confidence"] - b["mean_confidence"]).max() <= 1e-3
    warn = [json.loads((tmp_path / d / "classify.json").read_text())["warnings"] for d in "ab"]
    assert warn[0] == warn[1]


@pytest.mark.slow
def test_export_speed_times_every_runtime():
    """The speed table's function on a small RoNIN: one row per runtime and batch, positive rates,
    the exports' parity within tolerance."""
    from wearnav.export.speed import export_speed, speed_table

    rows = export_speed("ronin", batches=(1, 4), min_run_time_s=0.01, blocks=(1, 1, 1, 1))
    assert [(r["runtime"], r["batch"]) for r in rows] == [
        (rt, b) for b in (1, 4) for rt in ("pytorch", "pytorch-traced-graph", "onnxruntime", "torchscript")
    ]
    assert all(r["win_per_s"] > 0 and r["max_abs_diff"] < PARITY_TOL and r["threads"] == 1 for r in rows)
    assert "batch 4 (windows/s)" in speed_table(rows)


def _network_models() -> list[str]:
    return [s.name for s in registry.available() if s.learned and s.task in ("odometry", "classify")]


def _build_default(name: str, window: int | None = None):
    """``name`` at its default size (random weights, 3 devices; a classifier 6 classes), its header;
    ``window``: another window length than the config's default."""
    from wearnav.train.classify import ClassifyConfig

    task = registry.get(name).task
    torch.manual_seed(0)
    size = {} if window is None else {"window": window}
    if task == "odometry":
        cfg = odometry.TrainConfig(model=name, data="", **size)
        model, classes = odometry.build_model(cfg), None
    else:
        cfg = ClassifyConfig(model=name, data="", devices=DEVICES, **size)
        classes = [f"c{i}" for i in range(6)]
        model = registry.build(name, n_devices=3, window=cfg.window, n_classes=6)
    return model, make_header(task, cfg, classes)


@functools.cache
def _kinds_of(name: str) -> tuple:
    """:func:`_kinds` of ``name`` at its default size (built once: collection and two tests read it)."""
    return _kinds(_build_default(name)[0])


# The ONNX test's windows, shortest first: torch.export unrolls a recurrent layer over every time
# step of the window (the export's cost grows with it; ionet's is 20 s at 100 samples, 7 at 20).
# A network takes the shortest one it accepts (its pooling, intervals or segments set a least).
SHORT_WINDOWS = (20, 32, 40, 64)


def _build_short(name: str):
    """``name`` at its default widths and depth on the shortest of :data:`SHORT_WINDOWS` it accepts."""
    for window in SHORT_WINDOWS:
        try:
            return _build_default(name, window)
        except (ConfigError, ValueError):  # too short for this network
            continue
    return _build_default(name)


# Constructor switches that change a class's forward (and so the ops an export must map) without
# changing the kinds of module it holds: Suite-IN's ablation (1) has every switch off (mean fusion,
# hybrid extractors, no attention; suitein++ has them on), and har-gravity turns each window by its
# gravity first (the shipped activity model).
FORWARD_SWITCHED = ("suitein++-abl1", "har-gravity")


# exported to ONNX by the parity tests above (small widths: the same forward)
PARITY_TESTED = ("suitein++", "ronin", "ronin*", "har-cnn-bilstm")


def _kinds(model: torch.nn.Module) -> tuple:
    return type(model).__name__, frozenset(type(m).__name__ for m in model.modules())


def _onnx_models() -> list[str]:
    """The networks the ONNX test exports: the first of each model class and set of module kinds
    not among :data:`PARITY_TESTED`'s, and :data:`FORWARD_SWITCHED`. The other networks are those
    same forwards at other widths, layouts or head counts; an ONNX export costs 5-20 s each here
    (torch.export's tracing: it grows with the number of layers and a recurrent layer's time
    steps, hardly with the widths), TorchScript about one, so every network
    gets the latter."""
    seen = {_kinds_of(name) for name in PARITY_TESTED}
    names = []
    for name in _network_models():
        kinds = _kinds_of(name)
        if kinds not in seen or name in FORWARD_SWITCHED:
            seen.add(kinds)
            names.append(name)
    return names


@pytest.mark.slow
@pytest.mark.parametrize("name", _network_models())
def test_every_registered_network_exports_to_torchscript(name, tmp_path):
    """Each learned registry model at its default size writes a TorchScript file that passes the
    export's own parity check."""
    model, header = _build_default(name)
    written = export_model(model, header, "torchscript", tmp_path / f"m{FORMATS['torchscript']}")
    print(f"{name} torchscript: max |Δ| {written['max_abs_diff']:.2e}, {written['bytes'] / 1e6:.2f} MB")
    assert written["max_abs_diff"] < PARITY_TOL


def test_every_forward_is_exported_to_onnx_somewhere():
    """The ONNX tests' choice (this file's parity tests and the one below) covers every model class,
    both states of Suite-IN's switches and the shipped activity model, and leaves some networks out
    (TorchScript only)."""
    chosen = [*PARITY_TESTED, *_onnx_models()]
    classes = {_kinds_of(n)[0] for n in _network_models()}
    assert {_kinds_of(n)[0] for n in chosen} == classes
    assert {"suitein++", "suitein++-abl1", "har-gravity"} <= set(chosen)
    assert len(chosen) < len(_network_models())


@pytest.mark.slow
@pytest.mark.parametrize("name", _onnx_models())
def test_each_networks_forward_exports_to_onnx(name, tmp_path):
    """The networks of :func:`_onnx_models` at their default widths and depth write an ONNX file
    that passes the export's own parity check, on a short window (:func:`_build_short`: the same
    forward and module kinds as at the default window, fewer recurrent steps to unroll)."""
    model, header = _build_short(name)
    assert _kinds(model) == _kinds_of(name)
    written = export_model(model, header, "onnx", tmp_path / f"m{FORMATS['onnx']}")
    print(f"{name} onnx: max |Δ| {written['max_abs_diff']:.2e}, {written['bytes'] / 1e6:.2f} MB")
    assert written["max_abs_diff"] < PARITY_TOL
