"""The multi-source activity model (issue 35): gravity-aligned input, balanced sampling, labels of
whole-recording sources, the unknown threshold, a tiny leave-one-dataset-out suite on real slices,
and `classify` labelling unsure windows unknown."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
import torch
from scipy.spatial.transform import Rotation

from conftest import make_stream
from wearnav import activity_labels as al
from wearnav import pretrained
from wearnav.bench.executor import Execution
from wearnav.bench.har_lodo import IN_DATASET, run_lodo
from wearnav.errors import FormatError
from wearnav.importers import import_dataset, sensorlogger
from wearnav.importers.sensorlogger_export import simulated_export
from wearnav.models import registry
from wearnav.models.har import gravity_rotation, rotate_windows
from wearnav.outputs import check_suite_folder
from wearnav.recording import Recording, Trajectory
from wearnav.train import activity as act
from wearnav.train import activity_data as actd
from wearnav.train import labelling
from wearnav.train.classify import context_probs, load_model
from wearnav.train.labelling import UNKNOWN, label_recordings, window_classes


def test_gravity_rotation_turns_the_mean_acceleration_up():
    g = torch.randn(500, 3)
    g[0] = torch.tensor([0.0, 0.0, -9.8])  # upside down: the flipped branch
    g[1] = torch.tensor([0.0, 0.0, 0.0])  # an absent device: identity
    R = gravity_rotation(g[:, None, :].expand(500, 4, 3))
    up = (R[2:] @ (g[2:] / g[2:].norm(dim=1, keepdim=True))[..., None])[..., 0]
    assert torch.allclose(up, torch.tensor([0.0, 0.0, 1.0]).expand_as(up), atol=1e-5)
    assert torch.allclose(R @ R.transpose(1, 2), torch.eye(3).expand_as(R), atol=1e-5)
    assert torch.allclose(torch.linalg.det(R), torch.ones(500), atol=1e-5)
    assert torch.allclose(R[0] @ g[0], torch.tensor([0.0, 0.0, 9.8]), atol=1e-4)
    assert torch.equal(R[1], torch.eye(3))


def test_aligned_input_does_not_depend_on_how_the_device_is_held():
    """The same motion seen by a device held two ways: after alignment only the heading differs,
    so the vertical channels and the horizontal norms agree."""
    rng = np.random.default_rng(0)
    x = torch.from_numpy(rng.normal(size=(8, 1, 128, 6)).astype(np.float32))
    x[..., 2] += 9.81
    Q = torch.from_numpy(Rotation.random(8, random_state=0).as_matrix().astype(np.float32))[:, None]
    xq = rotate_windows(x, Q)
    a = rotate_windows(x, gravity_rotation(x[..., :3]))
    b = rotate_windows(xq, gravity_rotation(xq[..., :3]))
    for ch in (2, 5):
        assert torch.allclose(a[..., ch], b[..., ch], atol=1e-3)
    for chs in ((0, 1), (3, 4)):
        assert torch.allclose(a[..., chs].norm(dim=-1), b[..., chs].norm(dim=-1), atol=1e-3)
    # in training the heading is drawn at random, so the same window gives different logits
    m = registry.build("har-gravity", n_devices=1, window=128, n_classes=3, gyro_dropout=0.0).train()
    torch.manual_seed(0)
    assert not torch.allclose(m.head_inputs(x, torch.ones(8, 1))[0], m.head_inputs(x, torch.ones(8, 1))[0])
    m.eval()
    assert torch.equal(m.head_inputs(x, torch.ones(8, 1))[0], m.head_inputs(x, torch.ones(8, 1))[0])


def test_sample_weights_balance_classes_and_sources():
    y = np.array([0] * 90 + [0] * 10 + [1] * 5)
    src = np.array(["a"] * 90 + ["b"] * 10 + ["a"] * 5)
    p = act.sample_weights(y, src)
    assert np.isclose(p.sum(), 1)
    assert np.isclose(p[y == 1].sum(), 0.5)  # class_power 0: each class half
    assert np.isclose(p[(y == 0) & (src == "a")].sum(), p[(y == 0) & (src == "b")].sum())  # sources equal
    p = act.sample_weights(y, src, class_power=0.5)  # class mass ∝ √windows: 10 : √5
    assert np.isclose(p[y == 0].sum() / p[y == 1].sum(), 10 / np.sqrt(5))
    assert np.isclose(p[(y == 0) & (src == "a")].sum(), p[(y == 0) & (src == "b")].sum())
    capped = act.cap_per_class(
        actd.Windows(np.zeros((105, 2, 6)), y, src, np.zeros(105, bool), np.zeros(105, int)), 20, 0
    )
    assert len(capped) == 20 + 10 + 5


def test_windows_runs_are_each_recordings_consecutive_windows():
    src = np.array(["a", "a", "a", "b", "b", "a"])
    rec = np.array([0, 0, 1, 0, 0, 0])
    w = actd.Windows(np.zeros((6, 2, 6)), np.zeros(6, np.int64), src, np.zeros(6, bool), rec)
    assert [r.tolist() for r in w.runs()] == [[0, 1], [2], [3, 4], [5]]
    assert actd.Windows.concat([]).runs() == []


def test_whole_recording_labels_trim_edges_and_leave_out_floor_changes():
    rec = Recording(
        name="w",
        devices={"phone": make_stream(2000, 50.0)},
        truth=Trajectory(np.array([0.0, 10.0, 20.0, 39.0]), np.zeros((4, 2)), floor=np.array([0.0, 0.0, 1.0, 1.0])),
    )
    t = np.arange(0, 40, 0.02)
    lab = actd.sample_labels("ipin", rec, t)
    walk = al.LABELS.index(al.WALKING)
    assert np.all(lab[t < al.EDGE_TRIM_S] == -1) and np.all(lab[t > t[-1] - al.EDGE_TRIM_S] == -1)
    assert np.all(lab[(t >= 10) & (t <= 20)] == -1)  # floor 0 → 1: how is not known
    assert np.all(lab[(t > 4) & (t < 9.9)] == walk) and np.all(lab[(t > 20.1) & (t < 36)] == walk)
    assert np.all(actd.sample_labels("ilc2", rec, t)[(t > 4) & (t < 36)] == walk)  # ILC2: no floor rule


def test_step_rate_tells_walking_from_standing():
    """Whole-walk sources keep a window as walking only at walking cadence (PDR's step detector)."""
    t = np.arange(128) / 50.0
    walk = np.zeros((2, 128, 6), np.float32)
    walk[..., 2] = 9.81
    walk[0, :, 2] += 2.0 * np.sin(2 * np.pi * 1.8 * t)  # 1.8 steps/s, vertical bounce
    rates = actd.step_rate_hz(walk, 50.0)
    assert abs(rates[0] - 1.8) < 0.2 and rates[1] == 0.0


def test_unknown_threshold_keeps_95_percent_of_correct_windows():
    rng = np.random.default_rng(1)
    conf = rng.uniform(0.2, 1.0, 1000)
    correct = rng.uniform(size=1000) < conf
    thr = act.unknown_threshold(conf, correct)
    assert np.mean(conf[correct] >= thr) >= 0.95
    assert np.mean(conf[correct] >= np.nextafter(thr, 1)) < 0.95  # the largest such threshold


def test_context_probs_is_the_normalised_geometric_mean_of_the_neighbours():
    rng = np.random.default_rng(2)
    prob = rng.dirichlet(np.ones(4), size=9).astype(np.float32)
    assert np.allclose(context_probs(prob, 1), prob, atol=1e-6)  # no context: the window's own
    ctx = context_probs(prob, 5)
    assert ctx.shape == prob.shape and np.allclose(ctx.sum(1), 1.0, atol=1e-6)
    for i, (a, b) in {0: (0, 3), 1: (0, 4), 2: (0, 5), 3: (1, 6), 6: (4, 9), 7: (5, 9), 8: (6, 9)}.items():
        g = np.exp(np.log(prob[a:b]).mean(axis=0))
        assert np.allclose(ctx[i], g / g.sum(), atol=1e-5), i
    # one stray window among walking ones is outvoted; a run of 3 of 5 is not
    walk = np.tile([[0.9, 0.05, 0.05]], (7, 1))
    stray = walk.copy()
    stray[3] = [0.1, 0.85, 0.05]
    assert context_probs(stray, 5).argmax(1).tolist() == [0] * 7
    run = walk.copy()
    run[2:5] = [0.02, 0.96, 0.02]
    assert context_probs(run, 5)[3].argmax() == 1
    assert np.all(np.isfinite(context_probs(np.eye(3)[[0, 1, 0]], 3)))  # zero probabilities
    with pytest.raises(ValueError, match="odd"):
        context_probs(prob, 4)


@pytest.fixture(scope="module")
def tiny_sources(shared_data, tmp_path_factory):
    """Real slices: UCI HAPT's first experiment, two Oxford walks, four UJI executions."""
    root = tmp_path_factory.mktemp("lodo-data")
    data = {}
    for source, limit in (("uci-hapt", 1), ("oxford", 2), ("uji-phone", 4)):
        spec = actd.SOURCES[source]
        data[source] = str(root / source)
        import_dataset(spec.fmt, shared_data / spec.src, root / source, limit=limit, progress=False)
    return data


@pytest.mark.real_data
@pytest.mark.slow
def test_tiny_leave_one_dataset_out_suite(tiny_sources, tmp_path):
    out = tmp_path / "lodo"
    base = act.ActivityRun(device="phone", sources=(), data={}, epochs=1, steps=3, max_per_class=200)
    sources = {"phone": tuple(tiny_sources)}
    res = run_lodo(
        tmp_path,
        out,
        ("phone",),
        base,
        Execution(threads=1),
        final=True,
        sources=sources,
        data=tiny_sources,
        echo=lambda s: None,
    )
    phone = res["devices"]["phone"]
    assert [r["held-out source"] for r in phone["rows"]] == list(tiny_sources)
    for r in phone["rows"]:
        assert 0 <= r["LODO accuracy"] <= 1
        assert r["in-dataset accuracy"] is None or 0 <= r["in-dataset accuracy"] <= 1  # slices may lack test subjects
        assert r["LODO walking recall"] is not None  # every slice has walking
    ho = act.read_heldout(phone["runs"]["oxford"])
    assert set(ho["source"]) == {"oxford"} and len(ho["true"]) == phone["rows"][1]["windows"]
    assert np.all(ho["true"] >= 0) and ho["pred_window"].shape == ho["pred"].shape  # labelled windows only
    assert all(0 <= r["LODO walking recall, window alone"] <= 1 for r in phone["rows"])
    # the ILC2-like whole-walk source trains in the other folds only
    assert "oxford" not in json.loads((act.Path(phone["runs"]["oxford"]) / "training.json").read_text())["sources"]
    assert 0 < phone["unknown"]["threshold"] <= 1 and phone["unknown"]["correct_kept"] >= 0.95
    # stairs come from UCI HAPT alone here: a rare class, its prior cut by rare_factor
    rec = json.loads((act.Path(phone["runs"]["oxford"]) / "training.json").read_text())
    assert "stairs_up" in rec["rare_classes"] and rec["class_sources"]["walking"] == 2
    page = (out / "results.md").read_text()
    assert "| held-out source" in page and "unknown` threshold" in page
    # standing and sitting (UCI HAPT has both): the rule calibrated on the held-out windows, scored per
    # source on rules calibrated without it, and written into the final model (issue 56 §3)
    still = phone["still"]
    assert [r["held-out source"] for r in still["rows"]] == list(tiny_sources) and "Standing and sitting" in page
    if still["calibration"] is not None:
        assert set(still["calibration"]["rule"]) <= {"threshold", "standing_share", "gyro_rad_s"}
    check_suite_folder(out, "bench har-lodo")  # its own page: the suite resumes (e.g. to add --final)
    # the final model carries the threshold classify reads
    model, cfg, classes = load_model(phone["final"])
    assert model.unknown_threshold == phone["unknown"]["threshold"] and cfg.model == "har-gravity"
    rule = still["calibration"] and still["calibration"]["rule"]
    assert (model.still_rule and model.still_rule.record()) == rule
    assert model.context_windows == act.CONTEXT_WINDOWS == 5  # and the context it was scored with
    # resumable: a second invocation trains nothing
    said = []
    run_lodo(
        tmp_path,
        out,
        ("phone",),
        base,
        Execution(threads=1),
        final=True,
        sources=sources,
        data=tiny_sources,
        echo=said.append,
    )
    assert sum("complete, skipped" in s for s in said) == len(tiny_sources) + 2
    assert IN_DATASET in phone["runs"]


@pytest.mark.real_data
@pytest.mark.slow
def test_classify_labels_unsure_windows_unknown(tiny_sources, tmp_path):
    base = act.ActivityRun(
        device="phone",
        sources=("oxford", "uji-phone"),
        data={k: tiny_sources[k] for k in ("oxford", "uji-phone")},
        epochs=1,
        steps=2,
        unknown_threshold=1.0,  # every window is below it
    )
    run = tmp_path / "run"
    act.train_run(base, run)
    rec = Recording(name="walk", devices={"phone": make_stream(1500, 50.0)})
    model, cfg, classes = load_model(run)
    _, t, cls, conf = window_classes(model, cfg, rec)
    assert len(cls) > 0 and np.all(cls == -1)
    with pytest.warns(Warning, match="labelled unknown"):
        res = label_recordings([rec], run, tmp_path / "out")
    df = pd.read_csv(tmp_path / "out" / "walk_intervals.csv")
    assert list(df["label"]) == [UNKNOWN]
    assert any("labelled unknown" in w for w in res["warnings"])
    assert not any("held or worn differently" in w for w in res["warnings"])  # gravity is not its input
    model.unknown_threshold = 0.0  # none below it: the model's own classes
    _, _, cls, _ = window_classes(model, cfg, rec)
    assert np.all(cls >= 0)
    # each window decided over the context training.json names; an even one is refused on reading
    record = json.loads((run / "training.json").read_text())
    assert model.context_windows == record["context_windows"] == act.CONTEXT_WINDOWS
    (run / "training.json").write_text(json.dumps({**record, "context_windows": 4}))
    with pytest.raises(FormatError, match="odd"):
        load_model(run)


@pytest.mark.real_data
@pytest.mark.slow
def test_an_ensembles_first_member_is_the_single_run_and_it_decides_by_their_mean(tiny_sources, tmp_path):
    kw = dict(
        device="phone",
        sources=("oxford", "uji-phone"),
        data={k: tiny_sources[k] for k in ("oxford", "uji-phone")},
        epochs=1,
        steps=2,
    )
    act.train_run(act.ActivityRun(**kw), tmp_path / "one")
    act.train_run(act.ActivityRun(**kw, members=2), tmp_path / "two")
    one, _, _ = load_model(tmp_path / "one")
    two, cfg, _ = load_model(tmp_path / "two")
    assert cfg.model_args == {"members": 2} and len(two.members) == 2 and two.gravity_align
    first = two.members[0].state_dict()
    assert all(torch.equal(v, first[k]) for k, v in one.state_dict().items())  # seed + 0: the single run
    assert not torch.equal(first["fc.weight"], two.members[1].state_dict()["fc.weight"])
    x = torch.randn(5, 1, 128, 6)
    x[..., 2] += 9.8
    mask = torch.ones(5, 1)
    mean = torch.stack([torch.softmax(m(x, mask), dim=1) for m in two.members]).mean(dim=0)
    assert torch.allclose(torch.softmax(two(x, mask), dim=1), mean, atol=1e-6)
    assert "members" not in act.ActivityRun(**kw).record()  # runs from before it keep their folders


def test_classify_default_picks_the_model_by_devices(monkeypatch):
    monkeypatch.setattr(pretrained.Shipped, "installed", property(lambda self: True))
    assert pretrained.default_for("classify", ["phone"]).name == pretrained.ACTIVITY
    assert pretrained.default_for("classify", ["phone", "watch"]).name == pretrained.ACTIVITY
    assert pretrained.default_for("classify", ["watch"]).name == pretrained.ACTIVITY_WATCH
    assert pretrained.default_for("classify", ["watch", "earbuds"]).name == pretrained.ACTIVITY_WATCH
    assert pretrained.default_for("classify").name == pretrained.ACTIVITY


def _shipped_is_multi_source() -> bool:
    spec = pretrained.SHIPPED[pretrained.ACTIVITY]
    return spec.installed and "har-gravity" in (spec.path / "config.yaml").read_text()


def test_the_last_windows_alone_are_labelled_as_the_whole_labels_them():
    """window_classes(last=n), what the live page calls every second: the model sees only the windows
    the last n need (their contexts), and each comes out as in the whole recording's labelling."""
    from wearnav.simulate import WalkConfig, simulate_recording

    model, cfg, _ = load_model(pretrained.SHIPPED[pretrained.ACTIVITY].path)
    assert model.context_windows > 1  # otherwise the context would not be tested
    rec = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=30), seed=5)
    _, t, cls, conf = window_classes(model, cfg, rec)
    seen = []
    real = labelling.window_probs
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(labelling, "window_probs", lambda m, x, mask, **kw: seen.append(len(x)) or real(m, x, mask, **kw))
        for n in (1, 3):
            _, t_n, cls_n, conf_n = window_classes(model, cfg, rec, last=n)
            np.testing.assert_array_equal(t_n, t[-n:])
            np.testing.assert_array_equal(cls_n, cls[-n:])
            np.testing.assert_allclose(conf_n, conf[-n:], rtol=1e-6)
    assert seen == [1 + model.context_windows // 2, 3 + model.context_windows // 2] and len(t) > seen[-1]


def test_several_sessions_windows_classified_in_one_pass_are_labelled_as_alone():
    """The live receiver's batched activity (issue 37): the windows of several sessions through the
    classifier at once give each the probabilities, and the label, it gets alone."""
    from wearnav.live.models import classify_windows
    from wearnav.simulate import WalkConfig, simulate_recording

    model, cfg, _ = load_model(pretrained.SHIPPED[pretrained.ACTIVITY].path)
    recs = [
        simulate_recording(WalkConfig(mode=m, placement=p, duration_s=20), seed=k)
        for k, (m, p) in enumerate((("STW", "HD"), ("PVW", "MP"), ("STW", "PK")))
    ]
    ws = [labelling.class_windows(model, cfg, r, last=1) for r in recs]
    together = classify_windows(model, ws)
    assert [len(p) for p in together] == [len(w.index) for w in ws]
    for rec, w, prob in zip(recs, ws, together):
        np.testing.assert_allclose(prob, w.probs(model), atol=1e-5)
        _, t, cls, conf = window_classes(model, cfg, rec, last=1)
        t_b, cls_b, conf_b = labelling.decide_classes(model, w, prob)
        np.testing.assert_array_equal(t_b, t)
        np.testing.assert_array_equal(cls_b, cls)
        np.testing.assert_allclose(conf_b, conf, atol=1e-5)


@pytest.mark.slow
@pytest.mark.skipif(not _shipped_is_multi_source(), reason="the shipped activity model is not the multi-source one")
def test_shipped_activity_model_calls_a_simulated_sensor_logger_walk_walking(tmp_path):
    """Issue 35 "done when": ≥ 90 % walking on a simulated Sensor Logger walk through classify
    (the simulator is one of the model's training sources: not an independent measurement)."""
    simulated_export(tmp_path / "export", seed=1)
    recs = list(sensorlogger.read(tmp_path / "export"))
    res = label_recordings(recs, pretrained.SHIPPED[pretrained.ACTIVITY].path, tmp_path / "out")
    df = pd.read_csv(res["files"][0])
    assert df.loc[df["label"] == "walking", "windows"].sum() >= 0.9 * df["windows"].sum()


def test_still_windows_are_decided_between_standing_and_sitting_as_a_group():
    """Issue 56 §3: a still window the model splits between standing and sitting (neither over the one
    threshold) is still, and the calibrated share decides which; a window unsure of being still at
    all stays unknown, and a window of any other top class is decided as by the one threshold."""
    from wearnav.train.classify import StillRule, context_mean, decide

    classes = ["walking", "standing", "sitting", "other"]
    rule = StillRule.from_record({"threshold": 0.8, "standing_share": 0.45}, classes)
    prob = np.array(
        [
            [0.05, 0.50, 0.45, 0.00],  # a pause: standing (share 0.53)
            [0.03, 0.42, 0.54, 0.01],  # standing's share 0.44, under 0.45: sitting
            [0.02, 0.05, 0.90, 0.03],  # sitting, sure of it
            [0.30, 0.36, 0.30, 0.04],  # still or walking? 0.66 on still: unknown
            [0.40, 0.15, 0.10, 0.35],  # top walking 0.40 under the one threshold: unknown
            [0.90, 0.05, 0.04, 0.01],  # walking
            [0.01, 0.02, 0.02, 0.95],  # other
        ]
    )
    cls, conf = decide(prob, 0.664, rule)
    assert cls.tolist() == [1, 2, 2, -1, -1, 0, 3]
    np.testing.assert_allclose(conf, [0.95, 0.96, 0.95, 0.66, 0.40, 0.90, 0.95])
    plain, _ = decide(prob, 0.664)  # one threshold for every class, as before: the pause is unknown
    assert plain.tolist() == [-1, -1, 2, -1, -1, 0, 3]
    assert rule.record() == {"threshold": 0.8, "standing_share": 0.45}
    # with a gyroscope the posture is how much the phone turns: a swaying body stands, a seated one rests
    moving = StillRule.from_record({"threshold": 0.8, "standing_share": 0.45, "gyro_rad_s": 0.03}, classes)
    gyro = np.array([0.01, 0.05, 0.0, 0.05, 0.05, 0.01, 0.01])  # 0: no gyroscope, the share decides
    cls, _ = decide(prob, 0.664, moving, gyro)
    assert cls.tolist() == [2, 1, 2, -1, -1, 0, 3]
    assert decide(prob, 0.664, moving)[0].tolist() == [1, 2, 2, -1, -1, 0, 3]  # no rates given: the share
    assert moving.record()["gyro_rad_s"] == 0.03
    # the rate is averaged over the windows the probabilities are decided over
    np.testing.assert_allclose(context_mean(np.array([1.0, 2, 3, 4, 5]), 3), [1.5, 2, 3, 4, 4.5])
    with pytest.raises(FormatError, match="standing and sitting"):
        StillRule.from_record({"threshold": 0.8, "standing_share": 0.45}, ["walking", "sitting"])
    with pytest.raises(FormatError, match="threshold and standing_share"):
        StillRule.from_record({"threshold": 1.5, "standing_share": 0.45}, classes)


def test_still_rule_calibration_splits_postures_by_their_mean_recall():
    """har_lodo.calibrate_still: the group threshold keeps ≥ 95 % of the held-out windows that are
    still and called still; the standing share maximises the mean of the two postures' recall, so a
    posture with few windows counts as much as one with many."""
    from wearnav.bench import har_lodo

    rng = np.random.default_rng(3)
    st, si, wk = (al.LABELS.index(c) for c in (al.STANDING, al.SITTING, al.WALKING))
    n_st, n_si = 200, 2000  # sitting outnumbers standing ten to one
    share = np.concatenate([rng.normal(0.55, 0.05, n_st), rng.normal(0.40, 0.05, n_si)])
    q = rng.uniform(0.7, 1.0, n_st + n_si)
    prob = np.zeros((n_st + n_si, len(al.LABELS)))
    prob[:, st], prob[:, si], prob[:, wk] = q * share, q * (1 - share), 1 - q
    true = np.array([st] * n_st + [si] * n_si)
    source = np.where(np.arange(len(true)) % 2 == 0, "a", "b")  # two sources, each with both postures
    part = {"labels": prob, "true": true, "source": source}
    cal = har_lodo.calibrate_still([part])
    rule = cal["rule"]
    # equal spreads: equal recalls midway (0.475); the accuracy of all windows would favour sitting
    assert abs(rule["standing_share"] - 0.475) < 0.02
    kept = q >= rule["threshold"]
    assert kept.mean() >= 0.95 and (q >= rule["threshold"] + 1e-4).mean() < 0.95  # the largest, to its 4 decimals
    # without standing windows, or with one source's postures only, the rule is not calibrated
    assert har_lodo.calibrate_still([{**part, "true": np.full(len(true), si)}]) is None
    assert har_lodo.calibrate_still([{**part, "source": np.full(len(true), "a")}]) is None
    # with each window's angular rate, the posture is split on it too
    gyro = np.where(true == st, 0.06, 0.01) * rng.uniform(0.5, 1.5, len(true))
    moving = har_lodo.calibrate_still([{**part, "gyro": gyro}])["rule"]
    assert 0.01 < moving["gyro_rad_s"] <= 0.03 and moving["threshold"] == rule["threshold"]


def _walk_with_pause(pause_s: float = 40.0):
    """A simulated hand-held walk, then the phone held still in the same hand for ``pause_s``, then
    walking again: the stranger's Android walk of issue 56 §3 in miniature. The still part is the
    walk's own last second of gravity in the phone's frame plus sensor noise."""
    from wearnav.recording import DeviceStream, Recording
    from wearnav.simulate import WalkConfig, simulate_recording

    walk = simulate_recording(WalkConfig(mode="STW", placement="HD", duration_s=25, devices=("phone",)), seed=7)
    ph = walk.devices["phone"]
    rate = 1.0 / float(np.median(np.diff(ph.t)))
    n = int(pause_s * rate)
    rng = np.random.default_rng(0)
    g = ph.acc[-int(rate) :].mean(axis=0)
    still_acc = g + 0.03 * rng.standard_normal((n, 3))
    still_gyro = 0.005 * rng.standard_normal((n, 3))
    dur = ph.t[-1] - ph.t[0] + 1 / rate
    t = np.concatenate([ph.t, ph.t[-1] + (1 + np.arange(n)) / rate, ph.t + dur + pause_s])
    acc = np.concatenate([ph.acc, still_acc, ph.acc])
    gyro = np.concatenate([ph.gyro, still_gyro, ph.gyro])
    pause = (float(ph.t[-1]), float(ph.t[-1] + pause_s))
    return Recording(name="pause", devices={"phone": DeviceStream(t=t, acc=acc, gyro=gyro)}), pause


@pytest.mark.skipif(not _shipped_is_multi_source(), reason="the shipped activity model is not the multi-source one")
def test_shipped_model_does_not_call_a_pause_with_the_phone_in_hand_unknown(tmp_path):
    """Issue 56 §3: classify on a walk with a 40 s pause, the phone still in the hand: the pause's
    windows are standing or sitting, not unknown, and the walk stays walking."""
    rec, (a, b) = _walk_with_pause()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the walk is short; its warnings are not what is tested here
        res = label_recordings([rec], pretrained.SHIPPED[pretrained.ACTIVITY].path, tmp_path / "out")
    df = pd.read_csv(res["files"][0])

    def labels_over(t0: float, t1: float) -> set[str]:
        return set(df.loc[(df["end_s"] > t0) & (df["start_s"] < t1), "label"])

    assert labels_over(a + 8, b - 8) <= {al.STANDING, al.SITTING}, df.to_string()  # the context's edges left out
    assert labels_over(5, a - 5) == {al.WALKING}, df.to_string()
