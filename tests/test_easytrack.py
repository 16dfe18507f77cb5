"""EasyTrack (paper 004): phone labels, schedules and losses on hand-made tensors, resumable dual
training, and the quick benchmark end to end."""

import math
import re

import numpy as np
import pytest
import torch
from tests.conftest import run_cli

from wearnav import metrics
from wearnav.errors import ConfigError
from wearnav.fixlabels import (
    LabelConfig,
    Segments,
    fix_frame_yaw,
    label_recording,
    neighbour_correlation,
    segments_from_truth,
)
from wearnav.models.base import instance_velocity_loss
from wearnav.train import noisy
from wearnav.train.noisy import (
    NoisyConfig,
    cnal_labels,
    cnal_loss,
    coadapt_losses,
    fit_noisy,
    r_delta_update,
    r_select,
    r_tau,
    select_small_loss,
)

# ---- schedules (eqs. 14–16) ------------------------------------------------------------------------


def test_r_tau_follows_eq_15():
    assert r_tau(1, 10) == pytest.approx(1.0)  # g(η, 1) = log 1 / … = 0
    # at T_max, g = log(η(T_max − 1) + 1) / log(η T_max + 1) < 1, so R_τ stays above 1 − τ (as eq. 15 reads)
    assert r_tau(10, 10) == pytest.approx(1 - 0.8 * math.log(10) / math.log(11))
    assert r_tau(10_000, 10_000) == pytest.approx(0.2, abs=1e-4)
    T = 4
    assert r_tau(T, 10, tau=0.8, eta=1.0) == pytest.approx(1 - 0.8 * math.log(T) / math.log(11))
    assert r_tau(3, 10, tau=0.5, eta=2.0) == pytest.approx(1 - 0.5 * math.log(2 * 2 + 1) / math.log(21))
    vals = [r_tau(t, 50) for t in range(1, 51)]
    assert all(a > b for a, b in zip(vals, vals[1:]))  # strictly decreasing
    assert vals[4] < 1 - 0.8 * 4 / 49 - 0.2  # log schedule: far below a linear one early (memorisation effect)


def test_r_delta_is_a_moving_average_of_the_share_below_the_threshold():
    target = torch.zeros(4, 2)
    pred = torch.tensor([[0.1, 0.0], [0.0, 0.3], [0.2, 0.0], [0.3, 0.4]])  # errors 0.1, 0.3, 0.2, 0.5 m
    assert r_delta_update(0.0, pred, target, 0.24, 0.02) == pytest.approx(0.01)  # p_δ = 0.5
    assert r_delta_update(0.5, pred, target, 0.24, 0.02) == pytest.approx(0.5)
    assert r_delta_update(1.0, pred, target, 0.24, 0.1) == pytest.approx(0.95)
    r = 0.0
    for _ in range(2000):  # converges to p_δ
        r = r_delta_update(r, pred, target, 0.24, 0.02)
    assert r == pytest.approx(0.5, abs=1e-6)
    assert r_select(0.3, 0.6) == 0.6 and r_select(0.7, 0.6) == 0.7  # eq. 16


def test_r_delta_compares_delta_with_the_displacement_error_in_metres():
    """30 % of the instances 0.1 m off, 70 % 0.5 m off: R_δ → 0.3 with δ = 0.24 m. (Compared with
    the per-instance MSE in m², 0.005 and 0.125, every instance counted as clean: R_δ → 1.)"""
    rng = np.random.default_rng(3)
    err = np.r_[np.full(30, 0.1), np.full(70, 0.5)]
    ang = rng.uniform(0, 2 * np.pi, 100)
    target = torch.tensor(rng.normal(size=(100, 2)), dtype=torch.float32)
    pred = target + torch.tensor(np.c_[err * np.cos(ang), err * np.sin(ang)], dtype=torch.float32)
    assert noisy.instance_error(pred, target).numpy() == pytest.approx(err, abs=1e-6)
    r = 0.0
    for _ in range(1000):
        r = r_delta_update(r, pred, target, NoisyConfig().delta, NoisyConfig().beta)
    assert r == pytest.approx(0.3, abs=1e-6)


def test_small_loss_selection_and_weights():
    losses = torch.tensor([5.0, 1.0, 3.0, 2.0, 4.0])
    idx, w = select_small_loss(losses, 0.6)
    assert idx.tolist() == [1, 3, 2]
    assert w.tolist() == [1.0, 1.0, 1.0]  # 20 % of 3 selected rounds down to none
    idx, w = select_small_loss(losses, 1.0)
    assert idx.tolist() == [1, 3, 2, 4, 0]
    assert w.tolist() == pytest.approx([1, 1, 1, 1, 0.1])  # the last 20 % of the selected: 0.1
    ten = torch.arange(10, 0, -1).float()
    idx, w = select_small_loss(ten, 1.0)
    assert w.tolist() == pytest.approx([1] * 8 + [0.1, 0.1])
    assert select_small_loss(ten, 0.0)[0].numel() == 1  # at least one instance


def test_coadapt_each_model_learns_on_its_peers_selection():
    l1 = torch.tensor([0.1, 0.9, 0.5, 0.2, 0.8], requires_grad=True)
    l2 = torch.tensor([0.7, 0.1, 0.3, 0.9, 0.2], requires_grad=True)
    lp1, lp2, s1, s2 = coadapt_losses(l1, l2, 0.6, 0.2, 0.1)
    assert s1.tolist() == [0, 3, 2] and s2.tolist() == [1, 4, 2]
    # model 1 is trained on D_s2 = {1, 4, 2} with model 2's weights (all 1 here), sum / B (eq. 18)
    assert lp1.item() == pytest.approx((0.9 + 0.8 + 0.5) / 5)
    assert lp2.item() == pytest.approx((0.7 + 0.9 + 0.3) / 5)
    lp1.backward()
    assert l1.grad.tolist() == pytest.approx([0, 0.2, 0.2, 0, 0.2])  # only the peer's picks
    lp1, _, _, _ = coadapt_losses(l1.detach(), l2.detach(), 1.0, 0.2, 0.1)
    order = [1, 4, 2, 0, 3]  # ascending l2; the last (index 3) is down-weighted
    assert float(lp1) == pytest.approx((0.9 + 0.8 + 0.5 + 0.1 + 0.1 * 0.2) / 5)
    assert order[-1] == 3


# ---- CNAL (eqs. 12–13) --------------------------------------------------------------------------


def test_cnal_corrections_telescope_along_a_trajectory():
    rng = np.random.default_rng(0)
    p_true = np.cumsum(rng.normal(size=(7, 2)), axis=0)
    p_fix = p_true + rng.normal(scale=0.5, size=p_true.shape)  # noisy fixes at the nodes
    node0, node1 = torch.arange(6), torch.arange(1, 7)
    label = torch.tensor(p_fix[1:] - p_fix[:-1])
    corr = torch.tensor(rng.normal(size=(7, 2)))
    fixed = cnal_labels(label, corr, node0, node1)
    # along the chain the corrections telescope: Σ corrected = Σ raw + c_last − c_first
    assert fixed.sum(0).numpy() == pytest.approx((label.sum(0) + corr[6] - corr[0]).numpy())
    # correcting each fix by its error gives back the true displacements exactly (eq. 6)
    exact = cnal_labels(label, torch.tensor(p_true - p_fix), node0, node1)
    assert exact.numpy() == pytest.approx(p_true[1:] - p_true[:-1])


def test_cnal_loss_eq_13_by_hand():
    label = torch.tensor([[1.0, 0.0], [0.0, 1.0]])
    corr = torch.tensor([[0.0, 0.0], [0.3, 0.4], [0.3, 0.4]])
    pred = torch.tensor([[1.3, 0.4], [0.0, 0.0]])
    node0, node1 = torch.tensor([0, 1]), torch.tensor([1, 2])
    # segment 0: corrected (1.3, 0.4) = pred → 0; |Δc| = 0.5. segment 1: corrected (0, 1), Δc = 0
    want = ((0 + 0) + (0 + 1)) / 4 + 1.0 * (0.5 + 0.0) / 2
    assert float(cnal_loss(label, corr, node0, node1, pred, gamma=1.0)) == pytest.approx(want)
    assert instance_velocity_loss(pred, label).tolist() == pytest.approx([(0.09 + 0.16) / 2, 0.5])


def test_polar_loss_ranks_the_noisy_labels_last_and_is_checked():
    """With ``loss="polar"`` CoAdapt ranks instances by their log-length and direction error: labels
    half as long or 60° off come after the clean ones, as they do by the MSE."""
    pred = torch.tensor([[1.0, 0.0]] * 4)
    label = torch.tensor([[1.05, 0.02], [0.5, 0.0], [0.98, -0.03], [0.5, 0.866]])
    for kind in ("mse", "polar"):
        idx, _ = select_small_loss(instance_velocity_loss(pred, label, kind), 0.5)
        assert sorted(idx.tolist()) == [0, 2], kind
    assert NoisyConfig(loss="polar").loss == "polar"
    with pytest.raises(ConfigError, match="unknown loss"):
        NoisyConfig(loss="l1")


def test_the_bench_gives_every_run_its_loss(tmp_path):
    from wearnav.bench.easytrack import BenchConfig, _todo

    lc = LabelConfig()
    mse = _todo(tmp_path, BenchConfig(levels=("L1",), methods=("easytrack", "basemodel")), 1, lc)
    polar = _todo(tmp_path, BenchConfig(levels=("L1",), methods=("easytrack", "basemodel"), loss="polar"), 1, lc)
    assert [c.loss for c, *_ in mse] == ["mse", "mse"] and [c.loss for c, *_ in polar] == ["polar", "polar"]
    assert {f for _, _, f, _ in mse}.isdisjoint({f for _, _, f, _ in polar})  # their own run folders


def _chain_with_known_noise(n=2000, seed=0):
    """A chain of n consecutive segments whose nodes carry an AR(1) position error (ρ = 0.5,
    stationary σ 0.1835 m per axis, so the label noise |e_i+1 − e_i| is Rayleigh with median
    ≈ 21.6 cm, DS_L1's) and the true displacements (walking 1.2 m/s, turning)."""
    rng = np.random.default_rng(seed)
    sigma, rho = 0.1835, 0.5
    e = np.zeros((n + 1, 2))
    e[0] = rng.normal(scale=sigma, size=2)
    for i in range(1, n + 1):
        e[i] = rho * e[i - 1] + rng.normal(scale=sigma * math.sqrt(1 - rho**2), size=2)
    heading = np.cumsum(rng.normal(scale=0.2, size=n))
    d = 1.2 * np.c_[np.cos(heading), np.sin(heading)]
    label = d + e[1:] - e[:-1]
    return (
        torch.tensor(label, dtype=torch.float32),
        torch.tensor(d, dtype=torch.float32),
        torch.arange(n),
        torch.arange(1, n + 1),
    )


def _fit_cnal(label, truth, node0, node1, gamma, steps=3000):
    """Only the corrections, Adam at the paper's CNAL rate 2e-4 (betas as NoisyConfig), full batch,
    a perfect predictor d̂ = d. Returns the corrected labels' median noise (m)."""
    cfg = NoisyConfig()
    corr = torch.nn.Parameter(torch.zeros(len(label) + 1, 2))
    opt = torch.optim.Adam([corr], lr=cfg.lr_cnal, betas=cfg.betas)
    for _ in range(steps):
        opt.zero_grad()
        cnal_loss(label, corr, node0, node1, truth, gamma).backward()
        opt.step()
    fixed = cnal_labels(label, corr.detach(), node0, node1)
    return float((fixed - truth).norm(dim=1).median())


def test_cnal_corrections_move_with_the_default_gamma():
    """γ = 1 in the paper's centimetres is 0.01 in metres; with γ = 1 in metres the L1 term's pull
    (1 m per m) outweighs the MSE's below ~1 m of error and the corrections never move."""
    label, truth, node0, node1 = _chain_with_known_noise()
    raw = float((label - truth).norm(dim=1).median())
    assert raw == pytest.approx(0.216, abs=0.015)
    fixed = _fit_cnal(label, truth, node0, node1, NoisyConfig().gamma)
    assert fixed < 0.75 * raw
    assert _fit_cnal(label, truth, node0, node1, 1.0) == pytest.approx(raw, rel=0.01)  # γ = 1 m⁻¹: stuck


def test_aux_corrections_move_to_the_regularised_optimum():
    """AUX: MSE(d̃_i + c_i, d̂) + γ_aux·mean‖c_i‖² is minimal at c_i = (d̂ − d̃)/(1 + 2γ_aux)."""
    label = torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.0, -1.2], [0.8, 0.3]])
    pred = label + torch.tensor([[0.3, -0.1], [-0.2, 0.25], [0.05, 0.4], [-0.5, 0.0]])
    g = NoisyConfig().gamma_aux
    corr = torch.nn.Parameter(torch.zeros(4, 2))
    opt = torch.optim.Adam([corr], lr=1e-3, betas=NoisyConfig().betas)
    for _ in range(3000):
        opt.zero_grad()
        noisy.aux_loss(label, corr, pred, g).backward()
        opt.step()
    want = (pred - label) / (1 + 2 * g)
    assert corr.detach().numpy() == pytest.approx(want.numpy(), abs=2e-3)
    assert float(corr.detach().norm(dim=1).min()) > 0.03


# ---- phone labels (eq. 4) and their noise (eqs. 5–7) ----------------------------------------------


@pytest.fixture(scope="module")
def walk():
    from wearnav.simulate.config import WalkConfig
    from wearnav.simulate.walk import simulate_walk

    cfg = WalkConfig(
        name="w", mode="STW", placement="HD", scene="large", duration_s=90, noise_level="L2", devices=("phone",)
    )
    return simulate_walk(cfg, 3).recording


def test_phone_labels_are_fix_displacements_and_their_noise_is_the_metric(walk):
    seg = label_recording(walk, LabelConfig())
    assert len(seg) > 60 and seg.x.shape[1:] == (25, 6)
    f = walk.fixes
    i0 = np.searchsorted(f.t, seg.t0)
    i1 = np.searchsorted(f.t, seg.t1)
    assert seg.label == pytest.approx(f.pos[i1, :2] - f.pos[i0, :2])  # eq. 4
    assert seg.node_pos[seg.node1] - seg.node_pos[seg.node0] == pytest.approx(seg.label)
    assert np.all(np.abs(seg.t1 - seg.t0 - 1.0) <= 0.25)
    # chained: consecutive segments share a node (so CNAL corrections telescope)
    assert np.mean(seg.node1[:-1] == seg.node0[1:]) > 0.9
    # |d − d̃| equals metrics.label_noise over the same fix pairs (eqs. 5–6)
    ref = metrics.label_noise(f.t, f.pos, walk.truth.t, walk.truth.pos)
    pair = {(a, b): k for k, (a, b) in enumerate(zip(range(len(f.t) - 1), range(1, len(f.t))))}
    mine = np.linalg.norm(seg.noise(), axis=1)
    got = [(mine[k], ref[pair[(a, b)]]) for k, (a, b) in enumerate(zip(i0, i1)) if (a, b) in pair]
    assert len(got) > 60
    assert np.array([g[0] for g in got]) == pytest.approx(np.array([g[1] for g in got]))
    nc = neighbour_correlation(seg)
    assert nc["pairs"] > 50 and -1 <= nc["x"] <= 1


def test_white_fix_errors_give_minus_half_neighbour_correlation():
    """eq. 7: d_e,i and d_e,i+1 share P_e,i+1 with opposite signs."""
    rng = np.random.default_rng(1)
    n = 4000
    pe = rng.normal(size=(n + 1, 2))
    truth = np.zeros((n, 2))
    seg = Segments(
        x=np.zeros((n, 2, 6), np.float32),
        label=truth - (pe[1:] - pe[:-1]),
        truth=truth,
        traj=np.zeros(n, int),
        node0=np.arange(n),
        node1=np.arange(1, n + 1),
        t0=np.arange(n) * 1.0,
        t1=np.arange(1, n + 1) * 1.0,
        node_pos=pe,
        node_traj=np.zeros(n + 1, int),
        node_t=np.arange(n + 1) * 1.0,
        names=["a"],
    )
    nc = neighbour_correlation(seg)
    assert nc["x"] == pytest.approx(-0.5, abs=0.05) and nc["y"] == pytest.approx(-0.5, abs=0.05)


def test_fix_frame_matches_the_truth_frame_without_reading_the_truth(walk):
    from wearnav.preprocess import PreprocessConfig, align

    seq = align(walk, LabelConfig().preprocess())
    yaw, info = fix_frame_yaw(seq.imu[0], seq.t, seq.rate, walk.fixes.t, walk.fixes.pos[:, :2])
    truth_frame = align(walk, PreprocessConfig(devices=("phone",)))  # the estimator that reads the truth
    want = -np.deg2rad(truth_frame.meta["frame"]["truth"]["yaw_deg"])
    err = np.rad2deg(np.angle(np.exp(1j * (np.median(yaw) - want))))
    assert info["windows"] > 30 and abs(err) < 10


def test_truth_segments_integrate_the_trajectory(walk):
    seg = segments_from_truth(walk, LabelConfig())
    end = seg.start_pos[0] + seg.label.sum(0)
    assert end == pytest.approx(seg.node_pos[-1])
    assert np.array_equal(seg.node1[:-1], seg.node0[1:])


# ---- training ---------------------------------------------------------------------------------------


def test_dual_training_resumes_to_the_same_weights(walk, tmp_path):
    seg = label_recording(walk, LabelConfig())
    cfg = NoisyConfig(method="easytrack", ae_epochs=1, pre_epochs=1, joint_epochs=2, batch=32)
    fit_noisy(cfg, seg, tmp_path / "a")
    fit_noisy(cfg, seg, tmp_path / "b", stop_after=2)  # "killed" after the pre-training epoch
    rec = fit_noisy(cfg, seg, tmp_path / "b")
    a = torch.load(tmp_path / "a" / noisy.STATE, weights_only=False)
    b = torch.load(tmp_path / "b" / noisy.STATE, weights_only=False)
    for sa, sb in zip(a["models"], b["models"]):
        for k in sa:
            assert torch.equal(sa[k], sb[k]), k
    assert torch.equal(a["corr"], b["corr"]) and a["corr"].abs().sum() > 0  # CNAL learned something
    j = [h for h in rec["history"] if h["phase"] == "joint"]
    assert [h["r_tau"] for h in j] == pytest.approx([1.0, 1 - 0.8 * math.log(2) / math.log(3)])
    assert 0 < j[-1]["r_delta"] < 1 and j[-1]["selected_noise_cm"] > 0


def test_registry_has_ionet_and_basemodel():
    from wearnav.models.registry import build, get

    for name in ("ionet", "easytrack-base"):
        assert get(name).task == "odometry"
        m = build(name, n_devices=2, window=25)
        x = torch.randn(3, 2, 25, 6)
        assert m(x, torch.tensor([[1.0, 0], [0, 1], [1, 1]])).shape == (3, 2)


@pytest.mark.slow  # ~16 s on a busy 2-core machine: six methods trained
def test_quick_bench_end_to_end_and_label_cli(monkeypatch, capsys, tmp_path):
    out = tmp_path / "et"
    code, so, se = run_cli(monkeypatch, capsys, "bench", "easytrack", "--out", str(out), "--quick")
    assert code == 0, se
    page = (out / "results.md").read_text()
    for m in ("easytrack", "easytrack-amended", "coteaching", "aux", "basemodel", "basemodel-gt"):
        assert f"| {m} " in page
    assert "Issue 59's bar for the amended CoAdapt" in page and "| L1      | easytrack-amended |" in page
    assert "Length ratio (held-out" in page
    assert "Reduced from the paper" in page and (out / "ade_by_level.png").is_file()
    assert "(--quick: pipeline check, not accuracy)" in page.splitlines()[0]  # the title says so
    assert "Standing still (zero displacement per segment) scores" in page  # the trivial baseline beside
    assert "--quick: pipeline check, not accuracy" in so.splitlines()[0]  # and the first console line
    code, so, se = run_cli(monkeypatch, capsys, "bench", "easytrack", "--out", str(out), "--quick")
    assert code == 0 and "simulating" not in so  # data and runs are reused
    ds = next(p for p in (out / "data").iterdir() if p.is_dir() and "test" not in p.name)
    code, so, se = run_cli(
        monkeypatch, capsys, "label-from-fixes", str(ds), "--out", str(tmp_path / "lab"), "--segment", "1"
    )
    assert code == 0, se
    assert (tmp_path / "lab" / "segments.npz").is_file() and "median label noise" in so


def test_label_noise_correlation_metric_by_hand():
    e = np.array([[1.0, 2.0], [-1.0, -2.0], [1.0, 2.0], [-1.0, -2.0], [np.nan, 0.0]])
    rx, ry = metrics.label_noise_correlation(e, [0, 1, 2, 3])  # the pair (3, 4) has a NaN: skipped
    assert rx == pytest.approx(-1.0) and ry == pytest.approx(-1.0)
    assert np.isnan(metrics.label_noise_correlation(e, [0])[0])


def test_real_part_trains_on_fixes_and_scores_at_sparse_points(tmp_path):
    """The real-data path on simulated walks whose truth is cut to sparse waypoints (as IPIN's
    surveyed points): the held-out split is scored, GNSS and PDR beside the learned methods."""
    import dataclasses

    from wearnav.bench.easytrack import BenchConfig, real_part
    from wearnav.dataset import DatasetWriter
    from wearnav.recording import Trajectory
    from wearnav.simulate.presets import plan_phone_only
    from wearnav.simulate.walk import simulate_walk

    with DatasetWriter(tmp_path / "real") as w:
        for k, item in enumerate(plan_phone_only("L2", 0.0, 5, (40.0, 50.0), n=3)):
            rec = simulate_walk(item.config, item.seed).recording
            keep = np.arange(0, len(rec.truth), 1000)  # every 10 s
            rec = dataclasses.replace(rec, truth=Trajectory(rec.truth.t[keep], rec.truth.pos[keep]))
            w.add(rec, split="test" if k == 0 else "train")
    doc = real_part(tmp_path / "real", tmp_path / "out", BenchConfig.quick(), LabelConfig(), None, 1)
    assert len(doc["test_routes"]) == 1 and len(doc["train_routes"]) == 2
    for proto in ("user", "known"):
        for m in ("easytrack", "basemodel", "pdr", "gnss"):
            assert doc["summary"][proto][m]["points"] >= 3 and doc["summary"][proto][m]["median_m"] >= 0
    # the user protocol starts from the phone's own fix, not the surveyed point: different errors
    assert doc["summary"]["user"]["pdr"]["mean_m"] != doc["summary"]["known"]["pdr"]["mean_m"]
    assert doc["summary"]["user"]["gnss"] == doc["summary"]["known"]["gnss"]


def test_ipin_held_out_routes_are_real_odometrys_test_trials():
    from wearnav.bench.easytrack import IPIN_TEST_ROUTES
    from wearnav.bench.real_sites import SITE_DEFAULTS

    names = [
        f"IPIN2023_T3_TrainingTrial{t:02d}_repetition{r:02d}"
        for t in (1, 2, 3, 4, 5, 21, 22, 23, 24, 25, 51, 52)
        for r in (1, 2)
    ]
    held = sorted({int(n[25:27]) for n in names if re.search(IPIN_TEST_ROUTES, n)})
    assert held == [int(t) for t in SITE_DEFAULTS["ipin2023"][1]] == [4, 24, 52]


def test_jump_filter_counts_and_reports_what_it_drops(walk):
    """A gross fix jump (25 m and back) makes two labels no walker makes: the filter drops exactly
    those, the segments count them per recording and noise_summary reports count and share."""
    import dataclasses

    from wearnav.fixlabels import noise_summary

    all_kept = label_recording(walk, LabelConfig(max_speed=None))
    f = walk.fixes
    k = int(np.searchsorted(f.t, all_kept.t0[len(all_kept) // 2]))
    pos = f.pos.copy()
    pos[k, 0] += 25.0
    jumped = dataclasses.replace(walk, fixes=dataclasses.replace(f, pos=pos))
    n_all = len(label_recording(jumped, LabelConfig(max_speed=None)))
    with pytest.warns(UserWarning, match="dropped 2 of"):
        seg = label_recording(jumped, LabelConfig())
    assert seg.dropped.tolist() == [n_all - len(seg)] == [2]
    s = noise_summary(seg)
    assert s["dropped_labels"] == 2 and s["dropped_share"] == pytest.approx(2 / n_all, abs=1e-5)
    both = Segments.concat([seg, seg])
    assert both.dropped.tolist() == [2, 2] and noise_summary(both)["dropped_labels"] == 4


def test_overlapping_segments_start_every_stride_on_interpolated_fixes(walk):
    """stride_s 0.2: five segment starts per fix spacing; every label is the difference of the
    fixes linearly interpolated at its two ends; back-to-back segments (stride = segment) are the
    fix pairs themselves, so the default is unchanged."""
    plain = label_recording(walk, LabelConfig(max_speed=None))
    over = label_recording(walk, LabelConfig(max_speed=None, stride_s=0.2))
    f = walk.fixes
    assert np.isin(plain.t0, f.t).all() and np.isin(plain.t1, f.t).all()  # nodes are fixes
    assert 4.5 * len(plain) < len(over) <= 5 * len(plain) + 5
    np.testing.assert_allclose(np.diff(np.unique(over.node_t))[:20], 0.2, atol=0.02)
    interp = np.stack([np.interp(over.node_t, f.t, f.pos[:, k]) for k in range(2)], axis=1)
    np.testing.assert_allclose(over.node_pos, interp, atol=1e-9)
    np.testing.assert_allclose(over.label, over.node_pos[over.node1] - over.node_pos[over.node0], atol=1e-9)
    np.testing.assert_allclose(over.t1 - over.t0, 1.0, atol=0.25)
    # the IMU of a segment starting between two fixes is the samples from its own start time
    k = int(np.flatnonzero(~np.isin(over.t0, f.t))[0])
    assert not np.allclose(over.x[k], over.x[k - 1])
    # truth between the same two times, so the label noise statistics stay meaningful
    assert np.isfinite(over.truth).all()
    assert (
        abs(np.median(np.linalg.norm(over.noise(), axis=1)) - np.median(np.linalg.norm(plain.noise(), axis=1))) < 0.08
    )
    with pytest.raises(ConfigError):
        LabelConfig(stride_s=0.3)


def test_base_study_splits_a_walks_error_into_speed_and_heading():
    """per_walk on hand-made predictions: half the true displacement turned by 10° is a speed ratio
    of 0.5 and a heading error of 10° on every walk."""
    from wearnav.bench.easytrack_base import per_walk

    rng = np.random.default_rng(0)
    truth = rng.normal(0, 1, (40, 2)) + np.array([1.0, 0.0])
    a = np.radians(10.0)
    pred = 0.5 * truth @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    seg = Segments(
        x=np.zeros((40, 25, 6), np.float32),
        label=truth,
        truth=truth,
        traj=np.repeat([0, 1], 20),
        node0=np.arange(40),
        node1=np.arange(1, 41),
        t0=np.arange(40.0),
        t1=np.arange(1.0, 41.0),
        node_pos=np.zeros((41, 2)),
        node_traj=np.zeros(41, np.int64),
        node_t=np.arange(41.0),
        names=["a", "b"],
    )
    pw = per_walk(pred, seg)
    np.testing.assert_allclose(pw["speed ratio"], 0.5)
    np.testing.assert_allclose(pw["heading error (°, median)"], 10.0, atol=1e-9)
    assert (pw["ADE (cm)"] > 0).all()


@pytest.mark.slow
def test_bench_easytrack_base_writes_one_row_per_variant(tmp_path, monkeypatch, capsys):
    code, out, err = run_cli(
        monkeypatch, capsys, "bench", "easytrack-base", "--out", tmp_path / "b", "--km", "0.3", "--joint-epochs", "1"
    )
    assert code == 0, err
    page = (tmp_path / "b" / "results.md").read_text()
    for name in (
        "paper input, 30 % of the walking",
        "| paper input ",
        "+ yaw augmentation",
        "+ overlapping segments (0.2 s)",
        "diagnostic: truth frame",
    ):
        assert name in page
    assert "Per held-out walk" in page and "speed ratio" in page
