"""wearnav.trust: the pure checks, and `wearnav track` / `wearnav classify` run through the command
line (in-process: the CLI's main, stdout and stderr captured) printing one ``warning:`` line per
reason not to trust their result (issue 22, §1)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from wearnav import trust
from wearnav.dataset import DatasetWriter
from wearnav.errors import WearnavWarning
from wearnav.recording import DeviceStream, Recording
from wearnav.simulate import WalkConfig, simulate_recording
from wearnav.track import track

G = 9.80665


def _warnings(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("warning: ")]


# ---- the pure checks ---------------------------------------------------------------------------


def test_window_gravity_is_the_unit_mean_per_window():
    acc = np.tile([0.0, 0.0, G], (250, 1)) + np.random.default_rng(0).normal(0, 1.0, (250, 3))
    acc[125:] = [G, 0.0, 0.0]
    d = trust.window_gravity(acc, 50)
    assert d.shape == (5, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert trust.angles_deg(d[:2], np.array([[0, 0, 1.0]])).max() < 10
    np.testing.assert_allclose(d[3:], [[1.0, 0, 0]] * 2)
    assert trust.window_gravity(acc[:10], 50).shape == (1, 3)  # shorter than a window: one


def test_missing_devices_names_what_the_recording_lacks():
    assert trust.missing_devices(("phone",), ("phone", "watch")) is None
    m = trust.missing_devices(("phone", "watch", "earbuds"), ("phone",))
    assert m.startswith("the model was trained on phone, watch and earbuds; this recording has no watch and earbuds")


def test_rate_outside_allows_the_tolerance():
    assert trust.rate_outside("phone", 100.0 * 1.09, [100.0, 100.0, 100.0]) is None
    assert trust.rate_outside("phone", 50.0, [100.0, 100.0, 100.0]) == (
        "phone is sampled at 50 Hz; the model's training data at 100 Hz"
    )
    assert "at 25–50 Hz" in trust.rate_outside("watch", 100.0, [25.0, 40.0, 50.0])


def test_rate_outside_is_no_finding_for_an_input_resampled_down_to_the_models_rate():
    """A 100 Hz export for a 50 Hz model trained on 50 Hz data is low-passed and resampled to 50 Hz
    as the training data was; a 25 Hz input, interpolated up, still is a finding."""
    assert trust.rate_outside("phone", 100.0, [50.0, 50.0, 50.0], model_rate_hz=50.0) is None
    assert trust.rate_outside("phone", 25.0, [50.0, 50.0, 50.0], model_rate_hz=50.0) == (
        "phone is sampled at 25 Hz; the model's training data at 50 Hz"
    )


def test_placement_outside_maps_the_simulators_codes():
    assert trust.placement_outside("handheld", ["HD", "PK"]) is None  # HD = handheld
    assert trust.placement_outside("pocket", ["MP"]) is None  # MP changes between hand and pocket
    assert trust.placement_outside("", ["HD"]) is None and trust.placement_outside("waist", []) is None
    assert trust.placement_outside("handheld", ["waist"]) == (
        "the recording's placement is 'handheld'; the model's training data had waist"
    )


def test_gravity_outside_needs_most_windows_unseen():
    z = np.tile([0.0, 0.0, 1.0], (20, 1))
    tilt = np.array([[0.0, np.sin(np.radians(20)), np.cos(np.radians(20))]] * 10)
    assert trust.gravity_outside("phone", tilt, z) is None  # 20° < GRAVITY_MATCH_DEG
    x = np.tile([1.0, 0.0, 0.0], (10, 1))
    assert trust.gravity_outside("phone", x, z).startswith(
        "phone is held or worn differently from the model's training data: in 100% of the recording"
    )
    assert trust.gravity_outside("phone", np.concatenate([x[:4], z[:6]]), z) is None  # 40 % unseen


def test_domain_findings_of_an_unknown_training_set():
    (only,) = trust.domain_findings({"placement": "", "devices": {}}, None)
    assert only.startswith("training data unknown")


def test_implausible_walk():
    walking = np.full(20, 1.8)  # steps/s
    assert trust.implausible_walk(np.full(20, 1.3), walking, 26.0, 36.0) == []  # 26 m ≈ 36 × 0.67 m
    (slow,) = trust.implausible_walk(np.full(20, 0.2), walking, 17.0, 36.0)
    assert slow == (
        "implausible for walking: the median speed is 0.20 m/s while steps are detected (walking is 0.5–2.5 m/s)"
    )
    (short,) = trust.implausible_walk(np.full(20, 1.3), walking, 5.0, 36.0)
    assert short.startswith("implausible for walking: the path is 5.0 m long, but 36 steps were detected")
    assert trust.implausible_walk(np.full(20, 0.0), np.zeros(20), 0.0, 0.0) == []  # standing: no steps


def test_baselines_and_did_not_learn():
    r = trust.odometry_baseline(0.5, 0.4)
    assert r["beats_trivial"] is False and r["trivial_val_vel_mse"] == 0.4
    assert trust.odometry_baseline(0.1, 0.4)["beats_trivial"] is True
    assert trust.odometry_baseline(None, 0.4)["beats_trivial"] is False
    assert trust.did_not_learn({**r, "best_val_vel_mse": 0.5}).startswith(
        "the model did not learn: its best validation velocity MSE (0.5 (m/s)²) is no better than standing still"
    )
    c = trust.classify_baseline(0.5, np.array([0, 0, 0, 1]), 0, ["walk", "sit"])
    assert c == {"beats_trivial": False, "trivial": "always walk (majority class)", "trivial_accuracy": 0.75}
    assert "no better than always walk (majority class) (0.75)" in trust.did_not_learn({**c, "accuracy": 0.5})
    assert trust.did_not_learn({"beats_trivial": True}) is None and trust.did_not_learn({}) is None


def test_data_facts_of_simulated_walks():
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=20), seed=2)
    f = trust.data_facts([rec, rec], ("phone", "watch"), 4.0)
    assert f["recordings"] == 2 and f["placements"] == ["HD"]
    assert f["devices"]["phone"]["rate_hz"] == [pytest.approx(rec.devices["phone"].rate, abs=0.01)] * 3
    g = np.array(f["devices"]["phone"]["gravity_directions"])
    assert g.shape == (2 * (len(rec.devices["phone"]) // 400), 3) and np.allclose(
        np.linalg.norm(g, axis=1), 1.0, atol=2e-3
    )
    json.dumps(f)  # what training.json keeps


# ---- the commands ------------------------------------------------------------------------------


def _rotate_device(s: DeviceStream, every: int = 1) -> DeviceStream:
    """The stream held another way: device axes permuted (x→z): gravity lies along another axis."""
    perm = [2, 0, 1]
    return DeviceStream(
        t=s.t[::every],
        acc=s.acc[::every][:, perm],
        gyro=None if s.gyro is None else s.gyro[::every][:, perm],
        quat=None if s.quat is None else s.quat[::every],
        worn=None if s.worn is None else s.worn[::every],
    )


@pytest.fixture(scope="module")
def odometry_run(tmp_path_factory):
    """RoNIN on phone + watch, 1 epoch at lr 1e-9: a run that did not learn, as `wearnav train`
    leaves it (training.json with its training data's facts)."""
    from wearnav.train.odometry import TrainConfig, fit, prepare_run

    root = tmp_path_factory.mktemp("trust")
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=60), seed=1)
    with DatasetWriter(root / "ds", {"made_by": "test_trust"}) as w:
        w.add(rec, split="train")
        w.add(dataclasses.replace(rec, name="walk_val"), split="val")
    cfg = TrainConfig(model="ronin", data=str(root / "ds"), devices=("phone", "watch"), epochs=1, lr=1e-9, stride=20)
    run = prepare_run(cfg, root / "run")
    record = fit(cfg, run, progress=False)
    return root, rec, run, record


@pytest.mark.slow
def test_track_warns_when_the_model_is_out_of_its_depth(odometry_run, tmp_path, monkeypatch, capsys):
    from conftest import run_cli

    root, rec, run, record = odometry_run
    assert record["beats_trivial"] is False  # the untrained network is worse than standing still
    assert record["trivial_val_vel_mse"] > 0.5 and record["best_val_vel_mse"] >= record["trivial_val_vel_mse"]
    assert record["training_data"]["devices"]["phone"]["rate_hz"][1] == pytest.approx(100.0, abs=0.1)
    # the same walk, phone only, sampled at 50 Hz (above the model's 25), held another way, placement "waist"
    phone = _rotate_device(rec.devices["phone"], every=2)
    other = Recording(name="mine", devices={"phone": phone}, meta={"placement": "waist"})
    other.save(tmp_path / "mine.h5")
    code, _, err = run_cli(
        monkeypatch, capsys, "track", tmp_path / "mine.h5", "--model", run, "--out", tmp_path / "out"
    )
    assert code == 0, err
    lines = _warnings(err)
    expect = [
        "warning: mine: the model was trained on phone and watch; this recording has no watch (its input there "
        "is zeros the model never saw in training): track it with a model trained on the devices it has "
        "(e.g. `wearnav train ronin --devices phone`) or with `--model pdr`",
        "warning: mine: the recording's placement is 'waist'; the model's training data had HD: the path may be "
        "wrong: use a model trained on recordings like this one, or `--model pdr`",
        "warning: mine: phone is held or worn differently from the model's training data: in 100% of the "
        "recording its gravity direction is more than 30° from any training window's: the path may be wrong: "
        "use a model trained on recordings like this one, or `--model pdr`",
    ]
    assert lines[:3] == expect
    # 50 Hz against 100 Hz training data is no finding: both are resampled to the model's 25 Hz
    assert not any("sampled at" in ln for ln in lines)
    assert any(
        ln.startswith("warning: mine: the model did not learn: its best validation velocity MSE")
        and ln.endswith("train it longer (more --epochs / --max-time) or use `--model pdr`")
        for ln in lines
    )
    assert any(ln.startswith("warning: mine: implausible for walking: the median speed is") for ln in lines)
    saved = json.loads((tmp_path / "out" / "track.json").read_text())["warnings"]
    assert ["warning: " + w for w in saved] == lines

    # a run from before the training data was recorded: said so, once (in-process: the same lines)
    (run / "training.json").write_text(json.dumps({k: v for k, v in record.items() if k != "training_data"}))
    try:
        with pytest.warns(WearnavWarning):
            summary = track(tmp_path / "mine.h5", run, tmp_path / "out2")
    finally:
        (run / "training.json").write_text(json.dumps(record))
    unknown = [ln for ln in summary["warnings"] if "training data unknown" in ln]
    assert len(unknown) == 1 and unknown[0].startswith("mine: training data unknown: the model's run")


def test_track_is_quiet_on_data_like_its_training(odometry_run, tmp_path):
    """The training walk itself through PDR (walks plausibly, no warning) and through the run: no
    out-of-domain line (its domain is the training data's), only what a run that did not learn
    earns: the did-not-learn and implausible-result lines and, where its path is garbage, the fixes
    disagreeing with it (the fixes' receiver-filter error and ramped multipath make them disagree
    with each other too, so the smoother falls back and says so) and going farther than it does."""
    from wearnav.train.odometry import TrainConfig, fit, prepare_run

    root, rec, run, _ = odometry_run
    rec.save(tmp_path / "walk.h5")
    cfg = TrainConfig(model="pdr", data=str(root / "ds"), devices=("phone", "watch"))
    pdr = prepare_run(cfg, tmp_path / "pdr")
    fit(cfg, pdr, progress=False)
    assert track(tmp_path / "walk.h5", pdr, tmp_path / "o1")["warnings"] == []
    with pytest.warns(WearnavWarning):
        warned = track(tmp_path / "walk.h5", run, tmp_path / "o2")["warnings"]
    kinds = {ln.split(": ", 2)[1] for ln in warned}
    kinds = {"fixes disagree" if "location fixes disagree with the path" in k else k for k in kinds}
    assert "the model did not learn" in kinds
    short = {
        "the odometry walked far less than the fixes moved",
        "the odometry walked far less than the activity model says",
    }
    assert kinds <= {"the model did not learn", "implausible for walking", "fixes disagree"} | short


@pytest.fixture(scope="module")
def classifier_run(odometry_run):
    """The walk's phone placement labels (texting, swinging, ...), a 1-epoch classifier at lr
    1e-9 (it did not learn), evaluated as `wearnav bench har` does."""
    from wearnav.bench.har import BASELINE
    from wearnav.train.classify import ClassifyConfig, evaluate_run, fit, prepare_run

    root, rec, _, _ = odometry_run
    other = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=60), seed=3)
    with DatasetWriter(root / "har", {"made_by": "test_trust"}) as w:
        w.add(dataclasses.replace(rec, name="a"), split="train")
        w.add(dataclasses.replace(other, name="b"), split="train")
        w.add(dataclasses.replace(other, name="c"), split="test")
    cfg = ClassifyConfig(
        model=BASELINE, data=str(root / "har"), label_kind="placement", epochs=1, lr=1e-9, model_args={"hidden": 8}
    )
    run = prepare_run(cfg, root / "clf")
    metrics = evaluate_run(run, training=fit(cfg, run, progress=False))
    return run, metrics


@pytest.mark.slow
def test_classify_warns_outside_its_domain_and_shows_its_labels(
    classifier_run, odometry_run, tmp_path, monkeypatch, capsys
):
    from conftest import run_cli

    run, metrics = classifier_run
    _, rec, _, _ = odometry_run
    # the untrained network (lr 1e-9) does no better than always answering the majority class
    assert metrics["beats_trivial"] is False and metrics["accuracy"] <= metrics["trivial_accuracy"]
    assert metrics["trivial"].endswith("(majority class)")
    classes = metrics["classes"]
    mine = Recording(
        name="mine", devices={"phone": _rotate_device(rec.devices["phone"], every=4)}, meta={"placement": "waist"}
    )
    mine.save(tmp_path / "mine.h5")
    code, out, err = run_cli(
        monkeypatch, capsys, "classify", tmp_path / "mine.h5", "--model", run, "--out", tmp_path / "lab"
    )
    assert code == 0, err
    assert f"labels the model knows: {', '.join(classes)}" in out.splitlines()
    advice = "the labels may be wrong: use a classifier trained on recordings like this one"
    lines = _warnings(err)
    assert lines[:3] == [
        f"warning: mine: the recording's placement is 'waist'; the model's training data had HD and MP: {advice}",
        f"warning: mine: phone is sampled at 25 Hz; the model's training data at 100 Hz: {advice}",
        "warning: mine: phone is held or worn differently from the model's training data: in 100% of the "
        f"recording its gravity direction is more than 30° from any training window's: {advice}",
    ]
    (learned,) = [ln for ln in lines if "did not learn" in ln]
    assert learned.startswith("warning: mine: the model did not learn: its test accuracy (")
    assert learned.endswith("its labels are no better than a constant guess: train it longer (more epochs)")
    doc = json.loads((tmp_path / "lab" / "classify.json").read_text())
    assert doc["classes"] == classes and ["warning: " + w for w in doc["warnings"]] == lines


def test_train_and_the_report_say_when_a_model_did_not_learn(odometry_run, tmp_path, monkeypatch, capsys):
    from conftest import run_cli
    from wearnav.bench.odometry import BEATS_STILL, comparison_table
    from wearnav.evaluate import evaluate_run

    root, _, run, _ = odometry_run
    evaluate_run(run, splits=("val",), progress=False)
    assert comparison_table([run], "val")[BEATS_STILL].tolist() == ["NO"]
    code, out, err = run_cli(
        monkeypatch,
        capsys,
        "train",
        "ronin",
        "--data",
        root / "ds",
        "--out",
        tmp_path / "r",
        "--devices",
        "phone",
        "--epochs",
        "1",
        "--lr",
        "1e-9",
        "--no-evaluate",
    )
    assert code == 0, err
    assert '"beats_trivial": false' in out and "training_data" not in out  # the facts stay in training.json
    (line,) = _warnings(err)
    assert line.startswith(f"warning: {tmp_path / 'r'}: the model did not learn: its best validation velocity MSE")
    assert line.endswith("train it longer (more --epochs / --max-time) or use `--model pdr`")
