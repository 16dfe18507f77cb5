"""HAR benchmark pieces (paper 002): augmentations (eqs. 9–13), Head2/Head3 routing, subject
splits, and the --quick benchmark plus `wearnav classify` end to end on real UCI HAPT data."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import ROOT, make_stream
from wearnav.errors import ConfigError
from wearnav.models.har import HARNet
from wearnav.preprocess import Aligned, augment
from wearnav.preprocess.windows import WindowConfig, WindowDataset
from wearnav.train.classify import split_of, split_view

C, S = math.cos(math.pi / 6), math.sin(math.pi / 6)


# ---- rotation (eqs. 8–11) ----------------------------------------------------------------------


def test_rotation_matrices_are_eqs_9_to_11_and_orthonormal():
    expected = {
        "x": [[1, 0, 0], [0, C, S], [0, -S, C]],
        "y": [[C, 0, -S], [0, 1, 0], [S, 0, C]],
        "z": [[C, S, 0], [-S, C, 0], [0, 0, 1]],
    }
    for axis, m in expected.items():
        T = augment.axis_rotation(axis).numpy()
        np.testing.assert_allclose(T, m, atol=1e-15)
        np.testing.assert_allclose(T @ T.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(T) == pytest.approx(1.0)
    with pytest.raises(ConfigError, match="rotation axis"):
        augment.axis_rotation("w")


def test_rotate_imu_maps_acc_and_gyro_by_T():
    rng = np.random.default_rng(0)
    x = torch.from_numpy(rng.standard_normal((4, 2, 10, 6)))
    T = augment.axis_rotation("y")
    y = augment.rotate_imu(x, T).numpy()
    Tn = T.numpy()
    np.testing.assert_allclose(y[..., :3], np.einsum("ij,...j->...i", Tn, x.numpy()[..., :3]), atol=1e-12)
    np.testing.assert_allclose(y[..., 3:], np.einsum("ij,...j->...i", Tn, x.numpy()[..., 3:]), atol=1e-12)


def _wds(n_seq=2, T=400, window=50, stride=25):
    rng = np.random.default_rng(1)
    seqs = []
    for i in range(n_seq):
        imu = rng.standard_normal((1, T, 6)).astype(np.float32)
        imu[..., :3] = imu[..., :3] * 2.0 + [0, 0, 9.8]
        seqs.append(Aligned(f"s{i}", np.arange(T) / 50.0, ("phone",), imu, np.ones((1, T), bool)))
    return WindowDataset(seqs, WindowConfig(window=window, stride=stride, target=None))


def test_expansion_adds_fixed_copies_of_the_training_set():
    base = _wds()
    n = len(base)
    ex = augment.ExpandedWindows(base, augment.expansion_copies("rot_all"))
    assert len(ex) == 4 * n
    orig = base[list(range(n))]["x"]
    got = ex[list(range(4 * n))]["x"]
    torch.testing.assert_close(got[:n], orig)
    for c, axis in enumerate("xyz", 1):
        torch.testing.assert_close(got[c * n : (c + 1) * n], augment.rotate_imu(orig, augment.axis_rotation(axis)))


def test_noise_copy_statistics_and_is_the_same_every_epoch():
    base = _wds(n_seq=4, T=2000)
    n = len(base)
    sigma = augment.noise_sigma(base[list(range(n))]["x"], 0.1)
    # σ from the training windows: 0.1 × pooled std of acc (≈ std of N(0, 2²) plus the gravity offset) and gyro
    x = base[list(range(n))]["x"]
    assert sigma[0] == pytest.approx(0.1 * float(x[..., :3].std()))
    assert sigma[1] == pytest.approx(0.1 * float(x[..., 3:].std()))
    ex = augment.ExpandedWindows(base, ["noise"], sigma, seed=3)
    a = ex[list(range(n, 2 * n))]["x"]
    b = ex[list(range(n, 2 * n))]["x"]
    torch.testing.assert_close(a, b)  # generated once, not redrawn
    d = (a - x).numpy()
    assert abs(d.mean()) < 0.01
    assert d[..., :3].std() == pytest.approx(sigma[0], rel=0.03)
    assert d[..., 3:].std() == pytest.approx(sigma[1], rel=0.03)
    # no gyroscope (all zeros) → σ_gyro = 0: no noise where there is no sensor
    x0 = x.clone()
    x0[..., 3:] = 0
    assert augment.noise_sigma(x0)[1] == 0.0


def test_add_noise_statistics():
    g = torch.Generator().manual_seed(0)
    e = augment.add_noise(torch.zeros(200_000, 6, dtype=torch.float64), (0.3, 0.02), g).numpy()
    np.testing.assert_allclose(e.mean(axis=0), 0, atol=0.003)
    np.testing.assert_allclose(e.std(axis=0), [0.3] * 3 + [0.02] * 3, rtol=0.01)


# ---- moving average (eq. 13) --------------------------------------------------------------------


def test_moving_average_is_eq_13():
    rng = np.random.default_rng(2)
    x = rng.standard_normal((3, 60, 6))
    for n in (1, 10, 25, 50):
        y = augment.moving_average(x, n, axis=1)
        assert y.shape == x.shape
        for t in range(60):
            stop = min(t + n, 60)  # the last n − 1 samples average what remains
            np.testing.assert_allclose(y[:, t], x[:, t:stop].mean(axis=1), atol=1e-12)
    with pytest.raises(ConfigError, match="moving-average window"):
        augment.moving_average(x, 0)


# ---- random rotation on the fly -----------------------------------------------------------------


def test_rotate_random_keeps_norms_and_differs_per_device():
    rng = np.random.default_rng(3)
    x = torch.from_numpy(rng.standard_normal((8, 2, 20, 6)).astype(np.float32))
    g = torch.Generator().manual_seed(0)
    y = augment.get("rotate_random")({"x": x, "mask": torch.ones(8, 2)}, g)["x"]
    for sl in (slice(0, 3), slice(3, 6)):
        torch.testing.assert_close(y[..., sl].norm(dim=-1), x[..., sl].norm(dim=-1), atol=1e-5, rtol=1e-5)
    assert not torch.allclose(y, x, atol=1e-3)
    R = augment.random_rotation_matrices(100, torch.Generator().manual_seed(1)).numpy()
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


# ---- models: Head2 / Head3 routing --------------------------------------------------------------


@pytest.mark.parametrize(
    "heads,expected",
    [
        (1, [[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]]),
        (2, [[0, 1, 2, 6, 7, 8], [3, 4, 5, 9, 10, 11]]),  # acc head, gyro head (both devices)
        (3, [[0, 3, 6, 9], [1, 4, 7, 10], [2, 5, 8, 11]]),  # x, y, z: that axis' acc + gyro
    ],
)
def test_head_channel_routing(heads, expected):
    m = HARNet(n_devices=2, window=32, n_classes=4, heads=heads)
    assert m.head_channels == expected
    # channel c of device d carries the value 6·d + c: each head must see exactly its channels
    x = (torch.arange(12, dtype=torch.float32).reshape(2, 6)[None, :, None, :]).expand(3, 2, 32, 6).clone()
    for h, chans in zip(m.head_inputs(x, torch.ones(3, 2)), expected):
        assert h.shape == (3, len(chans), 32)
        torch.testing.assert_close(h[0, :, 0], torch.tensor(chans, dtype=torch.float32))
    assert m(x, torch.ones(3, 2)).shape == (3, 4)


def test_head2_acc_head_ignores_gyro():
    torch.manual_seed(0)
    m = HARNet(n_devices=1, window=40, n_classes=3, heads=2).eval()
    x = torch.randn(2, 1, 40, 6)
    x2 = x.clone()
    x2[..., 3:] += 5.0
    acc_head = m.branches[0]
    ins, ins2 = m.head_inputs(x, torch.ones(2, 1)), m.head_inputs(x2, torch.ones(2, 1))
    torch.testing.assert_close(acc_head(ins[0]), acc_head(ins2[0]))
    assert not torch.allclose(m.branches[1](ins[1]), m.branches[1](ins2[1]))


def test_loss_is_cross_entropy_and_absent_device_is_zeroed():
    m = HARNet(n_devices=2, window=40, n_classes=3)
    x = torch.randn(4, 2, 40, 6)
    mask = torch.tensor([[1.0, 0.0]] * 4)
    x2 = x.clone()
    x2[:, 1] = 123.0
    m.eval()
    torch.testing.assert_close(m(x, mask), m(x2, mask))
    lab = torch.tensor([0, 1, 2, 0])
    loss, parts = m.loss({"x": x, "mask": mask, "label": lab})
    torch.testing.assert_close(loss, torch.nn.functional.cross_entropy(m(x, mask), lab))


# ---- subject-independent splits -----------------------------------------------------------------

SUBJECT_IDS = {
    "uci-hapt": [f"user{i:02d}" for i in range(1, 31)],
    "motionsense": [f"sub{i:02d}" for i in range(1, 25)],
    "uji": [f"s{i:02d}" for i in range(1, 24)],
    "oxford": ["user1", "user2"],
}


@pytest.mark.parametrize("scheme", sorted(SUBJECT_IDS))
def test_split_schemes_partition_subjects(scheme):
    ids = SUBJECT_IDS[scheme]
    sides = {s: split_of(scheme, s) for s in ids}
    test = {s for s, v in sides.items() if v == "test"}
    train = {s for s, v in sides.items() if v == "train"}
    assert test and train and not (test & train) and test | train == set(ids)
    if scheme == "uci-hapt":
        assert sorted(int(s[4:]) for s in test) == [2, 4, 9, 10, 12, 13, 18, 20, 24]


def test_split_view_has_no_subject_on_both_sides(tmp_path):
    from wearnav.dataset import Dataset, DatasetWriter
    from wearnav.recording import Recording

    with DatasetWriter(tmp_path / "ds") as w:
        for user in (1, 2, 3, 4):
            for exp in range(2):
                w.add(
                    Recording(
                        name=f"e{user}{exp}",
                        devices={"phone": make_stream(100, 50.0)},
                        labels=[(0.0, 2.0, "activity", "WALKING")],
                        meta={"subject": f"user{user:02d}"},
                    )
                )
    ds = Dataset.open(tmp_path / "ds")
    tr, te = split_view(ds, "uci-hapt", "train"), split_view(ds, "uci-hapt", "test")
    assert set(tr.manifest["subject"]) == {"user01", "user03"}
    assert set(te.manifest["subject"]) == {"user02", "user04"}
    assert len(tr) + len(te) == len(ds)


# ---- end to end on real data --------------------------------------------------------------------


@pytest.mark.slow
def test_quick_bench_and_classify_end_to_end(shared_data, tmp_path, monkeypatch, capsys):
    """The first `bench har --quick` runs as a process of its own (its console and exit code); the
    resumed run and `classify` run in-process (what they print and write is under test, not the process)."""
    import json

    from conftest import run_cli

    env_py = {"PYTHONPATH": str(ROOT / "src")}
    import os

    # one thread: on a busy shared machine two spinning OpenMP threads cost more than they give
    env = {**os.environ, **env_py, "OMP_NUM_THREADS": "1"}
    out = tmp_path / "har"
    # a subset of the techniques keeps the test short; each kind (heads, expansion, noise,
    # moving average, batch augmentation) is represented
    cmd = [
        sys.executable,
        "-m",
        "wearnav",
        "bench",
        "har",
        "--quick",
        "--out",
        str(out),
        "--data",
        str(shared_data),
        "--techniques",
        "baseline,head2,head3,rot_all,noise,ma50,rot_random",
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    page = (out / "results.md").read_text()
    # quick results say what they are, on the page (title and note) and on the console
    assert "(--quick: pipeline check, not accuracy)" in page.splitlines()[0]
    assert "QUICK RUN (pipeline check, not accuracy)" in page
    assert "--quick: pipeline check, not accuracy" in r.stdout
    assert "beats majority class" in page  # a column: seeds that beat always answering the majority class
    assert "## uci-hapt" in page and "Fig. 12" in page
    doc = json.loads((out / "results.json").read_text())
    res = doc["datasets"]["uci-hapt"]
    assert set(res) == {"baseline", "head2", "head3", "rot_all", "noise", "ma50", "rot_random"}
    beats = res["baseline"]["beats_trivial"]
    assert len(beats) == 1 and isinstance(beats[0], bool)
    import re

    assert re.search(r"\|\s+" + ("1/1" if beats[0] else "NO 0/1") + r"\s+\|", page)
    assert "not applicable (no orientation)" in page  # UCI HAPT has no orientation: world frame not run
    for s in res.values():
        assert 0.0 <= s["accuracy_mean"] <= 1.0 and 0.0 <= s["f1_mean"] <= 1.0
        assert np.sum(s["confusion"]) == s["test_windows"] > 0
    for png in ("uci-hapt_improvement.png", "uci-hapt_confusion.png", "summary.png"):
        assert (out / png).stat().st_size > 1000
    # no subject on both sides of the real split
    from wearnav.dataset import Dataset

    ds = Dataset.open(out / "data" / "uci-hapt-quick")
    tr = set(split_view(ds, "uci-hapt", "train").manifest["subject"])
    te = set(split_view(ds, "uci-hapt", "test").manifest["subject"])
    assert tr and te and not (tr & te)
    base_run = next((out / "runs" / "uci-hapt").glob("baseline-*"))
    m = json.loads((base_run / "metrics.json").read_text())
    assert set(m["test_subjects"]) == te
    # a second invocation resumes: every run is complete and skipped
    code2, out2, _ = run_cli(monkeypatch, capsys, *cmd[3:])
    assert code2 == 0 and "done in" not in out2 and "skipped" in out2

    # wearnav classify on one (cropped) recording
    rec = ds.load(ds.names[0])
    from wearnav.recording import Recording

    s = rec.devices["phone"]
    keep = s.t < s.t[0] + 30.0
    from dataclasses import replace

    small = Recording(
        name="tiny",
        devices={"phone": replace(s, t=s.t[keep], acc=s.acc[keep], gyro=s.gyro[keep])},
        meta={"subject": "x"},
    )
    h5 = small.save(tmp_path / "tiny.h5")
    code3, out3, err3 = run_cli(monkeypatch, capsys, "classify", h5, "--model", base_run, "--out", tmp_path / "lab")
    assert code3 == 0, err3
    assert f"labels the model knows: {', '.join(m['classes'])}" in out3
    assert isinstance(m["beats_trivial"], bool) and 0 < m["trivial_accuracy"] < 1
    assert ("did not learn" in err3) is (not m["beats_trivial"])
    iv = pd.read_csv(tmp_path / "lab" / "tiny_intervals.csv")
    assert set(iv["label"]) <= set(m["classes"]) and iv["windows"].sum() == (30 * 50 - 128) // 64 + 1
    assert (iv["end_s"] > iv["start_s"]).all() and np.allclose(iv["start_s"].iloc[1:], iv["end_s"].iloc[:-1])
    assert (tmp_path / "lab" / "tiny_timeline.png").stat().st_size > 1000


def test_significance_is_welchs_t_test_over_seeds():
    """p in the HAR tables: Welch's t over per-seed accuracies. Well separated seeds give a small
    p, overlapping ones a large one, one seed says nothing; checked against the t statistic by hand."""
    from wearnav.stats import welch_p

    a, b = [0.80, 0.81, 0.82], [0.90, 0.91, 0.92]
    t = (np.mean(b) - np.mean(a)) / np.sqrt(np.var(a, ddof=1) / 3 + np.var(b, ddof=1) / 3)
    assert t == pytest.approx(12.25, abs=0.01)  # df = 4: p ≈ 2.6e-4
    assert welch_p(a, b) == pytest.approx(2.55e-4, rel=0.01)
    assert welch_p([0.80, 0.85, 0.90], [0.81, 0.86, 0.89]) > 0.05
    assert welch_p([0.8], b) is None
    assert welch_p([0.8, 0.8], [0.8, 0.8]) == 1.0 and welch_p([0.8, 0.8], [0.9, 0.9]) == 0.0


def _summary(acc_per_seed):
    acc = np.array(acc_per_seed)
    return {
        "accuracy_mean": acc.mean(),
        "accuracy_std": acc.std(ddof=1),
        "f1_mean": acc.mean(),
        "f1_std": acc.std(ddof=1),
        "seeds": acc.size,
        "accuracy_per_seed": list(acc_per_seed),
        "classes": ["a", "b"],
        "confusion": [[5, 1], [2, 4]],
        "train_wall_s": 1.0,
        "epochs": 1,
        "train_windows": 10,
        "test_windows": 12,
    }


def _first_table(page: str) -> list[list[str]]:
    """The cells of the first Markdown table of ``page``, row by row (header, rule, body)."""
    lines = page.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    end = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    return [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines[start:end]]


def test_significance_marks_follow_benjamini_hochberg_over_a_datasets_techniques(tmp_path):
    """Four techniques against the baseline: rotation x has raw p = 0.042 < 0.05 but its
    BH-adjusted p (rank 2 of 4: 0.042 · 4/2) is above 0.05, so it gets no †; additive noise
    (p = 2.6e-4) keeps its †. Table p and p_BH columns and results.json agree with scipy."""
    from scipy.stats import false_discovery_control, ttest_ind

    from wearnav.bench.har import write_report
    from wearnav.stats import bh_adjust

    base = [0.80, 0.81, 0.82]
    seeds = {
        "rot_x": [0.83, 0.84, 0.86],
        "rot_y": [0.79, 0.81, 0.83],
        "rot_z": [0.80, 0.82, 0.81],
        "noise": [0.90, 0.91, 0.92],
    }
    raw = {k: ttest_ind(v, base, equal_var=False).pvalue for k, v in seeds.items()}
    assert 0.04 < raw["rot_x"] < 0.05
    want = dict(zip(raw, false_discovery_control(list(raw.values()), method="bh")))
    assert want["rot_x"] > 0.05 and want["noise"] < 0.05
    got = bh_adjust({**raw, "head2": None})
    assert got["head2"] is None and all(got[k] == pytest.approx(want[k]) for k in raw)

    results = {"uci-hapt": {"baseline": _summary(base), **{k: _summary(v) for k, v in seeds.items()}}}
    page = write_report(results, tmp_path).read_text()
    head, _, *body = _first_table(page)
    row = {r[0]: dict(zip(head, r)) for r in body}
    assert "†" not in row["rotation x"]["Δ acc (points)"] and "†" in row["additive noise"]["Δ acc (points)"]
    assert float(row["rotation x"]["p"]) == pytest.approx(raw["rot_x"], rel=0.02)
    assert float(row["rotation x"]["p_BH"]) == pytest.approx(want["rot_x"], rel=0.02)
    assert row["baseline"]["p"] == row["baseline"]["p_BH"] == ""
    assert "Benjamini–Hochberg-adjusted p < 0.05" in page
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc["significance"]["uci-hapt"]["rot_x"]["p_bh"] == pytest.approx(want["rot_x"])
    summary = {r["technique"]: r for r in doc["summary"]}
    assert summary["rotation x"]["datasets improved"] == 1 and summary["rotation x"]["improved, p_BH < 0.05"] == 0
    assert summary["additive noise"]["improved, p_BH < 0.05"] == 1
    assert (tmp_path / "uci-hapt_improvement.png").stat().st_size > 1000
