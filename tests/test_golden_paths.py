"""The shipped models give the same paths (issue 58, "behaviour unchanged"): `wearnav track` on two
fixed simulated Sensor Logger walks, by the default command line and with ``--model pdr``, against
reference paths committed under ``tests/data/golden/``.

The walks: 60 s each, deterministic by seed, written as an iOS export by the package's own writer
(:func:`wearnav.importers.sensorlogger_export.write_export`): a phone-only walk (STW, phone in
hand, seed 0) whose default is the shipped ``phone`` model, and a phone + watch + earbuds walk
(PVW, phone in the pocket, seed 3) whose default is ``phone-watch-earbuds``; both carry GPS fixes,
so the path is placed by the smoother. Each reference keeps ``trajectory.csv``'s ``t``, ``x``,
``y`` (the odometry's own frame) and ``east``, ``north`` (the placed path) at 1 Hz (every 25th row
of the 25 Hz path); the test asserts every kept row within :data:`TOLERANCE_M` (1 mm) and the same
row count and times.

``inputs.json`` keeps a fingerprint (each file's columns, rows and column statistics) of each export,
so that a change to the simulator or the export writer, which changes the input rather than
`track`, is said as such instead of as a changed path.

A change to these references is a behaviour change: make it deliberately, state it in the commit
that makes it (what changed in the paths and why), and regenerate with::

    WEARNAV_UPDATE_GOLDEN=1 python -m pytest tests/test_golden_paths.py -p no:cacheprovider

which rewrites the files under ``tests/data/golden/`` from the code as it is (and passes).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from wearnav import pretrained
from wearnav.importers.sensorlogger_export import write_export
from wearnav.simulate import WalkConfig, simulate_recording

GOLDEN = Path(__file__).parent / "data" / "golden"
INPUTS_JSON = GOLDEN / "inputs.json"
UPDATE = os.environ.get("WEARNAV_UPDATE_GOLDEN") == "1"
TOLERANCE_M = 1e-3  # the "within 1 mm"
FINGERPRINT_RTOL = 1e-9  # how close an export's column statistics are to the reference's (_fingerprint)
KEEP_EVERY = 25  # rows of the 25 Hz path: one kept per second
COLUMNS = ["t", "x", "y", "east", "north"]
# walk name → (the simulated walk, the shipped model `track` takes for it without --model)
WALKS = {
    "phone": (WalkConfig(mode="STW", placement="HD", duration_s=60, devices=("phone",)), 0, pretrained.PHONE),
    "phone-watch-earbuds": (WalkConfig(mode="PVW", placement="MP", duration_s=60), 3, pretrained.MULTI),
}
CASES = [(walk, model) for walk in WALKS for model in ("default", "pdr")]


def _fingerprint(folder: Path) -> dict:
    """What the export holds, per file (sorted by name): a CSV's columns, row count and each number
    column's first value and the mean, std, min and max of its offsets from it (compared within
    :data:`FINGERPRINT_RTOL`); any other file's SHA-256. Not the CSVs' bytes: numpy's sin/cos/exp
    differ in the last bits between CPUs (its SIMD loops), which changes a full-precision export's
    bytes but not its walk."""
    got: dict = {}
    for f in sorted(p for p in folder.rglob("*") if p.is_file()):
        name = f.relative_to(folder).as_posix()
        if f.suffix == ".csv":
            table = pd.read_csv(f)
            stats = {}
            for c, v in table.select_dtypes("number").items():
                first = v.iloc[0].item()  # an int stays an int (nanosecond times), compared exactly
                d = (v - first).astype(float)  # the rest as offsets from it, so that a tolerance means something
                stats[c] = [first, d.mean(), d.std(ddof=0), d.min(), d.max()]
            got[name] = {"columns": list(table.columns), "rows": len(table), "stats": stats}
        else:
            got[name] = hashlib.sha256(f.read_bytes()).hexdigest()
    return got


def _same(got, want) -> bool:
    """``got`` is ``want`` (nested dicts and lists), numbers within :data:`FINGERPRINT_RTOL`."""
    if isinstance(want, dict):
        return isinstance(got, dict) and got.keys() == want.keys() and all(_same(got[k], want[k]) for k in want)
    if isinstance(want, list):
        return isinstance(got, list) and len(got) == len(want) and all(map(_same, got, want))
    if isinstance(want, float):
        return isinstance(got, float) and bool(np.isclose(got, want, rtol=FINGERPRINT_RTOL, atol=FINGERPRINT_RTOL))
    return got == want


@pytest.fixture(scope="module")
def exports(tmp_path_factory) -> dict[str, Path]:
    made = {}
    for walk, (cfg, seed, _) in WALKS.items():
        rec = simulate_recording(cfg, seed=seed)
        made[walk] = write_export(rec, tmp_path_factory.mktemp(walk) / "2023-11-14_22-13-20", platform="ios")
    return made


@pytest.fixture(scope="module")
def inputs(exports) -> dict:
    got = {walk: _fingerprint(folder) for walk, folder in exports.items()}
    if UPDATE:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        INPUTS_JSON.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
    return got


def _reference(walk: str, model: str) -> Path:
    return GOLDEN / f"{walk}--{model}.csv"


def test_the_walks_are_the_references_walks(inputs):
    """The simulated exports are byte for byte those the references were made from (else the
    simulator or the export writer changed, not `track`)."""
    assert INPUTS_JSON.is_file(), f"no {INPUTS_JSON}: regenerate (module docstring)"
    want = json.loads(INPUTS_JSON.read_text())
    assert _same(inputs, want), (
        "the simulated input walks changed (wearnav.simulate or the export writer), so the golden paths "
        "cannot say whether `track` did: regenerate deliberately (module docstring)"
    )


@pytest.mark.parametrize("walk, model", CASES, ids=[f"{w}-{m}" for w, m in CASES])
def test_track_gives_the_reference_path(walk, model, exports, inputs, monkeypatch, capsys, tmp_path):
    """`wearnav track WALK --out OUT` (and ``--model pdr``): the path at every kept row within 1 mm
    of the reference, and the default takes the shipped model named in :data:`WALKS`."""
    out = tmp_path / "out"
    args = ["track", exports[walk], "--out", out] + ([] if model == "default" else ["--model", model])
    code, _, err = run_cli(monkeypatch, capsys, *args)
    assert code == 0, err
    summary = json.loads((out / "track.json").read_text())
    assert summary["shipped_model"] == (WALKS[walk][2] if model == "default" else None)
    full = pd.read_csv(out / "trajectory.csv")
    assert set(COLUMNS) <= set(full.columns)
    kept = full[COLUMNS].iloc[::KEEP_EVERY].reset_index(drop=True)
    ref_file = _reference(walk, model)
    if UPDATE:
        with ref_file.open("w") as f:
            f.write(f"# rows {len(full)}\n")
            kept.to_csv(f, index=False, float_format="%.4f")
        return
    assert ref_file.is_file(), f"no reference {ref_file}: regenerate (module docstring)"
    rows = int(ref_file.read_text().splitlines()[0].removeprefix("# rows "))
    ref = pd.read_csv(ref_file, comment="#")
    assert len(full) == rows and list(ref.columns) == COLUMNS
    assert np.allclose(kept["t"], ref["t"], atol=1e-4)
    diff_m = np.abs(kept[COLUMNS[1:]].to_numpy() - ref[COLUMNS[1:]].to_numpy())
    worst = np.unravel_index(int(np.argmax(diff_m)), diff_m.shape)
    print(f"{walk} {model}: max |Δ| {diff_m.max() * 1e3:.3f} mm ({COLUMNS[1 + worst[1]]}, t {ref['t'][worst[0]]:g} s)")
    assert diff_m.max() <= TOLERANCE_M, (
        f"{walk} --model {model}: the path moved {diff_m.max() * 1e3:.1f} mm from the reference at t "
        f"{ref['t'][worst[0]]:g} s ({COLUMNS[1 + worst[1]]}); if that is meant, regenerate (module docstring)"
    )
