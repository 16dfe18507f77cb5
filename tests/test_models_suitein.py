"""Suite-IN++ / Suite-IN (paper 000, eqs. 1–25): shapes, budget, masking, each loss against a hand
computation, ablation switches, a learning check, and the efficiency measurement."""

import math

import pytest
import torch
from torch import nn
from torch.nn import functional as F

from wearnav.errors import ConfigError
from wearnav.models import registry
from wearnav.models.base import OdometryModel
from wearnav.models.suitein import (
    ABLATIONS,
    MaskedBatchNorm,
    _MaskedBatchNormFn,
    contrastive_loss,
    fusion_weights,
    orthogonality_loss,
)

# Small widths keep the tests fast; the paper-sized model is built where its size matters.
TINY = dict(widths=(8, 8, 8, 12, 12, 12), gru_hidden=16, loc_dim=16, loc_hidden=16)

# (phone, watch, earbuds)
MASKS = {
    "all three": [1, 1, 1],
    "watch + earbuds": [0, 1, 1],
    "phone + earbuds": [1, 0, 1],
    "phone only": [1, 0, 0],
    "earbuds only": [0, 0, 1],
}


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """These tiny models only wait on each other's threads on a shared 2-core machine."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def tiny(name="suitein++", **kw):
    torch.manual_seed(0)
    return registry.build(name, **{**TINY, **kw})


def batch(B=6, seed=1, mask=None):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(B, 3, 100, 6, generator=g)
    m = (
        torch.tensor(mask, dtype=torch.float32).expand(B, 3).clone()
        if mask is not None
        else torch.tensor([MASKS[k] for k in MASKS] * B, dtype=torch.float32)[:B]
    )
    return {"x": x * m[:, :, None, None], "mask": m, "vel": torch.randn(B, 2, generator=g)}


# --- registry, shapes, budget -----------------------------------------------------------------


def test_registered_with_paper_defaults():
    names = {s.name for s in registry.available("odometry")}
    assert {"suitein++", "suitein", *(f"suitein++-abl{n}" for n in range(1, 6))} <= names
    assert registry.get("suitein++").layout == "multi"
    m = registry.build("suitein++")
    assert (m.default_lr, m.default_batch, m.default_window, m.default_rate_hz) == (1e-4, 128, 100, 25.0)
    c = m.cfg
    assert (c.lambda_a, c.lambda_b, c.lambda_c) == (9.0, 0.01, 10.0)
    assert (c.w_vel, c.w_vel_glb, c.w_vel_loc, c.w_con, c.w_orth) == (1.0, 0.1, 1.0, 0.2, 0.05)
    assert c.kernels == (3, 2, 2, 2, 2, 2) and c.dropout == 0.2


def test_bad_hyper_parameters_are_config_errors():
    with pytest.raises(ConfigError, match="suitein"):
        registry.build("suitein++", no_such_option=3)
    with pytest.raises(ConfigError, match="too short"):
        registry.build("suitein++", window=10)
    with pytest.raises(ConfigError, match=r"expected x"):
        tiny()(torch.zeros(2, 2, 100, 6), torch.ones(2, 2))


@pytest.mark.parametrize("name", ["suitein++", "suitein", "suitein++-abl1", "suitein++-abl4"])
def test_shapes(name):
    m = tiny(name)
    b = batch()
    for mode in (m.train, m.eval):
        mode()
        assert m(b["x"], b["mask"]).shape == (6, 2)
    m.train()
    total, parts = m.loss(b)
    assert total.ndim == 0 and torch.isfinite(total)


def test_other_device_counts_and_window():
    m = registry.build("suitein++", n_devices=2, window=50)
    x = torch.randn(4, 2, 50, 6)
    assert m(x, torch.ones(4, 2)).shape == (4, 2)


# Parameters and MACs against the paper's Table VI: tests/test_models_size.py.


# --- flexible device number --------------------------------------------------------------------


@pytest.mark.parametrize("name", ["suitein++", "suitein"])
@pytest.mark.parametrize("which", list(MASKS))
def test_absent_device_input_changes_nothing(name, which):
    """Changing an absent device's input changes no output, loss part or gradient of any sample,
    in training (batch statistics) and in inference."""
    m = tiny(name, dropout=0.0)
    b = batch(mask=MASKS[which])
    b["mask"][0] = 1.0  # one full sample beside the others
    b2 = {**b, "x": b["x"] + 5.0 * (1 - b["mask"])[:, :, None, None] * torch.randn_like(b["x"])}
    for train in (True, False):
        m.train(train)
        state = {k: v.clone() for k, v in m.state_dict().items()}
        out1 = m.loss(b)
        m.zero_grad()
        out1[0].backward()
        g1 = [p.grad.clone() for p in m.parameters() if p.grad is not None]
        m.load_state_dict(state)  # undo the running-statistics update
        out2 = m.loss(b2)
        m.zero_grad()
        out2[0].backward()
        g2 = [p.grad.clone() for p in m.parameters() if p.grad is not None]
        m.load_state_dict(state)
        for k in out1[1]:
            assert torch.isfinite(out1[1][k]) and torch.allclose(out1[1][k], out2[1][k], atol=1e-6), k
        assert all(torch.isfinite(a).all() and torch.allclose(a, c, atol=1e-6) for a, c in zip(g1, g2))
        with torch.no_grad():
            assert torch.allclose(m(b["x"], b["mask"]), m(b2["x"], b2["mask"]), atol=1e-6)
            m.load_state_dict(state)


def test_single_device_batch_has_zero_pair_losses_and_finite_gradients():
    m = tiny()
    b = batch(mask=[0, 1, 0])
    total, parts = m.loss(b)
    assert parts["con"].item() == 0.0
    # Only the watch's own global-vs-local term of eq. 5 remains.
    assert torch.isfinite(parts["orth"])
    total.backward()
    assert all(torch.isfinite(p.grad).all() for p in m.parameters() if p.grad is not None)


def test_batch_without_any_phone_trains():
    """A device absent from the whole batch: its batch statistics are empty, nothing blows up."""
    m = tiny(dropout=0.0)
    b = batch(mask=[0, 1, 1])
    total, parts = m.loss(b)
    total.backward()
    assert all(torch.isfinite(v) for v in parts.values())
    assert all(torch.isfinite(p.grad).all() for p in m.parameters() if p.grad is not None)
    with torch.no_grad():
        h_glb, h_loc = m.features(b["x"], b["mask"])
    assert h_glb.abs().max() < 1e3 and h_loc.abs().max() < 1e3


def test_fusion_weights_of_a_sample_without_devices_are_zero():
    alpha = fusion_weights(torch.randn(2, 3), torch.tensor([[0.0, 0, 0], [1, 1, 0]]), 9, 0.01, 10)
    assert torch.equal(alpha[0], torch.zeros(3)) and alpha[1, 2] == 0
    assert alpha[1].sum().item() == pytest.approx(1.0)


# --- each loss part by hand --------------------------------------------------------------------


def _cos(a, b):
    return sum(x * y for x, y in zip(a, b)) / math.sqrt(sum(x * x for x in a) * sum(y * y for y in b))


G2 = [[1.0, 0.0], [1.0, 1.0]]  # global features of devices 1, 2
L2 = [[0.0, 1.0], [-1.0, 2.0]]  # local features


def test_infonce_two_devices_by_hand():
    """Eqs. 3–4, J = 2: ordered pairs (1,2) and (2,1) share one term;
    negatives = Σ_j exp(⟨g_j, l_j⟩/τ) + Σ_{i≠j} exp(⟨l_i, l_j⟩/τ) (two ordered pairs)."""
    tau = 0.5
    pos = math.exp(_cos(G2[0], G2[1]) / tau)
    neg = (
        math.exp(_cos(G2[0], L2[0]) / tau) + math.exp(_cos(G2[1], L2[1]) / tau) + 2 * math.exp(_cos(L2[0], L2[1]) / tau)
    )
    expected = -2 * math.log(pos / (pos + neg))
    got = contrastive_loss(torch.tensor([G2]), torch.tensor([L2]), torch.ones(1, 2), tau)
    assert got.item() == pytest.approx(expected, rel=1e-5)
    # A third, absent device with arbitrary features changes nothing.
    g3 = torch.tensor([G2 + [[3.0, -1.0]]])
    l3 = torch.tensor([L2 + [[-2.0, 5.0]]])
    got3 = contrastive_loss(g3, l3, torch.tensor([[1.0, 1.0, 0.0]]), tau)
    assert got3.item() == pytest.approx(expected, rel=1e-5)


def test_infonce_three_devices_by_hand():
    tau = 0.1
    g = [[1.0, 0.2, 0.0], [0.5, 1.0, 0.1], [0.0, 0.3, 1.0]]
    l = [[0.0, 1.0, 1.0], [1.0, -1.0, 0.0], [0.3, 0.3, -1.0]]
    neg = sum(math.exp(_cos(g[j], l[j]) / tau) for j in range(3)) + sum(
        math.exp(_cos(l[i], l[j]) / tau) for i in range(3) for j in range(3) if i != j
    )
    expected = -sum(
        math.log(math.exp(_cos(g[i], g[j]) / tau) / (math.exp(_cos(g[i], g[j]) / tau) + neg))
        for i in range(3)
        for j in range(3)
        if i != j
    )
    got = contrastive_loss(torch.tensor([g]), torch.tensor([l]), torch.ones(1, 3), tau)
    assert got.item() == pytest.approx(expected, rel=1e-5)


def test_orthogonality_by_hand():
    """Eq. 5 as a cosine embedding loss (target −1, margin 0): Σ_{i≠j} max(0, ⟨l_i, l_j⟩) +
    Σ_j max(0, ⟨g_j, l_j⟩)."""
    expected = 2 * max(0.0, _cos(L2[0], L2[1])) + max(0.0, _cos(G2[0], L2[0])) + max(0.0, _cos(G2[1], L2[1]))
    got = orthogonality_loss(torch.tensor([G2]), torch.tensor([L2]), torch.ones(1, 2))
    assert got.item() == pytest.approx(expected, rel=1e-6)
    # Agrees with PyTorch's CosineEmbeddingLoss (target −1) summed over the same pairs.
    cel = nn.CosineEmbeddingLoss(reduction="sum")
    a = torch.tensor([L2[0], L2[1], G2[0], G2[1]])
    b = torch.tensor([L2[1], L2[0], L2[0], L2[1]])
    assert got.item() == pytest.approx(cel(a, b, -torch.ones(4)).item(), rel=1e-6)


def test_fusion_weights_by_hand():
    """Eqs. 11–12: α̃_j = λa / (1 + exp(−e_j/λb)) + λc, normalised over present devices."""
    e = [0.004, -0.01, 0.03]
    mask = [1.0, 0.0, 1.0]
    tilde = [9 / (1 + math.exp(-v / 0.01)) + 10 for v in e]
    expected = [tilde[0] / (tilde[0] + tilde[2]), 0.0, tilde[2] / (tilde[0] + tilde[2])]
    got = fusion_weights(torch.tensor([e]), torch.tensor([mask]), 9.0, 0.01, 10.0)
    assert got[0].tolist() == pytest.approx(expected, rel=1e-6)
    mean = fusion_weights(torch.tensor([e]), torch.tensor([mask]), 9.0, 0.01, 10.0, weighted=False)
    assert mean[0].tolist() == pytest.approx([0.5, 0.0, 0.5])


def test_quality_score_is_eq_10():
    """e_j = (w_glb·u_j + b_glb) / l_glb with u_j the time-pooled global features (eq. 9)."""
    m = tiny().eval()
    b = batch(mask=[1, 1, 0])
    with torch.no_grad():
        h_glb, _ = m.features(b["x"], b["mask"])  # (B, T', D, C)
        Bn, T, D, C = h_glb.shape
        p, steps = m.cfg.glb_pool, T // m.cfg.glb_pool
        u = h_glb[:, : steps * p].reshape(Bn, steps, p, D, C).mean(2).permute(0, 2, 1, 3).reshape(Bn, D, -1)
        e = (u @ m.fusion.quality.weight[0] + m.fusion.quality.bias) / u.shape[-1]
        tilde = 9 * torch.sigmoid(e / 0.01) + 10
        expected = tilde * b["mask"] / (tilde * b["mask"]).sum(1, keepdim=True)
        assert torch.allclose(m.parts(b["x"], b["mask"])["alpha"], expected, atol=1e-6)


def test_velocity_losses_by_hand():
    """Eqs. 22, 23, 25: L_vel = MSE(v, v_true), L_vel^loc = MSE(v_loc, v_true − v_glb)."""
    m = tiny().eval()
    b = batch()
    total, parts = m.loss(b)
    with torch.no_grad():
        p = m.parts(b["x"], b["mask"])
    assert parts["vel"].item() == pytest.approx(((p["v"] - b["vel"]) ** 2).mean().item(), rel=1e-5)
    assert parts["vel_glb"].item() == pytest.approx(((p["v_glb"] - b["vel"]) ** 2).mean().item(), rel=1e-5)
    res = b["vel"] - p["v_glb"]
    assert parts["vel_loc"].item() == pytest.approx(((p["v_loc"] - res) ** 2).mean().item(), rel=1e-5)
    expected = parts["vel"] + 0.1 * parts["vel_glb"] + parts["vel_loc"] + 0.2 * parts["con"] + 0.05 * parts["orth"]
    assert total.item() == pytest.approx(expected.item(), rel=1e-6)
    # the trainer's aux_scale weighs the contrastive and orthogonality terms only
    m.aux_scale = 0.25
    ramped, parts = m.loss(b)
    expected = (
        parts["vel"] + 0.1 * parts["vel_glb"] + parts["vel_loc"] + 0.25 * (0.2 * parts["con"] + 0.05 * parts["orth"])
    )
    assert ramped.item() == pytest.approx(expected.item(), rel=1e-6) and ramped.item() < total.item()
    # Eq. 21 starts as v_glb + v_loc.
    assert torch.allclose(p["v"], p["v_glb"] + p["v_loc"], atol=1e-6)


# --- implementation equivalences ---------------------------------------------------------------


def test_masked_batch_norm_uses_present_samples_only():
    torch.manual_seed(0)
    bn = MaskedBatchNorm(groups=2, channels=3).train()
    y = torch.randn(5, 6, 1, 7)
    gm = torch.tensor([[1, 1], [1, 0], [0, 1], [1, 1], [1, 0]], dtype=torch.float32)
    out = bn(y, gm)
    for g in range(2):
        keep = gm[:, g].bool()
        ref_mean, ref_var = torch.zeros(3), torch.ones(3)
        ref = F.batch_norm(y[keep, 3 * g : 3 * g + 3, 0], ref_mean, ref_var, training=True, momentum=0.1)
        assert torch.allclose(out[keep, 3 * g : 3 * g + 3, 0], ref, atol=1e-5)
        assert torch.allclose(bn.running_mean[3 * g : 3 * g + 3], ref_mean, atol=1e-6)
        assert torch.allclose(bn.running_var[3 * g : 3 * g + 3], ref_var, atol=1e-5)
    # Everyone present: the same as PyTorch's batch norm, running statistics included.
    bn2, ref_mean, ref_var = MaskedBatchNorm(groups=2, channels=3).train(), torch.zeros(6), torch.ones(6)
    out = bn2(y, torch.ones(5, 2))
    assert torch.allclose(out, F.batch_norm(y, ref_mean, ref_var, training=True, momentum=0.1), atol=1e-5)
    assert torch.allclose(bn2.running_mean, ref_mean) and torch.allclose(bn2.running_var, ref_var)
    # The masked path with everyone present agrees with it.
    bn3 = MaskedBatchNorm(groups=2, channels=3).train()
    y3 = torch.cat([y, y[:1]])
    out3 = bn3(y3, torch.tensor([[1.0, 1.0]] * 5 + [[0.0, 0.0]]))
    assert torch.allclose(out3[:5], out, atol=1e-5) and torch.allclose(bn3.running_var, ref_var, atol=1e-5)


def test_masked_batch_norm_gradient():
    """The hand-written backward against finite differences, with absent samples."""
    g = torch.Generator().manual_seed(0)
    y = torch.randn(5, 4, 2, 3, dtype=torch.float64, generator=g).requires_grad_()
    m = torch.tensor([[1, 1], [1, 0], [0, 1], [1, 1], [1, 0]], dtype=torch.float64)
    w = (torch.rand(2, 3, dtype=torch.float64, generator=g) + 0.5).requires_grad_()
    b = torch.randn(2, 3, dtype=torch.float64, generator=g).requires_grad_()
    assert torch.autograd.gradcheck(lambda y, w, b: _MaskedBatchNormFn.apply(y, m, w, b, 1e-5)[0], (y, w, b))


@pytest.mark.parametrize(
    "kw",
    [{"extractor": "paper"}, {}, {"extractor": "paper", "sensor_pools": (1, 2, 3, 1, 1, 1)}],
    ids=["paper", "mixed", "paper-row-pooling"],
)
def test_grouped_inference_equals_separate_extractors(kw):
    """The fused inference path (one grouped convolution, BN folded, ReLU fused, strided max)
    computes what one Conv2d/BN/ReLU/MaxPool2d stack per extractor computes, for both extractor
    readings and with max-pool along the sensor rows."""
    m = registry.build("suitein++", **kw)
    g = torch.Generator().manual_seed(3)
    for n in m.extractors.norms:  # non-trivial statistics, so folding matters
        n.running_mean.copy_(torch.rand(n.running_mean.shape, generator=g) - 0.5)
        n.running_var.copy_(torch.rand(n.running_var.shape, generator=g) + 0.5)
        n.weight.data.copy_(torch.rand(n.weight.shape, generator=g) + 0.5)
    m.eval()
    b = batch(B=5)
    with torch.inference_mode():
        fused = m(b["x"], b["mask"])
        m.extractors.separate = True
        plain = m(b["x"], b["mask"])
    assert torch.allclose(fused, plain, atol=1e-5)


def test_extractor_readings():
    """paper: one input channel per device, the six axes are rows kept to the end (C·6 features
    per step); mixed: the six axes are block 1's input channels. Row max-pooling with kernels
    shared by the rows makes the features symmetric in pooled axes (why it is off by default):
    swapping acc x and y changes nothing there, and changes the paper default's output."""
    paper, mixed = tiny(extractor="paper"), tiny(extractor="mixed")
    assert paper.extractors.convs[0].in_channels == 3 and mixed.extractors.convs[0].in_channels == 18
    assert paper.extractors.out_channels == 6 * mixed.extractors.out_channels
    b = batch(B=4)
    swapped = b["x"][..., [1, 0, 2, 3, 4, 5]]
    pooled = tiny(extractor="paper", sensor_pools=(2, 3, 1, 1, 1, 1)).eval()
    with torch.no_grad():
        assert torch.equal(pooled(b["x"], b["mask"]), pooled(swapped, b["mask"]))
        paper.eval()
        assert not torch.allclose(paper(b["x"], b["mask"]), paper(swapped, b["mask"]))
    from wearnav.models.suitein import ROWS_SIZE

    assert registry.build("suitein++").cfg.extractor == "mixed"  # the default reading (module docstring)
    assert registry.build("suitein++-rows").cfg == registry.build("suitein++", **ROWS_SIZE).cfg
    assert registry.build("suitein").cfg.extractor == "paper"  # Suite-IN's own size needs the rows
    with pytest.raises(ConfigError):
        tiny(extractor="rows")
    with pytest.raises(ConfigError):
        tiny(extractor="paper", sensor_pools=(2, 2, 2, 1, 1, 1))  # 6 → 3 → 1 → 0 rows


# --- ablation switches -------------------------------------------------------------------------


def test_ablation_mapping():
    """Table V: (1) none, (2) W, (3) C+A, (4) W+A, (5) C+W, (6) all; Suite-IN = C only."""
    assert ABLATIONS == {
        1: dict(contrast=False, weighted=False, attentive=False),
        2: dict(contrast=False, weighted=True, attentive=False),
        3: dict(contrast=True, weighted=False, attentive=True),
        4: dict(contrast=False, weighted=True, attentive=True),
        5: dict(contrast=True, weighted=True, attentive=False),
        6: dict(contrast=True, weighted=True, attentive=True),
    }
    for n, sw in ABLATIONS.items():
        cfg = tiny("suitein++" if n == 6 else f"suitein++-abl{n}").cfg
        assert (cfg.contrast, cfg.weighted, cfg.attentive) == (sw["contrast"], sw["weighted"], sw["attentive"])
    cfg = tiny("suitein").cfg
    assert (cfg.contrast, cfg.weighted, cfg.attentive) == (True, False, False)


@pytest.mark.parametrize("number", [1, 2, 3, 4, 5, 6])
def test_ablation_switches_change_the_computation(number):
    sw = ABLATIONS[number]
    m = tiny("suitein++" if number == 6 else f"suitein++-abl{number}").eval()
    b = batch(mask=[1, 1, 1])
    total, parts = m.loss(b)
    expected_parts = (
        {"vel"}
        | ({"vel_glb", "vel_loc"} if sw["attentive"] else set())
        | ({"con", "orth"} if sw["contrast"] else set())
    )
    assert set(parts) == expected_parts
    # Local extractors exist only where a module uses them.
    assert m.extractors.branches == (2 if sw["contrast"] or sw["attentive"] else 1)
    assert (m.local is not None) == sw["attentive"]
    with torch.no_grad():
        p = m.parts(b["x"], b["mask"])
    if sw["weighted"]:
        # Rescaled weights lie in [λc, λa+λc]; with 3 devices α_j ∈ [10/48, 19/39].
        assert not torch.allclose(p["alpha"], torch.full_like(p["alpha"], 1 / 3))
        assert (p["alpha"] >= 10 / 48 - 1e-6).all() and (p["alpha"] <= 19 / 39 + 1e-6).all()
    else:
        assert torch.allclose(p["alpha"], torch.full_like(p["alpha"], 1 / 3))
    if not sw["attentive"]:
        assert torch.equal(p["v"], p["v_glb"])
        assert total.item() == pytest.approx(
            parts["vel"].item() + (0.2 * parts["con"].item() + 0.05 * parts["orth"].item() if sw["contrast"] else 0.0),
            rel=1e-6,
        )


# --- learning ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["suitein++", "suitein"])
def test_fits_a_linear_function_of_the_mean_acceleration(name):
    """32 random windows whose velocity is a fixed linear map of the mean horizontal acceleration
    over devices and time: 80 Adam steps must cut the inference-mode error by 4×. (50 steps
    were enough for the mixed extractor; the paper's row-keeping one at these tiny widths gets
    2.9× (suitein) in 50 steps and > 20× in 80.)"""
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(7)
    x = torch.randn(32, 3, 100, 6, generator=g)
    mask = torch.ones(32, 3)
    mask[:8, 0] = 0  # some windows without the phone
    x = x * mask[:, :, None, None]
    mean_acc = x[..., :2].sum((1, 2)) / (mask.sum(1, keepdim=True) * 100)
    vel = mean_acc @ torch.tensor([[1.0, -0.5], [0.3, 1.2]]) / mean_acc.std()
    b = {"x": x, "mask": mask, "vel": vel}
    m = registry.build(name, **TINY, dropout=0.0)
    opt = torch.optim.Adam(m.parameters(), lr=3e-3)

    def eval_mse():
        m.eval()
        with torch.no_grad():
            return F.mse_loss(m(x, mask), vel).item()

    before = eval_mse()
    m.train()
    for _ in range(80):
        opt.zero_grad()
        total, _ = m.loss(b)
        total.backward()
        opt.step()
    after = eval_mse()
    assert after < before / 4, (before, after)


# --- efficiency measurement --------------------------------------------------------------------


class _Linear(OdometryModel):
    def __init__(self):
        super().__init__()
        self.fc = nn.Linear(3 * 100 * 6, 2)

    def forward(self, x, mask):
        return self.fc(x.flatten(1))


def test_efficiency_row():
    from wearnav.bench import efficiency

    lin = _Linear()
    assert efficiency.flops_per_window(lin) == 2 * 1800 * 2  # a multiply-add is 2 FLOPs
    row = efficiency.measure(lin, name="linear", batches=(1, 8), min_run_time_s=0.02)
    assert row["params"] == 1800 * 2 + 2 and row["mflops_per_window"] == pytest.approx(0.0072)
    assert row["dense_gflops"] > 0.1 and row["win_per_s_b8"] > 0 and row["train_step_s_b128"] > 0
    assert row["win_per_s_b8_iqr"] >= 0 and row["train_step_s_b128_iqr"] >= 0
    before = lin.fc.weight.clone()
    assert efficiency.train_step_seconds(lin, batch=4, min_run_time_s=0.01).median_s > 0
    assert torch.equal(lin.fc.weight, before)  # timed on a copy
    assert row["fraction_b8"] == pytest.approx(
        row["mflops_per_window"] * 1e6 * row["win_per_s_b8"] / (row["dense_gflops"] * 1e9)
    )
    with pytest.raises(ConfigError):
        efficiency.measure("no-such-model")


def test_time_call_is_blocked_autorange_median_and_iqr(monkeypatch):
    """time_call: torch's Timer.blocked_autorange on the current thread count and the chosen
    clock; Timing holds the median and quartiles of its per-call block times, rate() turns them
    into calls/s. A fake clock that advances 1 ms per call gives 1 ms with no spread; a faked
    Measurement gives known quartiles."""
    from wearnav.bench import efficiency

    state = {"now": 0.0}
    monkeypatch.setitem(efficiency.CLOCKS, "cpu", lambda: state["now"])
    t = efficiency.time_call(lambda: state.__setitem__("now", state["now"] + 1e-3), min_run_time_s=0.05, clock="cpu")
    assert t.calls_per_block >= 1 and t.blocks >= 2
    assert t.median_s == pytest.approx(1e-3) and t.iqr_s == pytest.approx(0.0, abs=1e-9)
    assert t.rate(8) == (pytest.approx(8000.0), pytest.approx(0.0, abs=1e-3))
    slow = efficiency.Timing(median_s=2.0, q25_s=1.0, q75_s=4.0, blocks=4, calls_per_block=1)
    assert slow.iqr_s == 3.0 and slow.rate(8) == (4.0, 8 / 1.0 - 8 / 4.0)
    seen = []
    monkeypatch.setattr(
        efficiency.benchmark.Timer,
        "blocked_autorange",
        lambda self, min_run_time: (
            seen.append((self._task_spec.num_threads, min_run_time))
            or type("M", (), {"times": [1.0, 2.0, 3.0], "number_per_run": 5})()
        ),
    )
    with efficiency.torch_threads(2):
        t = efficiency.time_call(lambda: None, 0.3)
    assert seen == [(2, 0.3)] and (t.q25_s, t.median_s, t.q75_s, t.calls_per_block) == (1.5, 2.0, 2.5, 5)


# --- the data contract -------------------------------------------------------------------------


def test_trains_on_window_dataset_batches():
    """Batches of :class:`wearnav.preprocess.windows.WindowDataset` (default collate) go straight into
    ``loss`` and ``forward``, including windows where the earbuds are out (mask 0)."""
    from torch.utils.data import DataLoader

    from synthetic import synthetic_recording
    from wearnav.preprocess.windows import WindowConfig, WindowDataset

    rec = synthetic_recording(duration=40.0)
    ds = WindowDataset.from_recordings([rec], wcfg=WindowConfig(window=100, stride=20))
    masks = torch.stack([ds[i]["mask"] for i in range(len(ds))])
    assert (masks[:, 2] == 0).any() and (masks[:, 2] == 1).any()  # earbuds out for a while
    m = tiny()
    opt = torch.optim.Adam(m.parameters(), lr=1e-3)
    for b in DataLoader(ds, batch_size=16, shuffle=True, generator=torch.Generator().manual_seed(0)):
        total, parts = m.loss(b)
        opt.zero_grad()
        total.backward()
        opt.step()
        assert torch.isfinite(total) and all(torch.isfinite(v) for v in parts.values())
    m.eval()
    b = next(iter(DataLoader(ds, batch_size=len(ds))))
    with torch.no_grad():
        assert torch.isfinite(m(b["x"], b["mask"])).all()
