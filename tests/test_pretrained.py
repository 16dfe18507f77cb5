"""Shipped models (issue 18 §1): the training mix, installing a run, and `track` / `classify`
without --model on a stranger's Sensor Logger export."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import run_cli
from test_bench_real import _building
from wearnav import pretrained
from wearnav.bench.real import RealBench, _train_config
from wearnav.bench.real_sites import estimate_site_yaw
from wearnav.dataset import Dataset, write_dataset
from wearnav.errors import ConfigError
from wearnav.importers.sensorlogger_export import write_export
from wearnav.pretrained.mix import MIX_FRAME, Part, recording_yaw, write_mix
from wearnav.pretrained.recipe import Recipe, install_run
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.train.odometry import TrainConfig, fit, load_model, prepare_run


@pytest.fixture(scope="module")
def sources(tmp_path_factory, tiny_dataset):
    """A stand-in building (phone frame turned 40° from its survey, points every 5 s) and the
    simulator's own recordings (each device with its drawn yaw offset, dense truth)."""
    root = tmp_path_factory.mktemp("mix")
    sim = Dataset.open(tiny_dataset(2, root / "sim"))
    recs = [sim.load(n) for n in sim.filter(mode=["STW", "DRW"]).names]
    write_dataset(root / "building", _building(recs, 40.0))
    return root


def _wrapped(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def test_mix_turns_every_source_into_its_own_input_frame(sources, tmp_path):
    out = write_mix(
        [Part(str(sources / "building"), "bldg"), Part(str(sources / "sim"), "sim", yaw="recording")],
        tmp_path / "mix",
        progress=False,
    )
    ds = Dataset.open(out)
    parts = {p["part"]: p for p in ds.provenance["parts"]}
    assert parts["bldg"]["recordings"] == len(Dataset.open(sources / "building"))
    assert parts["sim"]["recordings"] == len(Dataset.open(sources / "sim"))
    assert set(ds.manifest["split"]) <= {"train", "val"}
    # the building's part, turned by its phones' axis yaw: none is left, and PDR's fit moved with it
    yaw = parts["bldg"]["site_yaw"]
    write_dataset(tmp_path / "bldg", [(ds.load(n), "") for n in ds.names if n.startswith("bldg-")])
    left = estimate_site_yaw(tmp_path / "bldg", split=None)
    assert abs(_wrapped(left["phone_axis_yaw_deg"])) < 0.5
    assert _wrapped(left["yaw_deg"]) == pytest.approx(_wrapped(yaw["pdr_yaw_deg"] - yaw["yaw_deg"]), abs=0.5)
    # every simulated walk: its own truth-based yaw is gone; the sensor data is untouched
    sim = Dataset.open(sources / "sim")
    for name in sim.names[:3]:
        turned, original = ds.load(f"sim-{name}"), sim.load(name)
        before = np.degrees(recording_yaw(original, ("phone",)))
        assert abs(_wrapped(turned.meta["truth_turned_deg"] - before)) < 1e-3 and abs(before) > 1.0
        assert abs(np.degrees(recording_yaw(turned, ("phone",)))) < 0.1
        np.testing.assert_array_equal(turned.devices["phone"].acc, original.devices["phone"].acc)
        np.testing.assert_allclose(
            np.linalg.norm(np.diff(turned.truth.pos[:, :2], axis=0), axis=1),
            np.linalg.norm(np.diff(original.truth.pos[:, :2], axis=0), axis=1),
            atol=1e-9,
        )
    # a model trained elsewhere on a mix trains in the mix's frame, from joined surveyed points
    cfg = _train_config("suitein++", str(out), 12.0, RealBench(train_data=str(out)), elsewhere=True)
    assert (cfg.frame_align, cfg.yaw_deg) == (MIX_FRAME, 0.0) and cfg.truth_max_gap > 1.0


def test_an_installed_run_keeps_only_the_weights_and_predicts_the_same(tmp_path):
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=30), seed=3)
    write_dataset(tmp_path / "ds", [(rec, "train"), (dataclasses.replace(rec, name="v"), "val")])
    cfg = TrainConfig(model="suitein++", data=str(tmp_path / "ds"), epochs=1, stride=50, devices=("phone",))
    run = prepare_run(cfg, tmp_path / "run")
    fit(cfg, run, progress=False)
    dest = install_run(run, tmp_path / "shipped")
    full = (run / "checkpoints" / "best.ckpt").stat().st_size
    assert (dest / "checkpoints" / "best.ckpt").stat().st_size < 0.6 * full
    assert set(torch.load(dest / "checkpoints" / "best.ckpt", weights_only=False)) == {"state_dict"}
    (a, _), (b, _) = load_model(run), load_model(dest)
    x, mask = torch.randn(4, 1, 100, 6, generator=torch.Generator().manual_seed(0)), torch.ones(4, 1)
    assert torch.equal(a.predict(x, mask), b.predict(x, mask))


def test_a_missing_shipped_model_is_one_clear_line(monkeypatch, tmp_path):
    monkeypatch.setattr(pretrained, "MODELS_DIR", tmp_path)
    with pytest.raises(ConfigError, match="no shipped model 'phone-watch-earbuds'.*--model RUN"):
        pretrained.model_path(None, "odometry", ("phone", "watch"))
    # a phone-only recording without an installed phone model takes PDR, which needs nothing installed
    assert pretrained.model_path(None, "odometry", ("phone",)) == "pdr"
    with pytest.raises(ConfigError, match="a classify model, not odometry"):
        pretrained.model_path("activity", "odometry")
    assert pretrained.model_path("runs/x", "odometry") == "runs/x"


def _suite_page(root, rows_by_site: dict) -> object:
    """A suite folder whose results.json holds these known-start tables (what bench.real writes)."""
    root.mkdir(parents=True)
    sites = {site: {"table": table} for site, table in rows_by_site.items()}
    (root / "results.json").write_text(json.dumps({"sites": sites}))
    return root / "results.md"


def _row(method, median, length):
    return {
        "method": method,
        "median (m)": median,
        "p75 (m)": median + 2,
        "p95 (m)": median + 6,
        "length ratio": length,
        "traces": 10,
        "points": 134,
    }


def test_phone_only_choice_is_the_shipped_models_own_measurement_against_pdr(tmp_path, monkeypatch):
    """Issue 34: without --model a phone-only recording takes the shipped phone model only where its
    held_out.json shows it below PDR in every building it never trained in; the reason names them."""
    from wearnav.pretrained.recipe import held_out_record

    monkeypatch.setattr(pretrained, "MODELS_DIR", tmp_path / "models")
    phone = pretrained.SHIPPED[pretrained.PHONE].path
    (phone / "checkpoints").mkdir(parents=True)
    (phone / "checkpoints" / "best.ckpt").write_bytes(b"")
    (phone / "config.yaml").write_text("config: {}\n")
    assert pretrained.phone_only_choice()[0] == "pdr"  # installed, but measured nowhere
    learned = "suitein++ · simulator `sim` (commit abc)"

    def measured(ilc2_median):
        page = _suite_page(
            tmp_path / f"sim-to-real-{ilc2_median}" / "sim-to-real",
            {
                "main": [
                    _row(learned, 3.69, 1.03),
                    _row(learned + " · its speed, pointing", 1.0, 1.0),
                    _row("pdr", 4.77, 1.11),
                    _row("raw phone fixes", 5.72, float("nan")),
                ],
                "other": [_row(learned, ilc2_median, 0.83), _row("pdr", 3.75, 0.94)],
            },
        )
        return held_out_record(phone, page)

    record = measured(3.37)
    ipin, ilc2 = record["buildings"].values()
    assert (ipin["model_median_m"], ipin["pdr_median_m"], ipin["model_length_ratio"]) == (3.69, 4.77, 1.03)
    assert (ilc2["model_median_m"], ilc2["pdr_length_ratio"]) == (3.37, 0.94)  # the model's own row, not a variant
    path, why = pretrained.phone_only_choice()
    assert path == phone and "every building" in why and "3.37 against PDR's 3.75" in why
    assert pretrained.default_model("odometry", ("phone",))[0] == phone
    measured(4.19)  # worse than PDR in ILC2
    path, why = pretrained.phone_only_choice()
    assert path == "pdr" and "4.19 against PDR's 3.75" in why and "--model phone" in why
    assert pretrained.recorded_speed(phone) == "model"
    # no building measured the smoother: a recording with fixes is chosen by the known start too
    assert pretrained.phone_only_choice(has_fixes=True)[0] == "pdr"


def _with_smoother(page, site, rows):
    """``page``'s suite with a user-protocol table (path, median, p75) at ``site``."""
    doc = json.loads((page.parent / "results.json").read_text())
    table = [{**_row(path, median, 1.0), "path": path, "p75 (m)": p75} for path, median, p75 in rows]
    doc["sites"][site]["user_protocol"] = {"table": table}
    (page.parent / "results.json").write_text(json.dumps(doc))


def test_a_recording_with_fixes_is_chosen_by_the_smoothers_measurement(tmp_path, monkeypatch):
    """Issue 34: `track` places a recording with fixes by the smoother, so its phone-only default is
    chosen by the smoother's held-out median, where the building has fixes (IPIN; ILC2 has none);
    without fixes by the known start. A model that loses to PDR from a known start in ILC2 but wins
    on the smoother in IPIN is taken with fixes and not without; the reasons say which measurement."""
    from wearnav.pretrained.recipe import held_out_record

    monkeypatch.setattr(pretrained, "MODELS_DIR", tmp_path / "models")
    phone = pretrained.SHIPPED[pretrained.PHONE].path
    (phone / "checkpoints").mkdir(parents=True)
    (phone / "checkpoints" / "best.ckpt").write_bytes(b"")
    (phone / "config.yaml").write_text("config: {}\n")
    learned = "suitein++ · simulator `sim` (commit abc)"
    cadence = learned + " · cadence speed"
    smooth = " · smoother (`track` now)"
    page = _suite_page(
        tmp_path / "s" / "sim-to-real",
        {
            "main": [_row(learned, 3.9, 1.0), _row(cadence, 2.88, 0.98), _row("pdr", 4.77, 1.11)],
            "other": [_row(learned, 3.2, 0.9), _row(cadence, 3.94, 0.95), _row("pdr", 3.75, 0.94)],
        },
    )
    # the rows of the path with the recorded speed count, not the model's own
    _with_smoother(
        page, "main", [(learned + smooth, 7.0, 9.0), (cadence + smooth, 5.39, 7.54), ("pdr" + smooth, 6.15, 8.6)]
    )
    record = held_out_record(phone, page, "cadence")
    ipin, ilc2 = record["buildings"].values()
    assert ipin["smoother"] == {
        "model_median_m": 5.39,
        "model_p75_m": 7.54,
        "pdr_median_m": 6.15,
        "pdr_p75_m": 8.6,
        "walks": 10,
        "points": 134,
    }
    assert "smoother" not in ilc2  # no fixes there: no user protocol
    path, why = pretrained.phone_only_choice(has_fixes=True)
    assert path == phone and "with fixes" in why and "5.39 against PDR's 6.15" in why and "smoother" in why
    path, why = pretrained.phone_only_choice(has_fixes=False)
    assert path == "pdr" and "without fixes" in why and "3.94 against PDR's 3.75" in why
    assert pretrained.model_path(None, "odometry", ("phone",), has_fixes=True) == phone
    assert pretrained.model_path(None, "odometry", ("phone",)) == "pdr"
    # a smoother worse with the model than with PDR: PDR for a recording with fixes as well
    _with_smoother(page, "main", [(cadence + smooth, 6.4, 8.0), ("pdr" + smooth, 6.15, 8.6)])
    held_out_record(phone, page, "cadence")
    path, why = pretrained.phone_only_choice(has_fixes=True)
    assert path == "pdr" and "6.40 against PDR's 6.15" in why


def test_the_recipes_speed_is_recorded_and_taken_by_default(tmp_path, monkeypatch):
    """Recipe.speed: held_out.json records the numbers of the model's path with that speed (its
    hybrid's row, not the model's own) and the speed itself, which resolve_model then takes for the
    shipped model by default (an explicit speed wins); a page without that row is refused."""
    from wearnav.errors import ConfigError
    from wearnav.pretrained.recipe import held_out_record
    from wearnav.train.odometry import SPEED_SOURCES

    assert list(pretrained.SPEED_WORDS) == list(SPEED_SOURCES)
    monkeypatch.setattr(pretrained, "MODELS_DIR", tmp_path / "models")
    phone = pretrained.SHIPPED[pretrained.PHONE].path
    phone.mkdir(parents=True)
    learned = "suitein++ · simulator `sim` (commit abc)"
    page = _suite_page(
        tmp_path / "s" / "sim-to-real",
        {
            "main": [_row(learned, 3.69, 1.0), _row(learned + " · cadence speed", 2.86, 0.96), _row("pdr", 4.77, 1.11)],
            "other": [
                _row(learned, 3.37, 0.88),
                _row(learned + " · cadence speed", 3.13, 0.94),
                _row("pdr", 3.75, 0.94),
            ],
        },
    )
    record = held_out_record(phone, page, "cadence")
    assert record["speed"] == "cadence" == pretrained.recorded_speed(phone)
    assert [b["model_median_m"] for b in record["buildings"].values()] == [2.86, 3.13]
    (phone / "checkpoints").mkdir()
    (phone / "checkpoints" / "best.ckpt").write_bytes(b"")
    assert pretrained.recorded_speed(phone / "checkpoints" / "best.ckpt") == "cadence"  # a checkpoint: its run's
    assert pretrained.recorded_speed("pdr") == pretrained.recorded_speed(tmp_path) == "model"
    with pytest.raises(ConfigError, match="pointing"):
        held_out_record(phone, page, "pointing")


def test_cards_name_the_recipes_rows_and_each_building(tmp_path):
    from wearnav.pretrained.cards import RECIPE_ROW, measured_rows

    learned = "suitein++ · simulator `sim` (commit abc)"
    page = _suite_page(
        tmp_path / "sim-to-real",
        {
            "main": [_row(learned, 3.7, 1.0), _row(learned + " · PDR speed", 4.2, 1.1), _row("pdr", 4.8, 1.1)],
            "other": [_row(learned, 3.4, 0.8)],
        },
    )
    rows = measured_rows({"sim-to-real": page})
    assert [r["path"] for r in rows] == [RECIPE_ROW, f"{RECIPE_ROW} · PDR speed", "pdr", RECIPE_ROW]
    assert rows[0]["building"].startswith("IPIN") and rows[-1]["building"].startswith("ILC2")
    # user-protocol rows say at what lag the smoother read the fixes (the site's, `track --fix-lag`)
    doc = json.loads((tmp_path / "sim-to-real" / "results.json").read_text())
    smooth = {**_row(learned + " · smoother (`track` now)", 5.8, 0.85), "path": learned + " · smoother (`track` now)"}
    doc["sites"]["main"]["user_protocol"] = {"table": [smooth]}
    doc["sites"]["main"]["calibration"] = {learned: {"fix_lag_s": 3.5}, "pdr": {"fix_lag_s": 3.5}}
    (tmp_path / "sim-to-real" / "results.json").write_text(json.dumps(doc))
    user = [r for r in measured_rows({"sim-to-real": page}) if r["protocol"].startswith("user")]
    assert [r["protocol"] for r in user] == ["user (own fixes, read 3.5 s late: `track --fix-lag 3.5`)"]
    assert user[0]["path"] == f"{RECIPE_ROW} · smoother (`track` now)"


# ---- the shipped models themselves (issue 18, "done when") ------------------------------------

needs_shipped = pytest.mark.skipif(
    len(pretrained.installed()) < len(pretrained.SHIPPED),
    reason="the shipped models are not installed (wearnav pretrain --install)",
)


@needs_shipped
def test_shipped_models_are_small_and_carry_a_card():
    for spec in pretrained.SHIPPED.values():
        assert spec.size_bytes() < 5e6, spec.name
        card = (spec.path / pretrained.CARD).read_text()
        assert "## Known limits" in card and "licence" in card.lower()


@pytest.fixture(scope="module")
def stranger(tmp_path_factory):
    """A stranger's walk as Sensor Logger exports it: phone, watch, earbuds and GPS fixes."""
    root = tmp_path_factory.mktemp("stranger")
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=150), seed=11)
    return write_export(rec, root / "walk"), rec


@needs_shipped
@pytest.mark.slow
def test_track_without_model_lies_on_the_walks_own_fixes(stranger, monkeypatch, capsys, tmp_path):
    export, rec = stranger
    code, out, err = run_cli(monkeypatch, capsys, "track", str(export), "--out", str(tmp_path / "t"))
    assert code == 0, err
    summary = json.loads((tmp_path / "t" / "track.json").read_text())
    assert summary["shipped_model"] == pretrained.MULTI and "shipped model" in out
    geo = json.loads((tmp_path / "t" / "trajectory.geojson").read_text())
    line = next(f for f in geo["features"] if f["geometry"]["type"] == "LineString")
    table = pd.read_csv(tmp_path / "t" / "trajectory.csv")
    assert len(line["geometry"]["coordinates"]) > 10
    # on its fixes (as the export holds them: fixes.csv, east/north about the export's origin): the
    # path at each used fix's time lies within a few metres of it (the fixes scatter by 1-3 m)
    fx = pd.read_csv(tmp_path / "t" / "fixes.csv")
    fx = fx[fx["status"] == "used"]
    at = np.stack([np.interp(fx["t"], table["t"], table[c]) for c in ("east", "north")], axis=1)
    gap = np.linalg.norm(at - fx[["east", "north"]].to_numpy(), axis=1)
    assert len(fx) > 100 and np.median(gap) < 5.0
    assert "shipped model 'phone-watch-earbuds'" in summary["model_choice"]
    # phone only: what the shipped phone model's own measurement chose, saying why (issue 34); both
    # ways the choice can go are tested above
    phone_only = dataclasses.replace(rec, devices={"phone": rec.devices["phone"]})
    export2 = write_export(phone_only, tmp_path / "phone_walk")
    code, out, err = run_cli(monkeypatch, capsys, "track", str(export2), "--out", str(tmp_path / "t2"))
    assert code == 0, err
    t2 = json.loads((tmp_path / "t2" / "track.json").read_text())
    chosen, why = pretrained.phone_only_choice(has_fixes=True)  # the export has GPS fixes
    assert t2["model_choice"] == why and "PDR" in why and "with fixes" in why
    assert t2["shipped_model"] == (None if chosen == "pdr" else pretrained.PHONE)
    code, out, err = run_cli(
        monkeypatch, capsys, "track", str(export2), "--model", "phone", "--out", str(tmp_path / "t3")
    )
    assert code == 0, err
    t3 = json.loads((tmp_path / "t3" / "track.json").read_text())
    assert t3["shipped_model"] == pretrained.PHONE and t3["model_choice"] == "given with --model"
    # its speed: what its recipe recorded (cadence-long steps, turned onto the phone's pointing where
    # near it), unless --speed says otherwise
    recipe_speed = Recipe().speed_of(pretrained.PHONE)
    multi = pretrained.SHIPPED[pretrained.MULTI].path
    assert summary["speed"] == pretrained.recorded_speed(multi) == Recipe().speed_of(pretrained.MULTI) == "cadence"
    assert t3["speed"] == pretrained.recorded_speed(pretrained.SHIPPED["phone"].path) == recipe_speed == "snapped"
    assert pretrained.SPEED_WORDS[recipe_speed] in pretrained.phone_only_choice()[1]
    code, out, err = run_cli(
        monkeypatch,
        capsys,
        "track",
        str(export2),
        "--model",
        "phone",
        "--speed",
        "model",
        "--out",
        str(tmp_path / "t4"),
    )
    assert code == 0, err
    t4 = json.loads((tmp_path / "t4" / "track.json").read_text())
    assert t4["speed"] == "model" and t4["path"]["length_m"] != t3["path"]["length_m"]


@needs_shipped
def test_classify_without_model_writes_a_timeline(stranger, monkeypatch, capsys, tmp_path):
    export, _ = stranger
    code, out, err = run_cli(monkeypatch, capsys, "classify", str(export), "--out", str(tmp_path / "c"))
    assert code == 0, err
    assert list((tmp_path / "c").glob("*_timeline.png")) and list((tmp_path / "c").glob("*_intervals.csv"))
    assert "walking" in out


def test_shipped_calibration_is_the_recipes_worst_building(tmp_path, monkeypatch):
    """cross_building_calibration: the shipped run's fuse_calibration.json becomes the largest
    odometry random walk the leave-one-building-out models show on their held-out buildings, and
    the largest σ scale of those with fixes."""
    from wearnav import fuse
    from wearnav.core.textio import read_json
    from wearnav.pretrained import cards, recipe

    got = {"lobo-ipin": 0.56, "lobo-ilc2": 0.83}
    scale = {"lobo-ipin": 1.6, "lobo-ilc2": None}  # a building without fixes has no σ scale
    monkeypatch.setattr(
        recipe,
        "site_calibration",
        lambda run, site, data, trained, speed: {
            "odometry_walk_m_per_sqrt_s": got[run.parent.parent.name] * (1 if speed == "cadence" else 9),
            "sigma_scale": scale[run.parent.parent.name],
            "walks": 10,
        },
    )
    monkeypatch.setattr(recipe.runs, "read_config", lambda run: {"config": {"train": {"data": "mix"}}})
    suites = []
    for name in got:
        (tmp_path / name / "runs" / f"{recipe.MODEL}-abc").mkdir(parents=True)
        suites.append(tmp_path / name)
    shipped = tmp_path / "shipped"
    shipped.mkdir()
    cal = recipe.cross_building_calibration(shipped, suites, "cadence")  # the path with the speed `track` takes
    assert cal["odometry_walk_m_per_sqrt_s"] == 0.83 and cal["walks"] == 20
    named = {cards.site_name(suite, "main"): v for suite, v in got.items()}  # the buildings' names
    assert read_json(shipped / fuse.CALIBRATION_JSON)["per_building"] == named
    assert fuse.config_for(shipped)[0].odometry_walk_m_per_sqrt_s == 0.83
    assert cal["sigma_scale"] == 1.6 and fuse.config_for(shipped)[0].sigma_scale == 1.6


def test_both_odometry_models_train_on_the_simulator_in_their_own_suite(sources):
    """Issue 34: the multi-device model is made as the phone model is (one recipe: a suite trained
    on the simulator and scored in both real buildings, its run the shipped model), on its three
    devices; PDR stays on the phone; more devices than the phone only where the training data is
    simulated (the real walks carry the phone alone)."""
    from wearnav.bench.real import RealBench, _train_config
    from wearnav.errors import ConfigError
    from wearnav.pretrained.recipe import SUITES, Recipe, recipe_bench

    r, sim = Recipe(), sources / "sim"
    assert set(SUITES) == {pretrained.PHONE, pretrained.MULTI} and len(set(SUITES.values())) == 2
    multi, phone = recipe_bench(sim, r, pretrained.MULTI), recipe_bench(sim, r, pretrained.PHONE)
    three = pretrained.SHIPPED[pretrained.MULTI].devices
    assert multi.devices == three and three[0] == "phone" and phone.devices == ("phone",)
    assert multi.augment == phone.augment == ()
    # each model its own loss: the phone model the polar one (the real buildings), the three-device one
    # the MSE (Table III; its `track` path takes the cadence steps' length, not its own)
    assert (multi.vel_loss, phone.vel_loss) == ("mse", "polar") and multi.heading_frame and phone.heading_frame
    assert recipe_bench(sim, Recipe(multi_vel_loss="polar"), pretrained.MULTI).vel_loss == "polar"
    learned = _train_config("suitein++", str(sim), 0.0, multi, elsewhere=True)
    assert learned.devices == three and learned.heading_frame and "rotate_yaw" not in learned.augment
    # the earbuds' frame (measured, not shipped): the earbuds first, devices left out in training
    buds = recipe_bench(sim, Recipe(multi_frame="earbuds", multi_augment=("drop_devices",)), pretrained.MULTI)
    assert buds.devices == ("earbuds", "phone", "watch") and buds.augment == ("drop_devices",)
    assert recipe_bench(sim, Recipe(multi_frame="earbuds"), pretrained.PHONE).devices == ("phone",)
    assert _train_config("pdr", str(sim), 0.0, multi, elsewhere=True).devices == ("phone",)
    with pytest.raises(ConfigError, match="phone alone"):
        RealBench(devices=("phone", "watch"))  # trained on the real walks
    with pytest.raises(ConfigError, match="phone alone"):
        RealBench(devices=("watch",), train_data=str(sim))


def test_card_rows_name_the_recipe_once_and_keep_the_baselines_names():
    from wearnav.pretrained.cards import RECIPE_ROW, _path_name

    assert _path_name("suitein++ · `sim-hd` · cadence speed · map-aware") == f"{RECIPE_ROW} · cadence speed · map-aware"
    assert _path_name("suitein++ · `sim-hd`") == RECIPE_ROW
    assert _path_name("pdr · map-aware") == "pdr · map-aware"  # was once "the shipped recipe"
    assert _path_name("pdr") == "pdr"
