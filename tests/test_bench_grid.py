"""The odometry grid (issue #16 §4): seeds × models, and its page from hand-written run folders."""

import json

import numpy as np
import pandas as pd
import pytest

from wearnav.bench import odometry
from wearnav.bench import odometry_tables as tables
from wearnav.errors import ConfigError

# per-seed test ATE: ronin well separated from suitein++, pdr overlapping it
ATE = {"suitein++": [1.0, 1.1, 0.9], "ronin": [3.0, 3.1, 2.9], "pdr": [1.05, 1.3, 0.7]}


def fake_run(root, model, seed, ate, model_args=None, modes=("DRW", "DLW")):
    """A complete run folder as a grid run leaves it: config.yaml, metrics.json, trajectories."""
    folder = root / f"{model}-{seed}-{len(model_args or {})}"
    train = {
        "model": model,
        "seed": seed,
        "model_args": model_args or {},
        "epochs": 30,
        "patience": 10,
        "frame_align": "truth",
        "eval_frame_align": "initial",
        "window": 100,
    }
    (folder / "trajectories" / "test").mkdir(parents=True)
    (folder / "trajectories" / "test_unseen").mkdir(parents=True)
    (folder / "config.yaml").write_text(json.dumps({"config": {"train": train}}))
    t = np.arange(0, 20, 0.04)
    splits = {}
    for split, places in (("test", ("HD", "MP")), ("test_unseen", ("PK", "BG"))):
        rows = []
        for mode, place in zip(modes, places):
            name = f"{split}-{mode}-{place}"
            true = np.stack([1.2 * t, 0 * t], 1)
            est = np.stack([(1.2 + 0.05 * ate) * t, 0 * t], 1)
            pd.DataFrame(
                {
                    "t": t,
                    "x": est[:, 0],
                    "y": est[:, 1],
                    "x_true": true[:, 0],
                    "y_true": true[:, 1],
                    "error": np.linalg.norm(est - true, axis=1),
                }
            ).to_csv(folder / "trajectories" / split / f"{name}.csv", index=False)
            rows.append({"name": name, "mode": mode, "placement": place, "ate": ate, "rte": ate / 2})
        s = {"sequences": len(rows), "ate_mean": ate, "rte_mean": ate / 2}
        splits[split] = {
            "summary": s,
            "by_mode": {m: s for m in modes},
            "by_placement": {p: {**s, "ate_mean": ate + (0.5 if p == "BG" else 0)} for p in places},
            "sequences": rows,
        }
    (folder / "metrics.json").write_text(
        json.dumps(
            {
                "model": model,
                "splits": splits,
                "training": {"epochs_run": 30, "stopped_by": "epochs", "wall_s": 60, "beats_trivial": True},
            }
        )
    )
    return folder


@pytest.fixture
def grid_runs(tmp_path):
    folders = [fake_run(tmp_path / "suite", m, s, a) for m, v in ATE.items() for s, a in enumerate(v)]
    folders.append(fake_run(tmp_path / "suite", "suitein", 0, 2.0))
    folders.append(tmp_path / "suite" / "ronin-unfinished")  # no metrics.json: left out
    return folders


def test_row_labels_and_seeded_configs(tmp_path, tiny_dataset):
    assert odometry.row_label("suitein++", {"extractor": "mixed"}) == "suitein++ (extractor=mixed)"
    assert odometry.row_label("ronin", {"width": 8}) == "ronin (width=8)" and odometry.row_label("pdr", {}) == "pdr"
    data = tiny_dataset(1, tmp_path / "d")
    cfgs = odometry.suite_configs(data, ["pdr", ("ronin", {})], seeds=[0, 1, 2], epochs=2)
    assert [(c.model, c.seed) for c in cfgs] == [
        ("pdr", 0),
        ("pdr", 1),
        ("pdr", 2),
        ("ronin", 0),
        ("ronin", 1),
        ("ronin", 2),
    ]
    assert len({odometry.run_folder(tmp_path, c) for c in cfgs}) == 6  # one folder per model × seed
    assert [c.seed for c in odometry.suite_configs(data, ["pdr"], seed=4)] == [4]  # the one-seed call as before
    with pytest.raises(ConfigError):
        odometry.suite_configs(data, ["pdr"], seeds=[1, 1])
    assert ("suitein++-rows", {}) in odometry.GRIDS["paper"]
    assert {f"suitein++-abl{n}" for n in range(1, 6)} <= {m for m, _ in odometry.GRIDS["paper"]}


def test_cells_and_markers_from_known_numbers(grid_runs):
    grid = tables.read_grid(grid_runs)
    assert list(grid) == ["suitein++", "ronin", "pdr", "suitein"]
    table, stats = tables.marked_table(grid, list(grid), tables.table3_columns("test"), expected=3)
    cell = dict(zip(table["model"], table["ATE"]))
    assert cell["suitein++"] == "1.00 ± 0.10"
    assert cell["ronin"] == "3.00 ± 0.10 †"  # well separated seeds
    assert cell["pdr"] == "1.02 ± 0.30"  # overlapping seeds: no marker
    assert cell["suitein"] == "2.00"  # one seed: no spread, no test
    assert dict(zip(table["model"], table["seeds"])) == {
        "suitein++": "3",
        "ronin": "3",
        "pdr": "3",
        "suitein": "1 of 3",
    }
    assert stats["ATE"]["ronin"]["p_bh"] < 0.05 < stats["ATE"]["pdr"]["p_bh"]
    assert stats["ATE"]["suitein"]["p"] is None
    assert cell == dict(zip(table["model"], table["DRW ATE"]))


def test_placement_summary_and_page(grid_runs, tmp_path):
    grid = tables.read_grid(grid_runs)
    r = grid["ronin"][0]
    assert tables.placement_summary(r, "HD")["ate_mean"] == 3.0  # from test
    assert tables.placement_summary(r, "BG")["ate_mean"] == 3.5  # from test_unseen
    assert tables.phone_only("ronin", grid) and not tables.phone_only("suitein", grid)

    out = tmp_path / "suite"
    page = tables.write_grid_report(grid_runs, out, expected_seeds=3).read_text()
    assert "## Table III: split `test`" in page and "## Table III: split `test_unseen`" in page
    t4 = page[page.index("## Table IV") : page.index("## Table VI")]
    assert "BG ATE" in t4 and "3.50 ± 0.10 †" in t4 and "suitein " not in t4  # phone-only rows + Suite-IN++
    assert "`initial`: one constant yaw" in page and "epochs 30, patience 10" in page
    assert "## Table V:" not in page  # no ablation ran
    for fig in ("fig7_placement_cdf.png", "fig11_speed.png"):
        assert (out / fig).stat().st_size > 1000 and f"]({fig})" in page
    doc = json.loads((out / "results.json").read_text())
    assert doc["tables"]["III test"]["ATE"]["ronin"]["values"] == [3.0, 3.1, 2.9]


def test_table_v_marks_and_table_vi_columns(tmp_path):
    from wearnav.bench.efficiency import macs_per_window
    from wearnav.models.registry import build, n_parameters

    folders = [
        fake_run(tmp_path, m, s, a)
        for m, v in {"suitein++": [1.0, 1.1], "suitein++-abl1": [2.0, 2.2]}.items()
        for s, a in enumerate(v)
    ]
    page = tables.write_grid_report(folders, tmp_path / "page", expected_seeds=2).read_text()
    assert "| suitein++-abl1 |" not in page[page.index("## Table III") : page.index("## Table V:")]  # Table V only
    t5 = page[page.index("| variant") : page.index("## Table VI")]
    assert "| (1)       |" in t5 and t5.count("✓") == 3  # (1): no module; (6): all three
    t6 = page[page.index("## Table VI") :]
    for col in ("params", "MMACs per window", "windows/s b1", "windows/s b256"):
        assert col in t6
    row = json.loads((tmp_path / "page" / "results.json").read_text())["tables"]["VI"][0]
    model = build("suitein++", n_devices=3, window=100)
    assert row["params"] == n_parameters(model)
    assert row["MMACs per window"] == pytest.approx(macs_per_window(model) / 1e6)
    assert 17.0 < row["MMACs per window"] < 23.0  # the paper's 0.020 G (Table VI), GRU included
    assert row["windows/s b256"] > 0


def test_speed_from_positions():
    t = np.arange(0, 10, 0.04)
    v = tables.speed_of(t, np.stack([1.5 * t, 0 * t], 1))
    assert v == pytest.approx(1.5)  # the ends too


@pytest.mark.parametrize(
    "args, says",
    [
        (("--seeds", "0,x"), "--seeds takes comma-separated integers"),
        (("--seeds", "0,0"), "seeds must be distinct"),
        (("--grid", "paper", "--models", "pdr"), "not both"),
    ],
)
def test_bad_grid_options_are_one_line(tmp_path, monkeypatch, capsys, args, says):
    from conftest import run_cli

    code, _, err = run_cli(
        monkeypatch, capsys, "bench", "odometry", "--data", tmp_path / "d", "--out", tmp_path / "s", *args
    )
    assert code == 2 and says in err and err.count("\n") == 1


def test_unknown_model_args_refused_before_any_run(tmp_path, tiny_dataset):
    tiny_dataset(1, tmp_path / "d")
    cfgs = odometry.suite_configs(tmp_path / "d", [("ronin", {"no_such_switch": 1})], seeds=[0, 1], epochs=1)
    with pytest.raises(ConfigError, match="no_such_switch"):
        odometry.run_suite(cfgs, tmp_path / "suite")
    assert not (tmp_path / "suite").exists() or not any((tmp_path / "suite").iterdir())


def test_test_frame_table_pairs_honest_and_diagnostic_scores(grid_runs, tmp_path):
    """Issue 16 §1: per model, the honest ATE beside the diagnostic truth-frame ATE of the same runs
    (only seeds that have both), and their difference."""
    for folder, extra in ((grid_runs[0], 0.3), (grid_runs[1], 0.1)):  # suitein++ seeds 0 and 1
        diag = folder / odometry.DIAGNOSTIC_TRUTH_FRAME
        diag.mkdir()
        m = json.loads((folder / "metrics.json").read_text())
        for split in m["splits"].values():
            split["summary"]["ate_mean"] -= extra
        (diag / "metrics.json").write_text(json.dumps(m))
    table = tables.test_frame_table(tables.read_grid(grid_runs), ["suitein++", "ronin"], ("test",))
    assert list(table["model"]) == ["suitein++"]  # ronin has no diagnostic
    row = table.iloc[0]
    assert row["test honest"] == pytest.approx(1.05) and row["test diagnostic"] == pytest.approx(0.85)
    assert row["test Δ"] == pytest.approx(0.2)


def test_the_velocity_loss_reaches_every_run_and_names_its_folder(tmp_path):
    """`bench odometry --vel-loss polar` (issue 34: the simulator's tables with the fix): every
    config carries the loss, and its runs are not the MSE runs' folders."""
    mse = odometry.suite_configs(tmp_path / "d", ["suitein++", "ronin"], seeds=[0, 1], epochs=1)
    polar = odometry.suite_configs(tmp_path / "d", ["suitein++", "ronin"], seeds=[0, 1], epochs=1, vel_loss="polar")
    assert {c.vel_loss for c in mse} == {"mse"} and {c.vel_loss for c in polar} == {"polar"}
    assert {str(odometry.run_key(c)) for c in mse}.isdisjoint({str(odometry.run_key(c)) for c in polar})
    # `--heading-frame` (the shipped recipe's frame): no random yaw with it, its own folders too
    framed = odometry.suite_configs(
        tmp_path / "d", ["suitein++"], seeds=[0], epochs=1, vel_loss="polar", heading_frame=True, augment=()
    )
    assert framed[0].heading_frame and "rotate_yaw" not in framed[0].augment
    assert str(odometry.run_key(framed[0])) not in {str(odometry.run_key(c)) for c in polar}
